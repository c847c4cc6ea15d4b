"""Saturated and nonlinear loops (penaltyrun/dynamics/linear_feedback.py through
problem=lqr) against scipy solve_ivp, and the exact cutoff."""

import sys
import textwrap

import numpy as np
import pytest

from penaltyrun.dynamics import linear_feedback as loop
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import reference

A = [[0.0, 1.0], [2.0, -0.1]]
B = [[0.0], [1.0]]
PENDULUM = '''
import numpy as np


def f(X, U):
    """Damped pendulum about its upright position, torque input."""
    th, om = X[:, 0], X[:, 1]
    return np.stack([om, 9.81 * np.sin(th) - 0.2 * om + U[:, 0]], axis=1)
'''


@pytest.fixture
def pendulum(tmp_path, monkeypatch):
    (tmp_path / "lqr_pendulum_model.py").write_text(textwrap.dedent(PENDULUM))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "lqr_pendulum_model:f"
    sys.modules.pop("lqr_pendulum_model", None)


@pytest.mark.parametrize("u_max", [0.6, 2.0])
def test_saturated_linear_loop_matches_solve_ivp(u_max):
    x0 = [[0.3, 0.0], [-0.2, 0.4], [0.1, -0.5]]
    prob = lqr.make_problem("default", {"A": A, "B": B, "x0": x0, "t_max": 8.0,
                                        "u_max": u_max, "input_weight": [[0.5]]})
    Q, R = np.diag([10.0, 1.0]), np.array([[0.1]])
    ev = prob.evaluate({"Q": Q, "R": R})
    assert ev["method"] == "integrated" and ev["status"] == "converged"
    K = np.asarray(ev["gain"])
    assert np.abs(K @ np.asarray(x0).T).max() > u_max  # the limit is active
    refs = [reference.integrated_cost(prob.plant.f, K, np.asarray(x), np.eye(2),
                                      np.array([[0.5]]), np.array([u_max]), 8.0)[0]
            for x in x0]
    np.testing.assert_allclose(ev["start_costs"], refs, rtol=1e-8)


def test_nonlinear_dynamics_matches_solve_ivp_and_linearizes_by_jacobian(pendulum):
    x0 = [[0.8, 0.0], [-0.5, 1.0]]
    prob = lqr.make_problem("default", {"dynamics": pendulum, "x0": x0, "t_max": 6.0,
                                        "input_weight": [[0.2]], "u_max": 8.0})
    assert prob.plant.source == "dynamics"
    np.testing.assert_allclose(prob.plant.A, [[0.0, 1.0], [9.81, -0.2]], atol=1e-8)
    np.testing.assert_allclose(prob.plant.B, [[0.0], [1.0]], atol=1e-8)
    Q, R = np.eye(2), np.array([[0.2]])
    ev = prob.evaluate({"Q": Q, "R": R})
    K = np.asarray(ev["gain"])
    for x, cost in zip(x0, ev["start_costs"]):
        ref, _ = reference.integrated_cost(prob.plant.f, K, np.asarray(x), np.eye(2),
                                           np.array([[0.2]]), np.array([8.0]), 6.0)
        assert cost == pytest.approx(ref, rel=1e-8)


def test_unsaturated_integrator_agrees_with_the_closed_form():
    rng = np.random.default_rng(4)
    n, m = 4, 2
    Am, Bm = rng.normal(size=(n, n)), rng.normal(size=(n, m))
    X0 = rng.normal(size=(3, n))
    K = reference.gain(Am, Bm, np.eye(n), np.eye(m))
    run = loop.simulate(lambda X, U: X @ Am.T + U @ Bm.T, np.repeat(K[None], 3, 0), X0,
                        np.eye(n), np.eye(m), None, 5.0)
    exact = reference.linear_cost(Am, Bm, np.eye(n), np.eye(m), np.eye(n), np.eye(m), X0, 5.0)
    assert np.all(run["status"] == loop.HORIZON)
    np.testing.assert_allclose(run["cost"], exact, rtol=1e-8)


def test_cutoff_is_exact():
    """Uncut candidates get exactly their uncut cost; cut ones a cost above the threshold
    and at most their uncut cost, also when some starts diverge (graded costs ≥ J)."""
    x0 = [[0.3, 0.0], [-0.2, 0.4], [2.0, 0.0]]
    prob = lqr.make_problem("default", {"A": A, "B": B, "x0": x0, "t_max": 8.0,
                                        "u_max": 1.5, "failure_penalty": 1e12})
    rng = np.random.default_rng(2)
    Q = np.stack([np.diag(10 ** rng.uniform(-1, 1.5, 2)) for _ in range(8)])
    R = 10 ** rng.uniform(-1, 1, (8, 1, 1))
    full = prob.evaluate_batch({"Q": Q, "R": R})
    raw = prob.rows(Q, R, prob.x0)
    assert "diverged" in set(raw["status"][:, 2])
    thr = np.where(np.arange(8) % 2 == 0, 0.5 * raw["J"].mean(axis=1), np.inf)
    cut = prob.evaluate_batch({"Q": Q, "R": R}, thresholds=thr)
    for c in range(8):
        if cut.status[c] == "cutoff":
            assert thr[c] < cut.cost[c] <= full.cost[c] * (1 + 1e-12)
        else:
            assert cut.cost[c] == full.cost[c]
    assert (cut.status == "cutoff").sum() >= 3
    assert np.all(cut.status[1::2] == full.status[1::2])


def test_blow_up_is_a_graded_failure():
    """An input too weak to hold the unstable plant: diverged, ranked by how early."""
    prob = lqr.make_problem("default", {"A": A, "B": B, "x0": [[1.0, 0.0]], "t_max": 10.0,
                                        "u_max": 0.5})
    ev = prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})
    assert ev["status"] == "diverged" and not ev["converged"]
    P = ev["failure_penalty"]
    assert 2 * P < ev["cost"] <= 3 * P + ev["start_costs"][0] and ev["t_final"] < 10.0
    far = lqr.make_problem("default", {"A": A, "B": B, "x0": [[3.0, 0.0]], "t_max": 10.0,
                                       "u_max": 0.5, "failure_penalty": P})
    assert far.evaluate({"Q": np.eye(2), "R": np.eye(1)})["t_final"] < ev["t_final"]
