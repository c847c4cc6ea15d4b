"""Held-out set of the rendezvous MPC (sphere starts, eccentric target orbit, thrust errors)
and multi-scenario tuning on it."""

import numpy as np
import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems.mpc import scenarios as scen

MATS = {"Q": np.diag([1.0, 1, 1, 100, 100, 100]), "R": 1e4 * np.eye(3)}


def test_sphere_starts_are_at_rest_on_the_sphere():
    s = scen.sphere_starts(50, 1000.0, 3)
    np.testing.assert_allclose(np.linalg.norm(s[:, :3], axis=1), 1000.0, rtol=1e-14)
    assert np.all(s[:, 3:] == 0.0)
    np.testing.assert_array_equal(s, scen.sphere_starts(50, 1000.0, 3))


def test_holdout_set_is_disjoint_from_training_and_labelled_uniquely():
    prob = problems.make("mpc_rendezvous", None, {})
    sc = prob.holdout_scenarios()
    p = prob.params
    n_starts = p.holdout_n_sphere + 1
    expected = p.holdout_n_sphere + n_starts * (len(p.holdout_eccentricities)
                                                 + len(p.holdout_thrust_scales))
    assert len(sc["scenario"]) == expected == len(set(sc["scenario"]))
    assert prob.scenario_key() not in prob.holdout_keys()
    assert set(sc["kind"]) == {"start", "eccentric", "thrust"}
    assert np.all(sc["plant"][sc["kind"] == "eccentric"] == "keplerian")


def test_holdout_evaluation_records_every_scenario():
    prob = problems.make("mpc_rendezvous", None, {"holdout_n_sphere": 3})
    res = prob.holdout(MATS)
    n = len(res["scenario"])
    assert n == 3 + 4 * 3
    for key in ("cost", "delta_v", "converged", "status", "t_final", "final_distance"):
        assert len(res[key]) == n
    assert np.all(np.isfinite(res["cost"]))
    start = res["kind"] == "start"
    assert res["converged"][start].all()
    # the nominal training start under a 5 % thrust error converges with a different Δv
    nominal = prob.evaluate(MATS)
    row = list(res["scenario"]).index("thrust=0.95:s0")
    assert res["delta_v"][row] != pytest.approx(nominal["delta_v"], rel=1e-6)


def test_empty_holdout_set_is_none():
    prob = problems.make("mpc_rendezvous", None, {"holdout_n_sphere": 0,
                                                  "holdout_eccentricities": [],
                                                  "holdout_thrust_scales": []})
    assert prob.holdout(MATS) is None


def test_multiscenario_training_on_sampled_starts():
    prob = problems.make("mpc_rendezvous", None, {"train_sample": 2, "train_seed": 5,
                                                  "holdout_n_sphere": 2})
    out = prob.evaluate(MATS)
    assert len(out["train_scenarios"]) == 2
    assert out["cost"] == pytest.approx(np.mean([s["cost"] for s in out["train_scenarios"]]))


def test_training_on_a_held_out_start_is_rejected():
    seed = 20250422
    with pytest.raises(ConfigError, match="held-out"):
        problems.make("mpc_rendezvous", None, {"train_sample": 1, "train_seed": seed,
                                               "holdout_seed": seed})


def test_training_on_a_mismatched_plant():
    prob = problems.make("mpc_rendezvous", None, {"plant": "keplerian",
                                                  "plant_eccentricity": 0.01,
                                                  "holdout_eccentricities": [0.0]})
    out = prob.evaluate(MATS)
    assert out["converged"]
    assert "e=0:s0" in set(prob.holdout_scenarios()["scenario"])
