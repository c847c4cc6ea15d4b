"""The exact linear cost (penaltyrun/dynamics/linear.py and problem=lqr's closed-form path)
against independent references: scipy's Riccati and Lyapunov solvers with expm, and
solve_ivp on the augmented state (x, J)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from penaltyrun.dynamics.linear import COND_MAX, _scipy_route, loop_solution, quadratic_cost
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import reference


def random_plant(rng, n, m):
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    return A, B


def spd(rng, n, shift=0.1):
    L = rng.normal(size=(n, n))
    return L @ L.T + shift * np.eye(n)


def ivp_cost(A_cl, W, x0, t_max):
    n = x0.size
    sol = solve_ivp(lambda t, y: np.append(A_cl @ y[:n], y[:n] @ W @ y[:n]), (0.0, t_max),
                    np.append(x0, 0.0), method="DOP853", rtol=1e-13, atol=1e-15)
    return sol.y[n, -1], sol.y[:n, -1]


@pytest.mark.parametrize("seed", range(4))
def test_quadratic_cost_matches_solve_ivp_and_lyapunov(seed):
    rng = np.random.default_rng(seed)
    n = 5
    A_cl = rng.normal(size=(3, n, n)) - 2.0 * np.eye(n)
    W = np.stack([spd(rng, n) for _ in range(3)])
    X0 = rng.normal(size=(2, n))
    cost, x_final = quadratic_cost(A_cl, W, X0, 3.0)
    for b in range(3):
        ref, x_ref = _scipy_route(A_cl[b], W[b], X0, 3.0)
        np.testing.assert_allclose(cost[b], ref, rtol=1e-10)
        np.testing.assert_allclose(x_final[b], x_ref, rtol=1e-10, atol=1e-12)
        for k in range(2):
            J, xT = ivp_cost(A_cl[b], W[b], X0[k], 3.0)
            assert cost[b, k] == pytest.approx(J, rel=1e-9)
            np.testing.assert_allclose(x_final[b, k], xT, rtol=1e-9, atol=1e-11)


@pytest.mark.parametrize("seed", range(4))
def test_one_loop_by_schur_matches_the_batch_route_and_solve_ivp(seed):
    """The single-loop route (Bartels–Stewart on a Schur decomposition, expm) against the
    batched eigen-route, solve_ivp, and its own Lyapunov residual."""
    rng = np.random.default_rng(100 + seed)
    n = 6
    A_cl = rng.normal(size=(n, n))
    A_cl -= (np.max(np.linalg.eigvals(A_cl).real) + 0.3) * np.eye(n)
    W = spd(rng, n)
    X0 = rng.normal(size=(3, n))
    solved = loop_solution(A_cl, W, 5.0)
    cost, x_final = solved.cost(X0)
    ref, x_ref = quadratic_cost(A_cl[None], W[None], X0, 5.0)
    np.testing.assert_allclose(cost, ref[0], rtol=1e-11)
    np.testing.assert_allclose(x_final, x_ref[0], rtol=1e-11, atol=1e-13)
    residual = A_cl.T @ solved.S + solved.S @ A_cl + W
    assert np.linalg.norm(residual) < 1e-12 * np.linalg.norm(W) * np.linalg.cond(A_cl)
    for k in range(3):
        J, xT = ivp_cost(A_cl, W, X0[k], 5.0)
        assert cost[k] == pytest.approx(J, rel=1e-9)
        np.testing.assert_allclose(x_final[k], xT, rtol=1e-9, atol=1e-11)


@pytest.mark.parametrize("seed", range(3))
def test_one_candidate_costs_what_it_costs_in_a_batch(seed):
    """problem=lqr evaluates one candidate by the Schur route and a batch by the eigen-route:
    the same cost and status to round-off."""
    rng = np.random.default_rng(200 + seed)
    n, m = 7, 2
    A, B = random_plant(rng, n, m)
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(),
                                        "x0": rng.normal(size=(4, n)).tolist(),
                                        "t_max": 8.0})
    Q = np.stack([spd(rng, n) for _ in range(3)])
    R = np.stack([spd(rng, m) for _ in range(3)])
    batch = prob.evaluate_batch({"Q": Q, "R": R})
    for c in range(3):
        one = prob.evaluate_batch({"Q": Q[c:c + 1], "R": R[c:c + 1]})
        assert one.cost[0] == pytest.approx(batch.cost[c], rel=1e-11)
        assert one.status[0] == batch.status[c]


def test_defective_and_unstable_loops_take_the_fallback_exactly():
    """A Jordan block (eigenvectors parallel) and a non-Hurwitz loop."""
    jordan = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]])
    unstable = np.array([[0.3, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.5, -2.0]])
    A_cl = np.stack([jordan, unstable])
    _, V = np.linalg.eig(jordan)
    assert np.linalg.cond(V) > COND_MAX
    W = np.stack([np.eye(3), np.diag([1.0, 2.0, 3.0])])
    X0 = np.array([[1.0, -1.0, 2.0]])
    cost, x_final = quadratic_cost(A_cl, W, X0, 4.0)
    for b in range(2):
        J, xT = ivp_cost(A_cl[b], W[b], X0[0], 4.0)
        assert cost[b, 0] == pytest.approx(J, rel=1e-9)
        np.testing.assert_allclose(x_final[b, 0], xT, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_problem_cost_is_the_closed_form(seed):
    """J = mean x0ᵀ (S − e^{A_clᵀT} S e^{A_cl T}) x0 with the scipy gain, to 1e-9."""
    rng = np.random.default_rng(10 + seed)
    n, m = 4, 2
    A, B = random_plant(rng, n, m)
    X0 = rng.normal(size=(3, n))
    Wx, Wu = spd(rng, n), spd(rng, m)
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(), "x0": X0.tolist(),
                                        "t_max": 2.5, "state_weight": Wx.tolist(),
                                        "input_weight": Wu.tolist()})
    Q = np.stack([spd(rng, n) for _ in range(5)])
    R = np.stack([spd(rng, m) for _ in range(5)])
    batch = prob.evaluate_batch({"Q": Q, "R": R})
    for c in range(5):
        ref = reference.linear_cost(A, B, Q[c], R[c], Wx, Wu, X0, 2.5).mean()
        assert batch.cost[c] == pytest.approx(ref, rel=1e-9)
        one = prob.evaluate({"Q": Q[c], "R": R[c]})
        assert one["cost"] == pytest.approx(batch.cost[c], rel=1e-12)
        assert one["method"] == "closed_form" and one["status"] == "converged"
        np.testing.assert_allclose(one["gain"], reference.gain(A, B, Q[c], R[c]), rtol=1e-8,
                                   atol=1e-10)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), log_c=st.floats(-3.0, 3.0))
def test_scaling_q_and_r_together_leaves_the_cost_unchanged(seed, log_c):
    rng = np.random.default_rng(seed)
    prob = lqr.make_problem("default", {})
    Q, R = spd(rng, 3, 0.5), spd(rng, 2, 0.5)
    c = 10.0 ** log_c
    costs = prob.evaluate_batch({"Q": np.stack([Q, c * Q]), "R": np.stack([R, c * R])}).cost
    assert costs[1] == pytest.approx(costs[0], rel=1e-8)


def test_the_performance_lqr_is_the_optimum_of_the_known_answer_set_up():
    prob = lqr.make_problem("default", {})
    Wx = np.asarray(lqr.KNOWN_ANSWER["state_weight"])
    Wu = np.asarray(lqr.KNOWN_ANSWER["input_weight"])
    J_star = prob.evaluate({"Q": Wx, "R": Wu})["cost"]
    assert J_star == pytest.approx(prob.optimum, rel=1e-12)  # the tail beyond t_max is nil
    rng = np.random.default_rng(3)
    Q = np.stack([spd(rng, 3, 0.2) for _ in range(200)])
    R = np.stack([spd(rng, 2, 0.2) for _ in range(200)])
    assert np.all(prob.evaluate_batch({"Q": Q, "R": R}).cost >= J_star * (1 - 1e-12))
