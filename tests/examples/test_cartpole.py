"""The cart-pole example (examples/cartpole/cartpole.py) against independent references:
finite differences for the linearization, energy conservation without force, scipy
solve_ivp for the saturated closed loop, and a Hamiltonian-eigenvector Riccati solution
for the LQR gain."""

import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from penaltyrun import problems

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cartpole"
sys.path.insert(0, str(EXAMPLE))
import cartpole as cp  # noqa: E402

P = cp.Params()


def reference_rhs(t, y, K, p):
    """Lagrange's equations solved as a 2x2 linear system (independent of cp.rhs)."""
    x, xd, th, om, _ = y
    M, m, l, g = p.cart_mass, p.pole_mass, p.length, p.gravity
    F = float(np.clip(-K @ y[:4], -p.u_max, p.u_max))
    mass = np.array([[M + m, m * l * np.cos(th)], [m * l * np.cos(th), m * l**2]])
    force = np.array([F + m * l * np.sin(th) * om**2, m * g * l * np.sin(th)])
    xdd, thdd = np.linalg.solve(mass, force)
    return [xd, xdd, om, thdd, x**2 + th**2 + p.rho * F**2]


def care_hamiltonian(A, B, Q, R):
    """P from the stable eigenvectors of the Hamiltonian matrix (second CARE solver)."""
    n = A.shape[0]
    H = np.block([[A, -B @ np.linalg.solve(R, B.T)], [-Q, -A.T]])
    w, V = np.linalg.eig(H)
    stable = V[:, w.real < 0]
    return np.real(stable[n:] @ np.linalg.inv(stable[:n]))


def test_linearization_matches_finite_differences():
    A, B = cp.linearization(P)
    h = 1e-6
    s0 = np.zeros((1, 4))
    A_fd = np.column_stack([(cp.rhs(s0 + h * e, np.zeros(1), P)
                             - cp.rhs(s0 - h * e, np.zeros(1), P))[0] / (2 * h)
                            for e in np.eye(4)[:, None, :]])
    B_fd = (cp.rhs(s0, np.array([h]), P) - cp.rhs(s0, np.array([-h]), P))[0] / (2 * h)
    np.testing.assert_allclose(A, A_fd, atol=1e-7)
    np.testing.assert_allclose(B[:, 0], B_fd, atol=1e-7)


@pytest.mark.parametrize("seed", range(4))
def test_lqr_gain_matches_hamiltonian_solution(seed):
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(4, 4))
    Q = L @ L.T + 0.1 * np.eye(4)
    R = np.array([[10 ** rng.uniform(-2, 1)]])
    A, B = cp.linearization(P)
    K = cp.lqr_gain(Q, R, P)
    K_ref = np.linalg.solve(R, B.T @ care_hamiltonian(A, B, Q, R))
    np.testing.assert_allclose(K, K_ref, rtol=1e-8, atol=1e-8)
    assert np.all(np.linalg.eigvals(A - B @ K).real < 0)


def test_energy_is_conserved_without_force():
    p = cp.Params(s0=(0.0, 0.3, 0.4, -0.5), t_max=3.0, dt=0.001, theta_fail=1e9,
                  x_max=1e9, u_max=0.0)
    run = cp.simulate_batch(np.zeros((1, 4)), p, record=True)
    E = cp.energy(run["s"][:, 0, :], p)
    assert np.abs(run["s"][:, 0, 2]).max() > 2.0  # the pole swings far through the bottom
    assert np.max(np.abs(E - E[0])) < 1e-8 * abs(E[0]) + 1e-9


def _error_vs_solve_ivp(p, K):
    run = cp.simulate_batch(K[None], p, record=True)
    sol = solve_ivp(reference_rhs, (0.0, p.t_max), [*p.s0, 0.0], args=(K, p),
                    method="DOP853", rtol=1e-11, atol=1e-11, max_step=0.002,
                    t_eval=run["t"])
    state_err = np.abs(run["s"][:, 0, :] - sol.y[:4].T).max()
    return run, state_err, abs(run["cost"][0] / sol.y[4, -1] - 1.0), sol.y[4, -1]


@pytest.mark.parametrize("case", cp.CASES)
def test_saturated_closed_loop_matches_solve_ivp(case):
    """The actuator limit's kink makes fixed-step RK4 second order where the force leaves
    the limit: states agree to ~1e-4 at the default 5 ms step, and better with a finer one."""
    prob = cp.make_problem(case, {})
    p = prob.params
    Q, R = np.diag([1.0, 0.5, 20.0, 1.0]), np.array([[0.05]])
    K = cp.lqr_gain(Q, R, p)[0]
    run, state_err, cost_err, ref_cost = _error_vs_solve_ivp(p, K)
    assert np.abs(run["F"]).max() == pytest.approx(p.u_max)  # the limit is active
    assert state_err < 5e-4 and cost_err < 2e-5
    fine = cp.Params(**{**p.__dict__, "dt": p.dt / 4})
    _, fine_state_err, fine_cost_err, _ = _error_vs_solve_ivp(fine, K)
    assert fine_state_err < state_err / 4 and fine_cost_err < cost_err / 4
    ev = prob.evaluate({"Q": Q, "R": R})
    assert ev["converged"] and ev["cost"] == pytest.approx(ref_cost, rel=2e-5)


def test_problem_follows_the_protocol_and_batch_agrees_with_single():
    mod = problems.check_module(cp, "cartpole")
    prob = problems.check_problem(mod.make_problem("far", {}), "cartpole")
    rng = np.random.default_rng(1)
    Q = np.stack([np.diag(10 ** rng.uniform(-2, 2, 4)) for _ in range(6)])
    R = 10 ** rng.uniform(-2, 1, (6, 1, 1))
    batch = prob.evaluate_batch({"Q": Q, "R": R})
    assert np.all(np.isfinite(batch.cost))
    for b in range(6):
        one = prob.evaluate({"Q": Q[b], "R": R[b]})
        assert one["cost"] == pytest.approx(batch.cost[b], rel=1e-12)
        assert one["status"] == batch.status[b]
        assert one["converged"] == (batch.status[b] == "converged")


def test_failures_are_graded_not_infinite():
    prob = cp.make_problem("far", {"u_max": 2.0})  # too weak to catch the pole at 35°
    ev = prob.evaluate({"Q": np.eye(4), "R": np.eye(1)})
    assert ev["status"] in ("fell", "off_track") and not ev["converged"]
    assert ev["t_final"] < prob.params.t_max
    assert prob.params.failure_penalty < ev["cost"] < 2 * prob.params.failure_penalty + 100
    slow = cp.make_problem("near", {"t_max": 1.0}).evaluate({"Q": np.eye(4), "R": np.eye(1)})
    assert slow["status"] == "not_settled" and np.isfinite(slow["cost"])
