"""The package's one batched Riccati solver (penaltyrun/dynamics/riccati.py) against
scipy's solve_continuous_are and python-control's lqr on random stabilizable plants, through
both of its paths (the compiled candidate loop of small plants and the numpy batch), and its
stability margin: absolute (attitude_lqr's), relative to ‖A‖ (problem=lqr's), or both."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_continuous_are

from penaltyrun.dynamics import riccati

control = pytest.importorskip("control")


def _spd(rng: np.random.Generator, count: int, size: int, lo: float, hi: float) -> np.ndarray:
    """``count`` random SPD matrices with eigenvalues log-uniform in [lo, hi]."""
    out = np.empty((count, size, size))
    for c in range(count):
        V, _ = np.linalg.qr(rng.normal(size=(size, size)))
        out[c] = (V * np.exp(rng.uniform(np.log(lo), np.log(hi), size))) @ V.T
    return 0.5 * (out + np.swapaxes(out, 1, 2))


def _plant(rng: np.random.Generator, n: int, m: int, controllable: bool
           ) -> tuple[np.ndarray, np.ndarray]:
    """A random plant, unstable in general; ``controllable=False`` appends a stable mode that
    the input does not reach (stabilizable, not controllable)."""
    A = rng.normal(size=(n, n)) / np.sqrt(n) + 0.3 * np.eye(n)
    B = rng.normal(size=(n, m))
    if controllable:
        return A, B
    A2 = np.zeros((n + 1, n + 1))
    A2[:n, :n] = A
    A2[n, n] = -0.7
    A2[:n, n] = rng.normal(size=n)  # the stable mode drives the others
    return A2, np.vstack([B, np.zeros((1, m))])


@pytest.fixture(params=["compiled", "numpy"])
def path(request, monkeypatch):
    """Run the test through the compiled candidate loop and through the numpy batch."""
    monkeypatch.setattr(riccati, "COMPILED_MAX_STATES", 64 if request.param == "compiled" else 0)
    return request.param


@pytest.mark.parametrize("n, m", [(1, 1), (2, 1), (3, 2), (6, 3), (9, 2)])
@pytest.mark.parametrize("controllable", [True, False])
def test_gains_match_scipy_and_python_control(n, m, controllable, path):
    rng = np.random.default_rng(100 * n + 10 * m + controllable)
    A, B = _plant(rng, n, m, controllable)
    k = A.shape[0]
    Q, R = _spd(rng, 8, k, 1e-3, 1e2), _spd(rng, 8, m, 1e-2, 1e2)
    K, ok, failure = riccati.lqr_gains(A, B, Q, R)
    assert ok.all() and not failure.any()
    for c in range(len(Q)):
        P = solve_continuous_are(A, B, Q[c], R[c])
        K_scipy = np.linalg.solve(R[c], B.T @ P)
        K_ctrl, _, poles = control.lqr(A, B, Q[c], R[c])
        scale = np.abs(K_scipy).max()
        np.testing.assert_allclose(K[c], K_scipy, rtol=0, atol=1e-8 * scale)
        np.testing.assert_allclose(K[c], K_ctrl, rtol=0, atol=1e-8 * scale)
        # A pole moves by about ‖B‖·‖δK‖ under a gain error δK: large gains (scale up to
        # 3e3 here) put round-off of 1e-10 of them at 1e-7 in the poles.
        np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A - B @ K[c])),
                                   np.sort_complex(poles), rtol=1e-7,
                                   atol=1e-10 * scale * np.linalg.norm(B, 2))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 5), m=st.integers(1, 3),
       alpha=st.floats(1e-3, 1e3))
def test_stabilizing_solution_of_any_plant(seed, n, m, alpha):
    """Property: for any random plant and penalties the gain is python-control's, the loop
    is Hurwitz, and (αQ, αR) gives the same gain.

    Riccati equations too ill-conditioned for any solver to fix the gain to 1e-7 are left
    out: their closed-loop Lyapunov operator X ↦ A_clᵀX + XA_cl (the derivative of the
    equation, whose condition number bounds the forward error of P) has a condition number
    above 1e10. On one such plant (condition number 3e12) an exact 50-digit solution puts
    scipy's gain 1.2e-8 and this package's 2.2e-7 from the truth, relative to the largest
    gain."""
    rng = np.random.default_rng(seed)
    A, B = _plant(rng, n, m, True)
    assume(np.linalg.cond(control.ctrb(A, B)) < 1e4)
    Q, R = _spd(rng, 2, n, 1e-2, 1e2), _spd(rng, 2, m, 1e-1, 1e1)
    K_ctrl = [control.lqr(A, B, Q[c], R[c])[0] for c in range(2)]
    eye = np.eye(n)
    for gain in K_ctrl:
        closed_t = (A - B @ gain).T
        assume(np.linalg.cond(np.kron(eye, closed_t) + np.kron(closed_t, eye)) < 1e10)
    K, ok, _ = riccati.lqr_gains(A, B, np.concatenate([Q, alpha * Q]),
                                 np.concatenate([R, alpha * R]))
    assert ok.all()
    for c in range(2):
        scale = max(1.0, np.abs(K_ctrl[c]).max())
        np.testing.assert_allclose(K[c], K_ctrl[c], rtol=0, atol=1e-7 * scale)
        np.testing.assert_allclose(K[2 + c], K[c], rtol=0, atol=1e-7 * scale)
        assert np.linalg.eigvals(A - B @ K[c]).real.max() < 0.0


def test_margin_is_the_larger_of_absolute_and_relative():
    A = 100.0 * np.eye(2)  # ‖A‖_F = 141.42…
    assert riccati.margin(A) == pytest.approx(riccati.STABILITY_MARGIN * 100.0 * np.sqrt(2))
    assert riccati.margin(0.005 * A) == riccati.STABILITY_MARGIN  # ‖A‖ < 1: floored at 1
    assert riccati.margin(A, margin_abs=1e-7, margin_rel=0.0) == 1e-7
    assert riccati.margin(A, margin_abs=1e-7, margin_rel=1e-8) == pytest.approx(1.4142e-6,
                                                                                rel=1e-4)
    assert riccati.margin(A, margin_abs=1e-5, margin_rel=1e-8) == 1e-5


def test_absolute_margin_rejects_a_slow_loop(path):
    """ẋ = u with Q = q, R = 1: K = √q and the pole −√q. A pole at −5e-8 passes the default
    relative margin (1e-9 here) but not an absolute 1e-7 (attitude_lqr's)."""
    A, B = np.zeros((1, 1)), np.ones((1, 1))
    Q = np.array([[[2.5e-15]], [[1.0]]])
    R = np.ones((2, 1, 1))
    K, ok, failure = riccati.lqr_gains(A, B, Q, R)
    assert ok.tolist() == [True, True]
    np.testing.assert_allclose(K[:, 0, 0], [5e-8, 1.0], rtol=1e-6)
    K, ok, failure = riccati.lqr_gains(A, B, Q, R, margin_abs=1e-7, margin_rel=0.0)
    assert ok.tolist() == [False, True]
    assert K[0, 0, 0] == 0.0 and failure[0] > 0.0 and K[1, 0, 0] == pytest.approx(1.0)


def test_relative_margin_scales_with_the_plant(path):
    """The same slow pole (−1e-6) passes with ‖A‖_F ≈ 1 and fails once a fast stable mode
    makes ‖A‖_F = 1e4 (margin 1e-5 with the default relative 1e-9)."""
    B = np.array([[1.0], [0.0]])
    Q = np.array([[[1e-12, 0.0], [0.0, 1.0]]])
    R = np.ones((1, 1, 1))
    for fast, expected in ((-1.0, True), (-1e4, False)):
        A = np.diag([0.0, fast])
        _, ok, _ = riccati.lqr_gains(A, B, Q, R)
        assert ok.tolist() == [expected]


def test_discrete_margin():
    """x⁺ = x + u with Q = 4/15, R = 1: P = 2/3 and the loop pole 1/(1 + P) = 0.6, inside
    the unit circle, but not inside 1 − 0.5."""
    A, B = np.ones((1, 1)), np.ones((1, 1))
    Q, R = np.full((1, 1, 1), 4.0 / 15.0), np.ones((1, 1, 1))
    K, ok, _ = riccati.dlqr_gains(A, B, Q, R)
    assert ok.all() and K[0, 0, 0] == pytest.approx(0.4, rel=1e-10)
    K, ok, _ = riccati.dlqr_gains(A, B, Q, R, margin_abs=0.5)
    assert not ok.any() and K[0, 0, 0] == 0.0


def test_the_doubling_iteration_solves_the_discrete_equation_like_scipy():
    from scipy.linalg import solve_discrete_are

    rng = np.random.default_rng(11)
    A = rng.normal(size=(4, 4)) * 0.6
    B = rng.normal(size=(4, 2))
    Q = np.stack([np.diag(rng.uniform(0.1, 10.0, 4)) for _ in range(5)])
    R = np.stack([np.diag(rng.uniform(0.1, 10.0, 2)) for _ in range(5)])
    P, finite = riccati.doubling_solutions(A, B, Q, R)
    assert finite.all()
    for c in range(5):
        ref = solve_discrete_are(A, B, Q[c], R[c])
        np.testing.assert_allclose(P[c], ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    assert np.all(riccati.discrete_residual(A, B, Q, R, P) < 1e-12)


def test_candidates_the_batch_misses_are_solved_by_scipy(monkeypatch):
    """Where the batched solvers give nothing, each candidate is solved by scipy's Schur
    method (continuous and discrete): the gains of a direct scipy solve, every one ok; an
    unstabilizable plant stays not ok with an infinite residual."""
    from scipy.linalg import solve_discrete_are

    rng = np.random.default_rng(11)
    A, B = _plant(rng, 4, 2, True)
    Q, R = _spd(rng, 3, 4, 0.1, 10.0), _spd(rng, 3, 2, 0.1, 10.0)

    def nothing(A, S, Q, mu):
        return np.full(Q.shape, np.nan), np.full(Q.shape[0], np.inf), np.zeros(Q.shape[0], bool)

    monkeypatch.setattr(riccati, "hamiltonian_compiled", nothing)
    monkeypatch.setattr(riccati, "hamiltonian_solutions", nothing)
    monkeypatch.setattr(riccati, "doubling_solutions", lambda A, B, Q, R, max_iter: (
        np.full(Q.shape, np.nan), np.zeros(Q.shape[0], bool)))
    K, ok, failure = riccati.lqr_gains(A, B, Q, R)
    assert ok.all() and (failure == 0).all()
    for c in range(3):
        ref = np.linalg.solve(R[c], B.T @ solve_continuous_are(A, B, Q[c], R[c]))
        np.testing.assert_allclose(K[c], ref, rtol=1e-10, atol=1e-12)
    Ad = np.eye(4) + 0.1 * A
    Bd = 0.1 * B
    K, ok, failure = riccati.dlqr_gains(Ad, Bd, Q, R)
    assert ok.all() and (failure == 0).all()
    for c in range(3):
        P = solve_discrete_are(Ad, Bd, Q[c], R[c])
        ref = np.linalg.solve(R[c] + Bd.T @ P @ Bd, Bd.T @ P @ Ad)
        np.testing.assert_allclose(K[c], ref, rtol=1e-10, atol=1e-12)
    unstabilizable = np.diag([1.0, 2.0, -1.0, -2.0])
    B0 = np.zeros((4, 2))
    B0[2:, :] = np.eye(2)  # the input reaches only the stable modes
    K, ok, failure = riccati.lqr_gains(unstabilizable, B0, Q, R)
    assert not ok.any() and np.isinf(failure).all() and (K == 0).all()
