"""One Schur decomposition for several Lyapunov equations, against a closed form, the
residual and scipy's Bartels–Stewart."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.linalg import solve_continuous_lyapunov

from penaltyrun.dynamics.lyapunov import SchurLyapunov


def test_scalar_closed_form():
    # a x + x a = c  →  x = c / (2a)
    s = SchurLyapunov(np.array([[-0.5]]))
    assert s.solve(np.array([[3.0]]))[0, 0] == pytest.approx(-3.0)
    assert s.solve(np.array([[3.0]]), transpose=True)[0, 0] == pytest.approx(-3.0)


def test_diagonal_closed_form():
    # X_ij = C_ij / (a_i + a_j) for A = diag(a), either equation
    a = np.array([-1.0, -2.0, -5.0])
    C = np.arange(9.0).reshape(3, 3)
    expect = C / (a[:, None] + a[None, :])
    s = SchurLyapunov(np.diag(a))
    np.testing.assert_allclose(s.solve(C), expect, rtol=1e-14)
    np.testing.assert_allclose(s.solve(C, transpose=True), expect, rtol=1e-14)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 12), seed=st.integers(0, 2**32 - 1), transpose=st.booleans())
def test_matches_scipy_and_has_a_small_residual(n, seed, transpose):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A -= (np.max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)  # Hurwitz, margin 0.5
    C = rng.normal(size=(n, n))
    s = SchurLyapunov(A)
    X = s.solve(C, transpose=transpose)
    Aop = A.T if transpose else A
    scale = np.abs(C).max()
    np.testing.assert_allclose(Aop @ X + X @ Aop.T, C, atol=1e-10 * scale * max(1, n))
    np.testing.assert_allclose(X, solve_continuous_lyapunov(Aop, C),
                               atol=1e-9 * np.abs(X).max() + 1e-300)


def test_one_decomposition_serves_both_equations():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6)) - 4.0 * np.eye(6)
    s = SchurLyapunov(A)
    T, U = s.T.copy(), s.U.copy()
    for transpose in (False, True, False):
        s.solve(rng.normal(size=(6, 6)), transpose=transpose)
    np.testing.assert_array_equal(s.T, T)
    np.testing.assert_array_equal(s.U, U)
