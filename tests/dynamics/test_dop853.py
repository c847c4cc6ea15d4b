"""DOP853 closed-loop kernels against scipy ``solve_ivp`` (DOP853, rtol = atol = 1e-12).

Random PD and LQR gains, detumble and rest-to-rest, with and without saturation: the
kernel (run at the same tight tolerance) must match the reference cost to 1e-8 relative and
its event time to 1e-6 s, converged flags identical. The scipy reference checks the event at
step ends only, so its step is bounded by 0.05 s; it integrates the plain clamped law (no
switch points), so the saturated cases also check the kernel's kink handling. With
saturation scipy itself is the less accurate side (its error control has to resolve every
kink: at rtol 1e-12 it is up to 1e-8 off and moves towards the kernel's value, which is the
same at 1e-10, 1e-12 and 1e-13), so there the reference runs at 1e-13.
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import attitude as at
from penaltyrun.dynamics import dop853, integrate
from penaltyrun.problems.attitude.lqr import lqr_gains

I_DIAG = np.diag([10.0, 15.0, 20.0])
Q_START = np.array([0.413836, -0.610042, 0.290580, 0.610042])
Q_START = Q_START / np.linalg.norm(Q_START)
OMEGA = {"detumble": (0.01, -0.01, 0.01), "rest_to_rest": (0.0, 0.0, 0.0)}
TIGHT = 1e-12
#: Reference tolerance with saturation (see the module docstring).
TIGHT_SATURATED = 1e-13


def _kernel(G, y0, u_max, t_max=100.0, tol=1e-4, inertia=I_DIAG, weights=(1.0, 1.0, 1.0)):
    return at.final_state(np.asarray(G, float), np.asarray(y0, float), inertia,
                          np.linalg.inv(inertia), t_max, tol, u_max, TIGHT, TIGHT, np.inf, 0.05,
                          4, 1_000_000, *weights)


def _scipy(G, y0, u_max, t_max=100.0, tol=1e-4, inertia=I_DIAG, weights=(1.0, 1.0, 1.0)):
    p = np.empty(at.N_PRM)
    at.pack_params(inertia, np.linalg.inv(inertia), np.asarray(G, float), u_max, tol, p,
                   *weights)

    def rhs(t, y):
        out = np.empty(8)
        at.rhs(t, y, p, out)  # modes AUTO: the plain clamped law
        return out

    def hit(t, y):
        return at.event(t, y, p)

    hit.terminal = True
    hit.direction = -1.0
    tight = TIGHT if np.isinf(u_max) else TIGHT_SATURATED
    sol = solve_ivp(rhs, (0.0, t_max), np.concatenate([y0, [0.0]]), method="DOP853",
                    rtol=tight, atol=tight, events=hit, max_step=0.05)
    if sol.t_events[0].size:
        return float(sol.t_events[0][0]), float(sol.y_events[0][0][7]), True
    return float(sol.t[-1]), float(sol.y[7, -1]), False


def _pd_gains(rng, n):
    out = [np.hstack([3.0 * np.eye(3), 6.0 * np.eye(3)])]  # converges in both manoeuvres
    for _ in range(n):
        kp, kd = rng.uniform(0.3, 3.0), rng.uniform(2.0, 12.0)
        A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        Kp = kp * np.eye(3) + 0.1 * (A @ A.T)
        Kd = kd * np.eye(3) + 0.5 * (B @ B.T)
        out.append(np.hstack([Kp, Kd]))
    return out


def _lqr_gains(rng, n):
    out = []
    for _ in range(n):
        A, B = rng.normal(size=(6, 6)), rng.normal(size=(3, 3))
        Q = A @ A.T + np.diag(rng.uniform(0.1, 5.0, 6))
        R = B @ B.T + np.diag(rng.uniform(0.5, 3.0, 3))
        K, ok = lqr_gains(Q[None], R[None], I_DIAG)
        assert ok[0]
        out.append(K[0])
    return out


def _assert_agrees(G, y0, u_max, **kw):
    t, y, status = _kernel(G, y0, u_max, **kw)
    t_ref, j_ref, conv_ref = _scipy(G, y0, u_max, **kw)
    assert (status == integrate.EVENT) == conv_ref
    assert status in (integrate.EVENT, integrate.HORIZON)
    assert abs(t - t_ref) <= 1e-6
    assert y[7] == pytest.approx(j_ref, rel=1e-8)
    return status, t


@pytest.mark.parametrize("manoeuvre", ["detumble", "rest_to_rest"])
@pytest.mark.parametrize("u_max", [np.inf, 0.05], ids=["free", "saturated"])
@pytest.mark.parametrize("law", ["pd", "lqr"])
def test_kernel_matches_scipy(law, u_max, manoeuvre):
    rng = np.random.default_rng({"pd": 11, "lqr": 13}[law] + (manoeuvre == "detumble"))
    y0 = np.concatenate([Q_START, OMEGA[manoeuvre]])
    gains = _pd_gains(rng, 3) if law == "pd" else _lqr_gains(rng, 3)
    statuses = [_assert_agrees(G, y0, u_max)[0] for G in gains]
    if u_max == np.inf:  # some runs end at the event (the others at the horizon)
        assert integrate.EVENT in statuses


def test_saturated_run_crosses_many_kinks_at_full_order():
    """A tight limit: every axis saturates and leaves the limit; the kernel still matches."""
    G = np.hstack([2.0 * np.eye(3), 6.0 * np.eye(3)])
    y0 = np.concatenate([Q_START, OMEGA["detumble"]])
    u_full = np.abs(G @ y0[1:7])
    assert np.all(u_full > 0.02)  # all three axes start saturated
    _assert_agrees(G, y0, 0.02, t_max=300.0)


def test_first_crossing_of_a_dip_is_found():
    """The spec's LQR example (detumble): the distance first dips under 1e-4 at t ≈ 61.37 s,
    rises above it at ≈ 64.63 s and falls again at ≈ 70.81 s; the kernel stops at the first
    crossing although its steps are seconds long."""
    Qq, Qw, r = np.array([1.0, 2.0, 3.0]), np.array([0.5, 1.0, 4.0]), np.array([1.0, 2.0, 0.5])
    K, ok = lqr_gains(np.diag(np.concatenate([Qq, Qw]))[None], np.diag(r)[None], I_DIAG)
    y0 = np.concatenate([Q_START, OMEGA["detumble"]])
    status, t = _assert_agrees(K[0], y0, np.inf)
    assert status == integrate.EVENT
    assert t == pytest.approx(61.37, abs=0.01)


@pytest.mark.parametrize("u_max", [np.inf, 1.0], ids=["free", "saturated"])
def test_companion_setup_matches_scipy(u_max):
    """Companion set-up (weighted event, 350 s) with the authors' best Cayley gains."""
    inertia = np.diag([140.0, 100.0, 80.0])
    s = np.array([0.6, -0.4, 0.2])
    q = np.concatenate([[(1 - s @ s) / (1 + s @ s)], 2 * s / (1 + s @ s)])
    y0 = np.concatenate([q, [0.70, 0.20, -0.15]])
    kw = {"t_max": 350.0, "tol": 1e-3, "inertia": inertia, "weights": (0.0, 10.0, 1.0)}
    Kp = np.array([[1.57829253, 1.07740877, -1.09866686], [1.07740877, 1.30878875, -0.90675407],
                   [-1.09866686, -0.90675407, 1.31689833]])
    Kd = np.array([[1.74150880, -0.30138814, 0.16624500], [-0.30138814, 11.03831055, -3.04021733],
                   [0.16624500, -3.04021733, 11.24695355]])
    status, t = _assert_agrees(np.hstack([Kp, Kd]), y0, u_max, **kw)
    if np.isinf(u_max):  # the authors' run: the event at t ≈ 348.95 s
        assert status == integrate.EVENT and t == pytest.approx(348.9489, abs=0.05)


