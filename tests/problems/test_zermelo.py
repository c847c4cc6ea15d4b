"""Zermelo problem: compiled path vs scipy solve_ivp, paper matrices, failures, errors."""

import numpy as np
import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems import zermelo
from penaltyrun.problems.zermelo import PAPER_K_FULL, Params, make_problem, reference_cost


@pytest.fixture(scope="module")
def prob():
    return problems.make("zermelo", None, {})


def random_spd(rng, n, lo=0.05, hi=10.0):
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return Q @ np.diag(rng.uniform(lo, hi, n)) @ Q.T


def test_costs_agree_with_solve_ivp_reference(prob):
    rng = np.random.default_rng(7)
    Ks = np.array([random_spd(rng, 2) for _ in range(12)])
    batch = prob.evaluate_batch({"K": Ks})
    for K, cost, ok in zip(Ks, batch.cost, batch.converged):
        ref_cost, _, ref_ok = zermelo.reference_cost(K, prob.params)
        assert ok and ref_ok
        assert cost == pytest.approx(ref_cost, rel=1e-6)


def test_paper_matrices(prob):
    k1 = prob.evaluate({"K": zermelo.PAPER_K_DIAGONAL})
    k2 = prob.evaluate({"K": zermelo.PAPER_K_FULL})
    assert k1["converged"] and k2["converged"]
    assert k2["cost"] < k1["cost"]
    for res, K in ((k1, zermelo.PAPER_K_DIAGONAL), (k2, zermelo.PAPER_K_FULL)):
        ref_cost, ref_t, _ = zermelo.reference_cost(K)
        assert res["cost"] == pytest.approx(ref_cost, rel=1e-8)
        assert res["t_final"] == pytest.approx(ref_t, rel=1e-8)
        assert res["final_distance"] == pytest.approx(1e-3, rel=1e-9)


def test_closed_loop_is_linear_and_energy_decreases(prob):
    K = zermelo.PAPER_K_FULL
    path = prob.simulate({"K": K})
    X = np.stack([path["x"], path["y"]], axis=1)
    # Exact solution X(t) = expm(−Kᵀ t) X0 of the cancelled-current closed loop.
    from scipy.linalg import expm

    for i in (50, 200, 399):
        assert X[i] == pytest.approx(expm(-K.T * path["t"][i]) @ X[0], abs=1e-7)
    V = 0.5 * np.sum(X**2, axis=1)
    assert np.all(np.diff(V) < 0)


def test_non_converging_gain_gets_graded_finite_penalty():
    prob = problems.make("zermelo", None, {"t_max": 5.0})
    Ks = np.array([np.eye(2) * 0.01, np.eye(2) * 0.1])
    batch = prob.evaluate_batch({"K": Ks})
    assert not batch.converged.any()
    assert np.all(np.isfinite(batch.cost))
    assert list(batch.status) == ["horizon", "horizon"]
    # the slower gain is further away at t_max, so it is penalized more
    assert batch.cost[0] > batch.cost[1] > prob.params.failure_penalty


@pytest.mark.parametrize(
    ("matrix", "fragment"),
    [
        ([[1.0, 0.5], [0.4, 1.0]], "not symmetric"),
        ([[1.0, 2.0], [2.0, 1.0]], "not positive definite"),
        ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "2x2"),
        ([[1.0, "a"], ["a", 1.0]], "numeric"),
    ],
)
def test_bad_matrices_are_clear_errors(prob, matrix, fragment):
    with pytest.raises(ConfigError, match=fragment) as info:
        prob.evaluate({"K": matrix})
    assert info.value.key == "matrices.K"



@pytest.mark.parametrize("key, value", [("t_max", -1.0), ("t_max", 0.0),
                                        ("event_radius", -1.0), ("rtol", 0.0),
                                        ("max_step", 0.0), ("max_steps", 0),
                                        ("failure_penalty", float("nan")),
                                        ("x0", (float("inf"), 1.0))])
def test_settings_out_of_range_are_refused_when_built(key, value):
    """Refused before a run spends its budget (a negative t_max was accepted, and the
    run's own records were then refused by the reader: negative times)."""
    with pytest.raises(ConfigError) as info:
        problems.make("zermelo", None, {key: value})
    assert info.value.key == f"problem.params.{key}"

