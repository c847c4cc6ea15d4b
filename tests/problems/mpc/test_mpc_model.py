"""CW discretization and discrete Riccati solutions of the rendezvous MPC against closed
forms, solve_ivp and scipy."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.linalg import solve_discrete_are

from penaltyrun.problems.mpc import controller as ctl
from penaltyrun.problems.mpc.model import (
    cw_continuous,
    dare_residual,
    mean_motion,
    solve_dare_batch,
    zoh,
)
from penaltyrun.problems.mpc.reference import cw_discrete_closed_form

N_MEAN = mean_motion(6778.137e3, 398600.4418e9)


def random_spd(rng, n, lo, hi):
    Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Qo @ np.diag(np.exp(rng.uniform(np.log(lo), np.log(hi), n))) @ Qo.T


def test_mean_motion_of_400_km_orbit():
    assert N_MEAN == pytest.approx(1.1313e-3, rel=1e-4)


# The closed form loses digits to 1 − cos(n·dt) at small n·dt (2e-10 relative at dt = 1 s).
@pytest.mark.parametrize(("dt", "tol"), [(1.0, 1e-9), (20.0, 1e-11), (600.0, 1e-11)])
def test_zoh_matches_closed_form_cw_transition(dt, tol):
    A, B = cw_continuous(N_MEAN)
    Ad, Bd = zoh(A, B, dt)
    Ad_ref, Bd_ref = cw_discrete_closed_form(N_MEAN, dt)
    np.testing.assert_allclose(Ad, Ad_ref, rtol=0, atol=tol * np.abs(Ad_ref).max())
    np.testing.assert_allclose(Bd, Bd_ref, rtol=0, atol=tol * np.abs(Bd_ref).max())


def test_zoh_matches_solve_ivp_with_constant_input():
    A, B = cw_continuous(N_MEAN)
    Ad, Bd = zoh(A, B, 20.0)
    s0 = np.array([100.0, -1000.0, 50.0, 0.1, -0.2, 0.05])
    u = np.array([0.01, -0.004, 0.007])
    sol = solve_ivp(lambda t, s: A @ s + B @ u, (0.0, 20.0), s0, method="DOP853",
                    rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(Ad @ s0 + Bd @ u, sol.y[:, -1], rtol=1e-10, atol=1e-9)


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1))
def test_doubling_dare_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    Ad, Bd = zoh(*cw_continuous(N_MEAN), 20.0)
    Q = np.stack([random_spd(rng, 6, 1e-6, 1e2) for _ in range(3)])
    R = np.stack([random_spd(rng, 3, 1e2, 1e4) for _ in range(3)])
    P, ok = solve_dare_batch(Ad, Bd, Q, R)
    assert ok.all()
    assert np.all(dare_residual(Ad, Bd, Q, R, P) < 1e-9)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    assert np.all(np.abs(np.linalg.eigvals(Ad - Bd @ K)).max(axis=-1) < 1.0)
    for b in range(3):
        try:
            ref = solve_discrete_are(Ad, Bd, Q[b], R[b])
        except ValueError:
            # scipy's QZ reordering refuses some pairs of this conditioning (about 1 draw in
            # 700); the residual and stability checks above still hold for them.
            continue
        np.testing.assert_allclose(P[b], ref, rtol=0, atol=1e-7 * np.abs(ref).max())


def test_dare_scales_with_the_weights():
    Ad, Bd = zoh(*cw_continuous(N_MEAN), 20.0)
    Q = np.diag([1.0, 1, 1, 100, 100, 100])[None]
    R = (1e4 * np.eye(3))[None]
    P1, _ = solve_dare_batch(Ad, Bd, Q, R)
    P2, _ = solve_dare_batch(Ad, Bd, 1e3 * Q, 1e3 * R)
    np.testing.assert_allclose(P2, 1e3 * P1, rtol=1e-9)


def test_unstabilizable_pair_is_reported():
    A = np.diag([2.0, 0.5])
    B = np.array([[0.0], [1.0]])
    P, ok = solve_dare_batch(A, B, np.eye(2)[None], np.eye(1)[None])
    assert not ok[0] and np.all(P[0] == 0.0)


def test_nonfinite_weights_are_reported():
    Ad, Bd = zoh(*cw_continuous(N_MEAN), 20.0)
    Q = np.stack([np.eye(6), np.full((6, 6), np.nan)])
    P, ok = solve_dare_batch(Ad, Bd, Q, np.stack([np.eye(3)] * 2))
    assert ok.tolist() == [True, False]


@pytest.mark.parametrize("horizon", [1, 5, 20])
def test_unconstrained_mpc_is_the_discrete_lqr(horizon):
    """With P from the DARE, the first input of the unconstrained QP is −K s for every N."""
    rng = np.random.default_rng(horizon)
    Ad, Bd = zoh(*cw_continuous(N_MEAN), 20.0)
    Q = random_spd(rng, 6, 1e-4, 1e2)
    R = random_spd(rng, 3, 1e2, 1e4)
    P = solve_discrete_are(Ad, Bd, Q, R)
    K = np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
    Phi, Gam = ctl.prediction_matrices(Ad, Bd, horizon)
    H, F = ctl.qp_matrices(Phi, Gam, Q[None], R[None], P[None], np.full(3, 0.01))
    s = rng.standard_normal(6) * np.array([100, 100, 100, 0.1, 0.1, 0.1])
    u0 = 0.01 * np.linalg.solve(H[0], -F[0] @ s)[:3]
    np.testing.assert_allclose(u0, -K @ s, rtol=1e-8, atol=1e-14)
