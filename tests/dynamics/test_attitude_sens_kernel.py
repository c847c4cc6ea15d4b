"""The compiled forward-sensitivity run against the scipy one (its second implementation):
the same right-hand side, and the same end, energy, sensitivities and dips on free-time,
fixed-horizon, torque-limited and underdamped runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.dynamics import attitude_sens_kernel as kernel
from penaltyrun.problems.attitude import lyapunov

I_FULL = np.array([[10.0, 1.0, 0.5], [1.0, 15.0, -0.7], [0.5, -0.7, 20.0]])
WEIGHTS = (1.0, 1.0, 1.0)
#: An underdamped PD gain: the distance has local minima (dips) before it arrives.
UNDERDAMPED = np.concatenate([0.5 * np.eye(3), 2.0 * np.eye(3)], axis=1)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_rhs_is_the_reference_augmented_right_hand_side(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3, 3))
    inertia = A @ A.T + 3.0 * np.eye(3)
    inertia_inv = np.linalg.inv(inertia)
    G = 3.0 * rng.normal(size=(3, 6))
    z = rng.normal(size=kernel.N_AUG)
    out = np.empty(kernel.N_AUG)
    kernel.rhs(0.0, z, kernel.pack(G, inertia, inertia_inv, WEIGHTS, 1e-3, np.inf), out)
    ref = sens.augmented(z, G, inertia, inertia_inv)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-13 * np.max(np.abs(ref)))


def _both(G, y0, t_end, tol, u_max=np.inf, inertia=I_FULL):
    runs = [sens.sensitivity_run(G, y0, inertia, t_end, WEIGHTS, tol, u_max, compiled=c)
            for c in (True, False)]
    return runs


def _assert_same(fast, ref):
    assert fast.status == ref.status
    assert abs(fast.t_end - ref.t_end) <= 1e-8 * max(1.0, ref.t_end)
    np.testing.assert_allclose(fast.y, ref.y, rtol=1e-8, atol=1e-10)
    assert abs(fast.energy - ref.energy) <= 1e-8 * abs(ref.energy)
    for a, b in ((fast.Y, ref.Y), (fast.e, ref.e)):
        assert np.max(np.abs(a - b)) <= 1e-7 * np.max(np.abs(b))


@pytest.mark.parametrize("seed", range(4))
def test_free_time_runs_arrive_with_the_reference_sensitivities(seed):
    rng = np.random.default_rng(seed)
    Kp = np.diag(rng.uniform(0.5, 3.0, 3))
    Kd = np.diag(rng.uniform(4.0, 12.0, 3))
    G = np.concatenate([Kp, Kd], axis=1) + 0.2 * rng.normal(size=(3, 6))
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = rng.uniform(0.3, 2.5)
    y0 = np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis,
                         0.02 * rng.normal(size=3)])
    fast, ref = _both(G, y0, 600.0, 1e-3)
    assert fast.status == "arrived"
    _assert_same(fast, ref)


def test_a_fixed_horizon_has_no_event_and_the_reference_sensitivities():
    prob = lyapunov.make_problem("rest_to_rest", {})
    fast, ref = _both(UNDERDAMPED, prob.y0, 80.0, None, inertia=prob.inertia)
    assert fast.status == "horizon" and fast.t_end == 80.0 and fast.dips.size == 0
    _assert_same(fast, ref)


def test_every_dip_of_an_underdamped_run_is_found():
    prob = lyapunov.make_problem("rest_to_rest", {})
    fast, ref = _both(UNDERDAMPED, prob.y0, 400.0, 1e-12, inertia=prob.inertia)
    assert fast.status == ref.status == "horizon"
    assert fast.dips.size == ref.dips.size >= 10
    np.testing.assert_allclose(fast.dips, ref.dips, rtol=1e-9)
    _assert_same(fast, ref)


@pytest.mark.parametrize("offset", [-1e-2, 1e-2])
def test_arrival_next_to_a_dip_matches_the_reference(offset):
    """tol just under a dip (the run passes above it) or just over it (arrives in it)."""
    prob = lyapunov.make_problem("rest_to_rest", {})
    dips = sens.sensitivity_run(UNDERDAMPED, prob.y0, prob.inertia, 400.0, WEIGHTS,
                                1e-12).dips
    fast, ref = _both(UNDERDAMPED, prob.y0, 400.0, dips[3] * (1.0 + offset),
                      inertia=prob.inertia)
    assert fast.status == "arrived"
    assert np.min(fast.dips) == pytest.approx(np.min(ref.dips), rel=1e-9)
    _assert_same(fast, ref)


def test_the_torque_limit_ends_the_run_where_the_reference_does():
    prob = lyapunov.make_problem("detumble", {})
    G = np.concatenate([2.0 * np.eye(3), 10.0 * np.eye(3)], axis=1)
    u0 = np.max(np.abs(G @ prob.y0[1:7]))
    fast, ref = _both(G, prob.y0, 600.0, 1e-3, u_max=2.0 * u0, inertia=prob.inertia)
    if ref.status == "saturated":
        assert fast.status == "saturated"
        assert abs(fast.t_end - ref.t_end) <= 1e-8 * ref.t_end
    else:
        _assert_same(fast, ref)
    start, _ = _both(G, prob.y0, 600.0, 1e-3, u_max=0.5 * u0, inertia=prob.inertia)
    assert start.status == "saturated"


def test_the_dips_beyond_the_kept_ones_leave_their_smallest():
    p = kernel.pack(UNDERDAMPED, I_FULL, np.linalg.inv(I_FULL), WEIGHTS, 1e-3, np.inf)
    z = np.zeros(kernel.N_AUG)
    z[0] = 1.0
    extra = 5
    for k in range(kernel.N_DIPS + extra):  # a local minimum then a maximum, each time
        z[4] = 1.0 + (kernel.N_DIPS + extra - k) * 1e-3  # each dip deeper than the last
        kernel.set_mode(1.0 + 2 * k, z, p)
        kernel.set_mode(2.0 + 2 * k, z, p)
    dips = kernel.recorded_dips(p)
    assert dips.size == kernel.N_DIPS + 1
    assert dips[0] == pytest.approx(1.0 + (kernel.N_DIPS + extra) * 1e-3)
    assert dips[-1] == pytest.approx(1.001) and dips[-1] < dips[:-1].min()
