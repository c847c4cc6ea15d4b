"""States and running cost of linear closed loops sampled exactly
(:func:`penaltyrun.dynamics.linear.sampled_loop`) against ``solve_ivp`` (rtol 1e-10) and
the finite-horizon closed form of :func:`~penaltyrun.dynamics.linear.quadratic_cost`."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from penaltyrun.dynamics.linear import quadratic_cost, sampled_loop


def loops(rng, C, n, stable=True):
    A = rng.standard_normal((C, n, n))
    if stable:  # shift every spectrum left of −0.2
        A -= (np.max(np.linalg.eigvals(A).real, axis=1) + 0.2)[:, None, None] * np.eye(n)
    M = rng.standard_normal((C, n, n))
    return A, M @ np.swapaxes(M, 1, 2) + 0.1 * np.eye(n)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.booleans())
def test_sampled_states_and_cost_equal_an_integration(seed, n, stable):
    rng = np.random.default_rng(seed)
    A, W = loops(rng, 2, n, stable)
    X0 = rng.standard_normal((3, n))
    t = np.linspace(0.0, 3.0, 31)
    x, J = sampled_loop(A, X0, t, W)
    assert x.shape == (2, 3, 31, n) and J.shape == (2, 3, 31)
    for c in range(2):
        for k in range(3):
            def rhs(_t, y, c=c):
                return np.append(A[c] @ y[:n], y[:n] @ W[c] @ y[:n])

            sol = solve_ivp(rhs, (0.0, 3.0), np.append(X0[k], 0.0), t_eval=t,
                            method="DOP853", rtol=1e-10, atol=1e-12)
            scale = np.abs(sol.y[:n]).max()
            np.testing.assert_allclose(x[c, k], sol.y[:n].T, rtol=0, atol=1e-8 * scale)
            np.testing.assert_allclose(J[c, k], sol.y[n], rtol=1e-8,
                                       atol=1e-10 * np.abs(sol.y[n]).max())


def test_final_cost_equals_the_closed_form_and_states_alone_without_a_weight():
    rng = np.random.default_rng(4)
    A, W = loops(rng, 3, 4)
    X0 = rng.standard_normal((2, 4))
    t = np.linspace(0.0, 5.0, 201)
    x, J = sampled_loop(A, X0, t, W)
    cost, x_final = quadratic_cost(A, W, X0, 5.0)
    np.testing.assert_allclose(J[:, :, -1], cost, rtol=1e-10)
    np.testing.assert_allclose(x[:, :, -1], x_final, rtol=1e-10, atol=1e-14)
    states, none = sampled_loop(A, X0, t)
    assert none is None
    np.testing.assert_array_equal(states, x)