def test_unknown_case_and_param():
    with pytest.raises(ConfigError, match="allowed: default"):
        problems.make("zermelo", "B", {})
    with pytest.raises(ConfigError, match="problem.params.speed"):
        problems.make("zermelo", None, {"speed": 3})
    with pytest.raises(ConfigError, match="unknown problem 'nope'"):
        problems.make("nope", None, {})


# ------------------------------------------------------------------ held-out starts


def test_holdout_starts_on_circles_match_reference():
    prob = make_problem("default", {"holdout_radii": (2.0, 10.0), "holdout_n_angles": 4})
    sc = prob.holdout_scenarios()
    assert sc["x0"].shape == (8, 2)
    np.testing.assert_allclose(np.hypot(*sc["x0"].T), [2.0] * 4 + [10.0] * 4)
    held = prob.holdout({"K": PAPER_K_FULL})
    assert list(held["scenario"]) == list(sc["scenario"])
    for k, x0 in enumerate(sc["x0"]):
        cost, t_final, converged = reference_cost(PAPER_K_FULL, Params(x0=tuple(x0)))
        assert held["converged"][k] == converged
        assert held["cost"][k] == pytest.approx(cost, rel=1e-6)
        assert held["t_final"][k] == pytest.approx(t_final, rel=1e-6)


def test_holdout_leaves_out_the_training_start():
    x0 = (10.0, 0.0)
    prob = make_problem("default", {"x0": x0, "holdout_radii": (10.0,), "holdout_n_angles": 4})
    sc = prob.holdout_scenarios()
    assert sc["x0"].shape == (3, 2) and "r=10,deg=0" not in list(sc["scenario"])
    assert prob.training_scenario()["x0"] == [10.0, 0.0]
    assert make_problem("default", {"holdout_radii": ()}).holdout({"K": PAPER_K_FULL}) is None


@pytest.mark.parametrize("key,value", [("holdout_radii", (1.0, -2.0)), ("holdout_n_angles", 0)])
def test_bad_holdout_settings(key, value):
    with pytest.raises(ConfigError, match=key):
        make_problem("default", {key: value})


# ------------------------------------------------------------------ closed form vs integrator


def _integrator(prob, K, x0=None):
    p = prob.params
    x0 = np.asarray(p.x0 if x0 is None else x0, float)
    return zermelo.simulate_batch(np.ascontiguousarray(K), x0, p.t_max, p.event_radius,
                                  p.rtol, p.atol, p.max_step, p.max_steps)


def test_evaluate_batch_matches_the_integrator_on_decoded_candidates(prob):
    from penaltyrun.runner.setup import build_layout

    layout = build_layout(prob, "full", {})
    lb, ub = layout.bounds()
    Z = lb + np.random.default_rng(11).random((60, lb.size)) * (ub - lb)
    K = layout.split(Z)[0]["K"]
    batch = prob.evaluate_batch({"K": K})
    ref = prob._graded(*_integrator(prob, K), float(np.hypot(*prob.params.x0)))
    np.testing.assert_array_equal(batch.status, ref.status)
    assert "converged" in set(batch.status)
    np.testing.assert_allclose(batch.cost, ref.cost, rtol=1e-8)


@pytest.mark.slow
def test_non_symmetric_gain_is_integrated(prob):
    # outside the closed form (Kᵀ ≠ K); its symmetric part is PD, so the event fires
    K = np.array([[[1.0, 0.7], [-0.3, 0.8]], [[1.0, 0.2], [0.2, 0.5]]])
    batch = prob.evaluate_batch({"K": K})
    t_end, cost, _, status = _integrator(prob, K[:1])
    assert batch.status[0] == "converged" and status[0] == 0
    assert batch.cost[0] == cost[0]  # the integrator's own result, bitwise
    assert batch.cost[0] == pytest.approx(reference_cost(K[0], prob.params)[0], rel=1e-8)


def test_holdout_batch_matches_one_start_at_a_time():
    prob = make_problem("default", {"holdout_radii": (2.0, 10.0), "holdout_n_angles": 3})
    K = np.diag([0.02, 3.0])
    res = prob._holdout_runs({"K": K}, prob.holdout_scenarios())
    for k, x0 in enumerate(prob.holdout_scenarios()["x0"]):
        t_end, energy, dist, status = _integrator(prob, K[None], x0)
        be = prob._graded(t_end, energy, dist, status, float(np.hypot(*x0)))
        assert res["status"][k] == be.status[0]
        assert res["cost"][k] == pytest.approx(be.cost[0], rel=1e-8)
        assert res["t_final"][k] == pytest.approx(t_end[0], rel=1e-8)