@njit
def _osc_rhs(t, y, p, out):
    out[0] = y[1]
    out[1] = -y[0]


@njit
def _osc_event(t, y, p):
    return abs(y[0]) - p[0]


@njit
def _osc_slope(v, p):
    return v[0]


_OSC = dop853.make_dop853(_osc_rhs, _osc_event, _osc_slope)


def test_dip_inside_one_long_step():
    """x = cos t passes |x| ≤ 0.05 only for |t − π/2| ≤ 0.05: with steps of 2 s the event is
    found on the dense output, at the first crossing."""
    t, y, status, steps = _OSC(np.array([1.0, 0.0]), np.array([0.05]), 10.0, 1e-9, 1e-9, 2.0,
                               0.05, 4, 100000)
    assert status == integrate.EVENT and steps < 10
    assert t == pytest.approx(np.arccos(0.05), rel=1e-8)


def test_bitwise_deterministic():
    G = _pd_gains(np.random.default_rng(5), 1)[0]
    y0 = np.concatenate([Q_START, OMEGA["detumble"]])
    a = _kernel(G, y0, 0.05)
    b = _kernel(G, y0, 0.05)
    assert a[0] == b[0] and a[2] == b[2] and np.array_equal(a[1], b[1])


def test_tableau_is_scipys_and_the_unrolled_stages_are_current():
    from pathlib import Path

    from scipy.integrate._ivp import dop853_coefficients as ref

    from penaltyrun.dynamics import dop853_stages
    from penaltyrun.dynamics import dop853_tableau as tab

    A = np.zeros((16, 16))
    for s in range(16):
        for k in range(tab.A_PTR[s], tab.A_PTR[s + 1]):
            A[s, tab.A_IDX[k]] = tab.A_VAL[k]
    np.testing.assert_array_equal(A, ref.A)
    np.testing.assert_array_equal(tab.C, ref.C)
    np.testing.assert_array_equal(tab.E3, ref.E3)
    np.testing.assert_array_equal(tab.E5, ref.E5)
    np.testing.assert_array_equal(tab.D, ref.D)
    assert Path(dop853_stages.__file__).read_text() == tab.stages_source()


@pytest.mark.parametrize("gain", [1e308, np.inf])
def test_an_overflowing_first_derivative_is_a_nonfinite_status(gain):
    """A gain so large that the first derivative overflows ends at t = 0 with status
    NONFINITE (it raised ZeroDivisionError in the initial-step estimate)."""
    from penaltyrun.dynamics.zermelo import simulate_batch

    K = np.array([[[gain, 0.0], [0.0, gain]]])
    t_end, _, _, status = simulate_batch(K, np.array([-8.0, 6.0]), 50.0, 1e-3, 1e-10,
                                         1e-10, np.inf, 100000)
    assert status[0] == integrate.NONFINITE and t_end[0] == 0.0
