"""problem=lqr as a penaltyrun problem: protocol, statuses and graded penalties, held-out
set, multi-scenario tuning."""

import numpy as np
import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import problem as lqr_problem

A = [[0.0, 1.0], [2.0, -0.1]]
B = [[0.0], [1.0]]


def test_registered_and_follows_the_protocol():
    assert "lqr" in problems.available()
    mod = problems.check_module(problems.module("lqr"), "lqr")
    prob = problems.check_problem(problems.make("lqr", None, {}), "lqr")
    assert mod.DEFAULT_CASE in mod.CASES and prob.name == "lqr"
    assert [(s.name, s.size) for s in prob.matrices] == [("Q", 3), ("R", 2)]
    sim = prob.simulate({"Q": np.eye(3), "R": np.eye(2)}, n_points=50)
    assert sim["x"].shape == (3, 50, 3) and sim["u"].shape == (3, 50, 2)
    final = prob.evaluate({"Q": np.eye(3), "R": np.eye(2)})
    assert sim["J"][:, -1].mean() == pytest.approx(final["cost"], rel=1e-7)


def test_plot_histories(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    prob = lqr.make_problem("default", {"u_max": 0.8})
    paths = {label: prob.simulate({"Q": Q, "R": np.eye(2)}, n_points=60)
             for label, Q in (("identity", np.eye(3)), ("weights", 3 * np.eye(3)))}
    lqr.plot_histories(paths, out=tmp_path / "h.png")
    assert (tmp_path / "h.png").stat().st_size > 0


def test_riccati_failures_are_graded_by_their_size(monkeypatch):
    prob = lqr.make_problem("default", {})
    P = prob.penalty
    nan_q = np.full((1, 3, 3), np.nan)
    batch = prob.evaluate_batch({"Q": nan_q, "R": np.eye(2)[None]})
    assert batch.status[0] == "care_failure" and batch.cost[0] == pytest.approx(20 * P)
    sizes = np.array([1e-9, 1e-3, 1.0, np.inf])

    def failing(A_, B_, Q, R):
        return np.zeros((4, 2, 3)), np.zeros(4, bool), sizes

    monkeypatch.setattr(lqr_problem, "lqr_gains", failing)
    cost = prob.evaluate_batch({"Q": np.stack([np.eye(3)] * 4),
                                "R": np.stack([np.eye(2)] * 4)}).cost
    assert np.all(np.diff(cost) > 0) and 10 * P < cost[0] and cost[-1] == pytest.approx(20 * P)


def test_settle_rule_adds_a_graded_penalty():
    base = {"A": A, "B": B, "x0": [[1.0, 0.0]], "t_max": 3.0}
    loose = lqr.make_problem("default", base).evaluate({"Q": np.eye(2), "R": np.eye(1)})
    strict = lqr.make_problem("default", {**base, "settle_tol": 1e-9,
                                          "failure_penalty": 50.0})
    ev = strict.evaluate({"Q": np.eye(2), "R": np.eye(1)})
    assert loose["status"] == "converged" and ev["status"] == "not_settled"
    r = ev["final_state_ratio"][0]
    assert ev["cost"] == pytest.approx(loose["cost"] + 50.0 * (1 + r / (1 + r)), rel=1e-12)
    better = strict.evaluate({"Q": 10 * np.eye(2), "R": 0.1 * np.eye(1)})
    assert better["final_state_ratio"][0] < r  # a faster loop gets closer


def test_candidate_takes_its_worst_start():
    prob = lqr.make_problem("default", {"A": A, "B": B, "x0": [[0.1, 0.0], [2.0, 0.0]],
                                        "u_max": 0.5, "t_max": 8.0})
    ev = prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})
    assert ev["start_status"] == ["converged", "diverged"]
    assert ev["status"] == "diverged" and not ev["converged"]
    assert ev["cost"] == pytest.approx(np.mean(ev["start_costs"]))


def test_holdout_set():
    prob = lqr.make_problem("default", {})
    held = prob.holdout({"Q": np.eye(3), "R": np.eye(2)})
    assert len(held["cost"]) == 16 and np.all(held["converged"])
    radius = np.linalg.norm(held["x0"], axis=1)
    np.testing.assert_allclose(radius, 1.0)  # the mean norm of the unit training starts
    again = lqr.make_problem("default", {}).holdout_scenarios()["x0"]
    np.testing.assert_array_equal(again, held["x0"])  # seeded
    given = lqr.make_problem("default", {"holdout_x0": [[1, 1, 0]]})
    assert given.holdout({"Q": np.eye(3), "R": np.eye(2)})["cost"].shape == (1,)
    assert lqr.make_problem("default", {"holdout_n": 0}).holdout(
        {"Q": np.eye(3), "R": np.eye(2)}) is None


def test_multi_scenario_tuning_and_disjoint_holdout():
    prob = problems.make("lqr", None, {"train_scenarios": [{}, {"x0": [[1, 1, 1]]}]})
    mats = {"Q": np.eye(3), "R": np.eye(2)}
    ev = prob.evaluate(mats)
    single = [problems.make("lqr", None, o).evaluate(mats)["cost"]
              for o in ({}, {"x0": [[1, 1, 1]]})]
    assert ev["cost"] == pytest.approx(np.mean(single), rel=1e-12)
    sampled = problems.make("lqr", None, {"train_sample": 3})
    assert len(sampled.scenarios) == 3
    with pytest.raises(ConfigError, match="held-out"):
        problems.make("lqr", None, {"holdout_x0": [[1, 1, 1]],
                                    "train_scenarios": [{"x0": [[1, 1, 1]]}]})


def test_report_hooks():
    from penaltyrun.problems import base

    if not hasattr(base, "ReportInfo"):
        pytest.skip("the report-hook protocol (ReportInfo) is not on this branch")
    info = lqr.report_info("default", {"A": A, "B": B, "cost_unit": "m^2 s"})
    assert isinstance(info, base.ReportInfo) and info.cost_unit == "m^2 s"
    assert "16 initial states" in info.holdout_description
    assert lqr.report_info("default", {"holdout_n": 0}).holdout_description == ""


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_histories_of_a_linear_loop_equal_the_integrated_ones(seed):
    """A linear plant without input limits is sampled exactly (powers of e^{A_cl h}, Van
    Loan's cost increments); the DOP853 path of saturated or nonlinear plants gives the
    same histories at tight tolerances."""
    rng = np.random.default_rng(seed)
    A_ = rng.standard_normal((3, 3))
    B_ = rng.standard_normal((3, 2))
    params = {"A": A_.tolist(), "B": B_.tolist(), "x0": rng.standard_normal((2, 3)).tolist(),
              "t_max": 4.0, "rtol": 1e-12, "atol": 1e-12}
    prob = lqr.make_problem("default", params)
    Q = np.diag(rng.uniform(0.5, 3.0, 3))
    exact = prob.simulate({"Q": Q, "R": np.eye(2)}, n_points=80)
    K = prob.gains(Q[None], np.eye(2)[None])[0][0]
    x, J = prob._integrated(K, exact["t"])
    scale = np.abs(x).max()
    np.testing.assert_allclose(exact["x"], x, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(exact["J"], J, rtol=1e-9, atol=1e-12 * J.max())
    np.testing.assert_allclose(exact["u"], -x @ K.T, rtol=0, atol=1e-8 * scale)
