"""The compiled eigendecomposition route of the closed-loop quadratic cost
(small_linear.quadratic_eig) against the batched numpy route it replaces for small loops,
and against scipy's Lyapunov / expm route."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.dynamics import linear


def _both(A, W, X0, t_max, monkeypatch):
    monkeypatch.setattr(linear, "COMPILED_MAX_STATES", 8)
    compiled = linear.quadratic_cost(A, W, X0, t_max)
    monkeypatch.setattr(linear, "COMPILED_MAX_STATES", 0)
    return compiled, linear.quadratic_cost(A, W, X0, t_max)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
@pytest.mark.parametrize("t_max", [0.3, 10.0, 200.0])
def test_costs_match_the_numpy_route(n, t_max, monkeypatch):
    rng = np.random.default_rng(n)
    A = rng.normal(size=(10, n, n)) - 2.0 * np.eye(n)
    A[2] = 0.1 * np.eye(n)  # not Hurwitz: the scipy route in both
    A[3] = np.eye(n) + np.diag(np.ones(n - 1), 1)  # defective: V ill-conditioned
    L = rng.normal(size=(10, n, n))
    W = L @ np.swapaxes(L, 1, 2)
    X0 = rng.normal(size=(3, n))
    (c1, x1), (c0, x0) = _both(A, W, X0, t_max, monkeypatch)
    np.testing.assert_allclose(c1, c0, rtol=1e-12, atol=0)
    np.testing.assert_allclose(x1, x0, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(x0))))


def test_per_loop_starts_and_scipy_reference(monkeypatch):
    """Starts given per loop (B, k, n), and the cost against scipy's Lyapunov route."""
    from scipy.linalg import expm, solve_continuous_lyapunov

    rng = np.random.default_rng(9)
    n = 4
    A = rng.normal(size=(5, n, n)) - 3.0 * np.eye(n)
    L = rng.normal(size=(5, n, n))
    W = L @ np.swapaxes(L, 1, 2)
    X0 = rng.normal(size=(5, 2, n))
    (c1, x1), (c0, _) = _both(A, W, X0, 2.0, monkeypatch)
    np.testing.assert_allclose(c1, c0, rtol=1e-12)
    for b in range(5):
        S = solve_continuous_lyapunov(A[b].T, -W[b])
        E = expm(2.0 * A[b])
        M = S - E.T @ S @ E
        np.testing.assert_allclose(c1[b], np.einsum("ki,ij,kj->k", X0[b], M, X0[b]),
                                   rtol=1e-10)
        np.testing.assert_allclose(x1[b], X0[b] @ E.T, rtol=1e-10, atol=1e-14)


def test_empty_batch_and_non_finite_loop(monkeypatch):
    monkeypatch.setattr(linear, "COMPILED_MAX_STATES", 8)
    cost, x_final = linear.quadratic_cost(np.zeros((0, 2, 2)), np.zeros((0, 2, 2)),
                                          np.ones((1, 2)), 1.0)
    assert cost.shape == (0, 1) and x_final.shape == (0, 1, 2)
    from penaltyrun.dynamics.small_linear import quadratic_eig

    A = np.stack([-np.eye(2), np.full((2, 2), np.nan)])
    _, _, good = quadratic_eig(A, np.stack([np.eye(2)] * 2), np.ones((2, 1, 2)), 1.0, 1e4)
    assert good.tolist() == [True, False]
