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


def _holdout_one_call_per_start(prob, K, sc):
    """The held-out runs as they were computed before: one kernel call per start."""
    out = {k: [] for k in ("cost", "energy", "converged", "status", "t_final",
                           "final_distance")}
    for x0 in sc["x0"]:
        t_end, energy, dist, status = prob._run(K[None], x0)
        be = prob._graded(t_end, energy, dist, status, float(np.hypot(*x0)))
        for key, value in (("cost", be.cost[0]), ("energy", energy[0]),
                           ("converged", be.converged[0]), ("status", be.status[0]),
                           ("t_final", t_end[0]), ("final_distance", dist[0])):
            out[key].append(value)
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_batched_holdout_is_the_per_start_holdout(seed):
    """All held-out starts in one kernel call give, bit for bit, the runs of one call per
    start, failures (a gain too weak to arrive, one that stalls) included."""
    rng = np.random.default_rng(seed)
    prob = make_problem("default", {"t_max": 30.0, "max_steps": 400})
    sc = prob.holdout_scenarios()
    gains = [PAPER_K_FULL, np.diag([1e-3, 1e-3]), np.diag([50.0, 0.02])]
    L = rng.normal(size=(2, 2))
    gains.append(L @ L.T + 0.05 * np.eye(2))
    seen = set()
    for K in gains:
        K = np.asarray(K, dtype=float)
        batched = prob._holdout_runs({"K": K}, sc)
        old = _holdout_one_call_per_start(prob, K, sc)
        for key, values in old.items():
            assert batched[key].tolist() == list(values), key
        assert batched["status"].dtype == object
        seen |= set(batched["status"])
    assert {"converged", "horizon"} <= seen
