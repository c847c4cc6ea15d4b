"""The cart-pole example (examples/cartpole: problem=lqr with `dynamics: cartpole:dynamics`)
against independent references: the hand-derived linearization, energy conservation
without force, and scipy solve_ivp on Lagrange's equations solved as a 2x2 linear system
for the saturated closed loop."""

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.integrate import solve_ivp

from penaltyrun import problems
from penaltyrun.dynamics import linear_feedback as loop

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cartpole"
sys.path.insert(0, str(EXAMPLE))
import cartpole as cp  # noqa: E402

M, m, l, g = cp.CART_MASS, cp.POLE_MASS, cp.LENGTH, cp.GRAVITY


def config_params(**changes):
    params = yaml.safe_load((EXAMPLE / "conf" / "problem" / "cartpole.yaml").read_text())
    return {**params["params"], **changes}


def reference_rhs(t, y, K, u_max):
    """Lagrange's equations as a 2x2 linear system (independent of cp.dynamics)."""
    x, xd, th, om, _ = y
    F = float(np.clip(-K @ y[:4], -u_max, u_max))
    mass = np.array([[M + m, m * l * np.cos(th)], [m * l * np.cos(th), m * l**2]])
    force = np.array([F + m * l * np.sin(th) * om**2, m * g * l * np.sin(th)])
    xdd, thdd = np.linalg.solve(mass, force)
    return [xd, xdd, om, thdd, x**2 + th**2 + 0.01 * F**2]


def energy(s):
    xd, th, om = s[..., 1], s[..., 2], s[..., 3]
    kin = 0.5 * (M + m) * xd**2 + m * l * np.cos(th) * xd * om + 0.5 * m * l**2 * om**2
    return kin + m * g * l * np.cos(th)


def test_jacobians_match_the_hand_linearization():
    prob = problems.make("lqr", None, config_params())
    A = np.array([[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -m * g / M, 0.0],
                  [0.0, 0.0, 0.0, 1.0], [0.0, 0.0, (M + m) * g / (M * l), 0.0]])
    B = np.array([[0.0], [1.0 / M], [0.0], [-1.0 / (M * l)]])
    np.testing.assert_allclose(prob.plant.A, A, atol=1e-8)
    np.testing.assert_allclose(prob.plant.B, B, atol=1e-8)


def test_energy_is_conserved_without_force():
    s0 = np.array([[0.0, 0.3, 0.4, -0.5]])
    angles = []
    for t_max in (0.5, 1.0, 1.5, 2.0, 3.0):
        run = loop.simulate(cp.dynamics, np.zeros((1, 1, 4)), s0, np.eye(4), np.eye(1),
                            None, t_max, rtol=1e-12, atol=1e-14)
        assert run["status"][0] == loop.HORIZON
        assert energy(run["x_final"][0]) == pytest.approx(energy(s0[0]), rel=1e-10)
        angles.append(abs(run["x_final"][0, 2]))
    assert max(angles) > 2.0  # the pole swings far through the bottom


def test_saturated_closed_loop_matches_solve_ivp():
    prob = problems.make("lqr", None, config_params(settle_tol=None))
    Q, R = np.diag([1.0, 0.5, 20.0, 1.0]), np.array([[0.05]])
    ev = prob.evaluate({"Q": Q, "R": R})
    K = np.asarray(ev["gain"])[0]
    assert ev["method"] == "integrated" and ev["status"] == "converged"
    for x0, cost in zip(prob.x0, ev["start_costs"]):
        sol = solve_ivp(reference_rhs, (0.0, 8.0), [*x0, 0.0], args=(K, 10.0),
                        method="DOP853", rtol=1e-12, atol=1e-13)
        assert cost == pytest.approx(sol.y[4, -1], rel=1e-7)
    assert np.abs(K @ prob.x0[0]) > 10.0  # the limit is active from the far start


def test_batch_agrees_with_single_and_failures_are_graded():
    prob = problems.make("lqr", None, config_params())
    rng = np.random.default_rng(1)
    Q = np.stack([np.diag(10 ** rng.uniform(-2, 2, 4)) for _ in range(6)])
    R = 10 ** rng.uniform(-2, 1, (6, 1, 1))
    batch = prob.evaluate_batch({"Q": Q, "R": R})
    assert np.all(np.isfinite(batch.cost))
    for b in range(6):
        one = prob.evaluate({"Q": Q[b], "R": R[b]})
        assert one["cost"] == pytest.approx(batch.cost[b], rel=1e-12)
        assert one["status"] == batch.status[b]
    weak = problems.make("lqr", None, config_params(u_max=1.0))
    ev = weak.evaluate({"Q": np.eye(4), "R": np.eye(1)})
    assert ev["status"] == "diverged" and ev["cost"] > 2 * ev["failure_penalty"]
