"""The compiled Dormand–Prince integrator against closed forms."""

import numpy as np
import pytest
from numba import njit

from penaltyrun.dynamics import integrate


@njit
def decay_rhs(t, y, p, out):
    out[0] = -p[0] * y[0]
    out[1] = 0.5 * y[0] * y[0]


@njit
def decay_event(t, y, p):
    return y[0] - p[1]


@njit
def oscillator_rhs(t, y, p, out):
    out[0] = y[1]
    out[1] = -y[0]


@njit
def near_zero_event(t, y, p):
    # |x| − tol with a cosine solution: dips below tol only briefly around t = π/2.
    return abs(y[0]) - p[0]


def run(rhs, event, y0, p, t_max, rtol, max_step, samples):
    return integrate.dopri5(rhs, event, y0, p, t_max, rtol, rtol, max_step, samples, 100000)


def test_specialized_integrator_is_reused_and_callable_from_compiled_code():
    integ = integrate.make_dopri5(decay_rhs, decay_event)

    @njit
    def caller(y0, p):
        return integ(y0, p, 1000.0, 1e-11, 1e-11, np.inf, 1, 100000)

    y0, p = np.array([3.0, 0.0]), np.array([0.7, 1e-3])
    t, y, status, _ = caller(y0, p)
    t2, y2, status2, _ = run(decay_rhs, decay_event, y0, p, 1000.0, 1e-11, np.inf, 1)
    assert status == status2 == integrate.EVENT
    assert t == t2 and np.array_equal(y, y2)
    assert integrate._specialized(decay_rhs, decay_event) is integrate._specialized(
        decay_rhs, decay_event)


def test_exponential_decay_event_time_and_integral():
    a, x0, level = 0.7, 3.0, 1e-3
    t, y, status, _ = run(decay_rhs, decay_event, np.array([x0, 0.0]), np.array([a, level]),
                          1000.0, 1e-11, np.inf, 1)
    t_exact = np.log(x0 / level) / a
    integral = x0**2 / (4 * a) * (1 - np.exp(-2 * a * t_exact))
    assert status == integrate.EVENT
    assert t == pytest.approx(t_exact, rel=1e-9)
    assert y[1] == pytest.approx(integral, rel=1e-9)


def test_horizon_reached_without_event():
    t, y, status, _ = run(decay_rhs, decay_event, np.array([1.0, 0.0]), np.array([0.1, 1e-9]),
                          5.0, 1e-10, np.inf, 1)
    assert status == integrate.HORIZON
    assert t == pytest.approx(5.0)
    assert y[0] == pytest.approx(np.exp(-0.5), rel=1e-9)


def test_event_inside_a_step_is_found_on_dense_output():
    # x = cos t passes |x| ≤ 0.05 only for |t − π/2| ≤ 0.05; a large step jumps over it
    # unless the event is sampled inside the step.
    p = np.array([0.05])
    y0 = np.array([1.0, 0.0])
    t_dense, _, status, _ = run(oscillator_rhs, near_zero_event, y0, p, 10.0, 1e-6, 2.0, 16)
    assert status == integrate.EVENT
    assert t_dense == pytest.approx(np.arccos(0.05), rel=1e-6)


def test_event_already_true_at_start():
    t, _, status, steps = run(decay_rhs, decay_event, np.array([1e-4, 0.0]),
                              np.array([1.0, 1e-3]), 10.0, 1e-10, np.inf, 1)
    assert (t, status, steps) == (0.0, integrate.EVENT, 0)


def test_cutoff_stops_after_the_running_cost_exceeds_the_threshold():
    # ẋ = −a x, J̇ = x²/2: J(t) = x0²/(4a) (1 − e^{−2at}) rises to the event at x = level.
    y0, p = np.array([3.0, 0.0]), np.array([0.7, 1e-3])
    t_full, y_full, st_full, n_full = run(decay_rhs, decay_event, y0, p, 1000.0, 1e-11,
                                          np.inf, 1)
    for frac in (0.0, 0.1, 0.5, 0.9, 0.999999):
        thr = frac * y_full[1]
        t, y, st, n = integrate.dopri5(decay_rhs, decay_event, y0, p, 1000.0, 1e-11, 1e-11,
                                       np.inf, 1, 100000, 1, thr)
        assert st == integrate.CUTOFF and integrate.STATUS_NAMES[st] == "cutoff"
        assert thr < y[1] <= y_full[1] and t < t_full and n < n_full
    for thr in (y_full[1], 2.0 * y_full[1], np.inf):  # never exceeded: the uncut run, bitwise
        t, y, st, n = integrate.dopri5(decay_rhs, decay_event, y0, p, 1000.0, 1e-11, 1e-11,
                                       np.inf, 1, 100000, 1, thr)
        assert (t, st, n) == (t_full, st_full, n_full) and np.array_equal(y, y_full)


def test_cutoff_never_replaces_the_horizon_status():
    # J first exceeds the threshold in the step that reaches t_max: that step ends the run
    # as without the cutoff.
    y0, p = np.array([3.0, 0.0]), np.array([0.7, 1e-3])
    t_h, y_h, st_h, _ = integrate.dopri5(decay_rhs, decay_event, y0, p, 0.5, 1e-11, 1e-11,
                                         0.5, 1, 100000)
    assert st_h == integrate.HORIZON
    t, y, st, _ = integrate.dopri5(decay_rhs, decay_event, y0, p, 0.5, 1e-11, 1e-11, 0.5, 1,
                                   100000, 1, y_h[1] * (1.0 - 1e-12))
    assert st == integrate.HORIZON and t == t_h and np.array_equal(y, y_h)
