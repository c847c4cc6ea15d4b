"""RODAS4 integrator against closed forms and numpy: linear stiff systems (matrix
exponential), its LU against ``numpy.linalg.solve``, the attitude Jacobian against finite
differences."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from scipy.linalg import expm
from scipy.optimize import brentq

from penaltyrun.dynamics import attitude as at
from penaltyrun.dynamics import integrate, rosenbrock

#: Stiff linear test system y' = A y (eigenvalues −0.5 ± 0.3i, −2 000, −800), and y[0]'s
#: magnitude as the event: |y0| − p[0].
_V = np.array([[1.0, 0.2, 0.0, 0.3], [0.1, 1.0, 0.4, 0.0], [0.0, 0.3, 1.0, 0.2],
               [0.2, 0.0, 0.1, 1.0]])
_D = np.array([[-0.5, 0.3, 0.0, 0.0], [-0.3, -0.5, 0.0, 0.0], [0.0, 0.0, -2000.0, 0.0],
               [0.0, 0.0, 0.0, -800.0]])
A_LIN = _V @ _D @ np.linalg.inv(_V)


@njit
def _lin_rhs(t, y, p, out):
    for i in range(4):
        acc = 0.0
        for j in range(4):
            acc += p[1 + 4 * i + j] * y[j]
        out[i] = acc


@njit
def _lin_jac(t, y, p, out):
    for i in range(4):
        for j in range(4):
            out[i, j] = p[1 + 4 * i + j]


@njit
def _lin_event(t, y, p):
    return abs(y[0]) - p[0]


@njit
def _lin_slope(v, p):
    return v[0]


_LIN = rosenbrock.make_rodas(_lin_rhs, _lin_jac, _lin_event, _lin_slope)


def _params(level: float) -> np.ndarray:
    return np.concatenate([[level], A_LIN.ravel()])


Y0 = np.array([1.0, -0.5, 2.0, 1.0])


def test_linear_stiff_horizon_matches_expm():
    t, y, status, steps = _LIN(Y0.copy(), _params(0.0), 5.0, 1e-10, 1e-10, np.inf, 0.05, 4,
                               100_000)
    assert status == integrate.HORIZON and t == 5.0
    np.testing.assert_allclose(y, expm(5.0 * A_LIN) @ Y0, rtol=1e-8, atol=1e-11)
    # L-stable: the step follows the slow modes, not the −2 000 1/s pole (an explicit
    # method needs ~ 2 000 · 5 / 3 ≈ 3 000 steps)
    assert steps < 1000


def test_linear_event_first_crossing_matches_closed_form():
    """|y0(t)| falls to 0.3 first at the root of the exact solution; the kernel's time is
    that root (Newton on the method, not on the cubic interpolant)."""
    level = 0.3

    def y0_of(t):
        return (expm(t * A_LIN) @ Y0)[0]

    grid = np.linspace(0.0, 5.0, 5001)
    vals = np.array([abs(y0_of(t)) - level for t in grid])
    k = int(np.flatnonzero(vals <= 0.0)[0])
    t_ref = brentq(lambda t: abs(y0_of(t)) - level, grid[k - 1], grid[k], xtol=1e-14)
    t, y, status, _ = _LIN(Y0.copy(), _params(level), 5.0, 1e-10, 1e-10, np.inf, 0.05, 4,
                           100_000)
    assert status == integrate.EVENT
    assert t == pytest.approx(t_ref, abs=1e-8)
    np.testing.assert_allclose(y, expm(t_ref * A_LIN) @ Y0, rtol=1e-7, atol=1e-9)


def test_cutoff_and_step_cap():
    p = _params(0.0)
    t, y, status, steps = _LIN(Y0.copy(), p, 5.0, 1e-10, 1e-10, np.inf, 0.05, 4, 100_000, 1,
                               -10.0)
    assert status == integrate.CUTOFF and steps == 1 and y[1] > -10.0 and 0.0 < t < 5.0
    t, y, status, steps = _LIN(Y0.copy(), p, 5.0, 1e-10, 1e-10, np.inf, 0.05, 4, 5)
    assert status == integrate.STEP_FAILURE and steps == 5


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 8), st.integers(0, 2 ** 31 - 1))
def test_lu_solve_matches_numpy(n, seed):
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n)) + n * np.eye(n) * rng.uniform(-1.0, 1.0)
    b = rng.standard_normal(n)
    W = M.copy()
    piv = np.empty(n, dtype=np.int64)
    if abs(np.linalg.det(M)) < 1e-8:
        return
    assert rosenbrock._lu(W, piv)
    x = b.copy()
    rosenbrock._solve(W, piv, x)
    np.testing.assert_allclose(x, np.linalg.solve(M, b), rtol=1e-8, atol=1e-8)


def test_lu_reports_singular():
    W = np.array([[1.0, 2.0], [2.0, 4.0]])
    W[1] -= 2.0 * W[0]
    assert not rosenbrock._lu(W, np.empty(2, dtype=np.int64))


@pytest.mark.parametrize("seed", range(5))
def test_attitude_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    L = rng.standard_normal((3, 3))
    inertia = L @ L.T + 10.0 * np.eye(3)
    G = rng.standard_normal((3, 6)) * 10.0 ** rng.uniform(-1, 3)
    p = np.empty(at.N_PRM)
    at.pack_params(inertia, np.linalg.inv(inertia), G, np.inf, 1e-4, p)
    y = rng.standard_normal(8)
    jac = np.empty((8, 8))
    at.jacobian(0.0, y, p, jac)
    fd = np.empty((8, 8))
    plus = np.empty(8)
    minus = np.empty(8)
    for j in range(8):
        e = np.zeros(8)
        e[j] = 1e-6
        at.rhs(0.0, y + e, p, plus)
        at.rhs(0.0, y - e, p, minus)
        fd[:, j] = (plus - minus) / 2e-6
    np.testing.assert_allclose(jac, fd, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(fd).max()))


def test_stiffness_bounds_the_spectral_radius():
    """The row-sum bound is at least the largest |eigenvalue| of A − B G (numpy)."""
    rng = np.random.default_rng(3)
    inertia = np.diag([10.0, 15.0, 20.0])
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(inertia)])
    for _ in range(20):
        G = rng.standard_normal((3, 6)) * 10.0 ** rng.uniform(-1, 4)
        p = np.empty(at.N_PRM)
        at.pack_params(inertia, np.linalg.inv(inertia), G, np.inf, 1e-4, p)
        assert at.stiffness(p) >= np.abs(np.linalg.eigvals(A - B @ G)).max() * (1 - 1e-12)
        at.pack_params(inertia, np.linalg.inv(inertia), G, 1.0, 1e-4, p)
        assert at.stiffness(p) == np.inf
