"""Multi-scenario tuning: the aggregated objective against hand computations from
independently built single-scenario problems; disjointness and bad settings."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.multiscenario import (
    DEFAULT_QUANTILE,
    MultiScenarioProblem,
    quantile_weights,
)

STARTS = [{"x0": (-8.0, 6.0)}, {"x0": (3.0, -4.0)}, {"x0": (1.0, 7.5)}]
KS = np.stack([np.array([[1.7421, 0.9560], [0.9560, 1.1414]]), np.diag([0.8094, 0.1611]),
               np.eye(2)])


def _sorted_quantile(values: np.ndarray, q: float) -> float:
    """The linear-interpolation quantile by hand: sort, h = q (m - 1), interpolate."""
    v = sorted(float(x) for x in values)
    h = q * (len(v) - 1)
    lo = int(np.floor(h))
    hi = min(lo + 1, len(v) - 1)
    return v[lo] + (h - lo) * (v[hi] - v[lo])


@pytest.mark.parametrize("how", ["mean", "max", "quantile"])
def test_zermelo_aggregate_matches_hand_computation(how):
    over = {"train_scenarios": STARTS, "train_aggregate": how}
    if how == "quantile":
        over["train_quantile"] = 0.75
    prob = make("zermelo", None, over)
    assert isinstance(prob, MultiScenarioProblem)
    batch = prob.evaluate_batch({"K": KS})
    single = np.array([[make("zermelo", None, s).evaluate({"K": K})["cost"] for K in KS]
                       for s in STARTS])  # (scenario, candidate)
    want = {"mean": single.mean(axis=0), "max": single.max(axis=0),
            "quantile": np.array([_sorted_quantile(single[:, b], 0.75)
                                  for b in range(single.shape[1])])}[how]
    np.testing.assert_allclose(batch.cost, want, rtol=1e-12)
    assert batch.converged.all()
    detail = prob.evaluate({"K": KS[0]})
    assert detail["cost"] == pytest.approx(want[0], rel=1e-12)
    assert [d["cost"] for d in detail["train_scenarios"]] == pytest.approx(single[:, 0])
    json.dumps(detail)


def test_quantile_level_defaults_and_is_recorded():
    prob = make("zermelo", None, {"train_scenarios": STARTS, "train_aggregate": "quantile"})
    assert prob.quantile == DEFAULT_QUANTILE == 0.9
    assert prob.params.train_quantile == 0.9
    assert prob.evaluate({"K": KS[0]})["train_quantile"] == 0.9
    top = make("zermelo", None, {"train_scenarios": STARTS, "train_aggregate": "quantile",
                                 "train_quantile": 1.0})
    worst = make("zermelo", None, {"train_scenarios": STARTS, "train_aggregate": "max"})
    np.testing.assert_array_equal(top.evaluate_batch({"K": KS}).cost,
                                  worst.evaluate_batch({"K": KS}).cost)
    assert make("zermelo", None, {"train_scenarios": STARTS}).params.train_quantile is None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3, allow_nan=False), min_size=1, max_size=12),
       st.floats(0.01, 1.0))
def test_quantile_weights_reproduce_the_quantile(costs, q):
    """Where the quantile is differentiable its weights give it back; they sum to 1, are
    non-negative and put weight on at most two scenarios."""
    c = np.asarray(costs)
    w = quantile_weights(c, q)
    if w is None:  # a tie at the order statistics used: a kink, no weights
        return
    assert w.sum() == pytest.approx(1.0) and (w >= 0).all() and (w > 0).sum() <= 2
    assert float(w @ c) == pytest.approx(float(np.quantile(c, q)), rel=1e-12, abs=1e-9)
    assert float(w @ c) == pytest.approx(_sorted_quantile(c, q), rel=1e-12, abs=1e-9)


def test_quantile_weights_none_at_a_tie():
    assert quantile_weights(np.array([1.0, 3.0, 3.0, 0.0]), 0.9) is None
    assert quantile_weights(np.array([1.0, 2.0, 3.0, 0.0]), 0.9) is not None


@pytest.mark.slow
def test_attitude_mean_over_training_attitudes():
    scen = [{"attitude": (60.0, 80.0, -60.0)}, {"attitude": (20.0, -30.0, 45.0)}]
    prob = make("attitude_lyapunov", "rest_to_rest", {"train_scenarios": scen})
    gains = {"Kp": 3.0 * np.eye(3), "Kd": 6.0 * np.eye(3)}
    costs = [make("attitude_lyapunov", "rest_to_rest", s).evaluate(gains)["cost"] for s in scen]
    assert prob.evaluate(gains)["cost"] == pytest.approx(np.mean(costs), rel=1e-12)
    assert prob.holdout(gains)["cost"].shape == (216,)


def test_one_failing_scenario_fails_the_candidate():
    scen = [{}, {"t_max": 1.0}]
    prob = make("zermelo", None, {"train_scenarios": scen, "train_aggregate": "max"})
    res = prob.evaluate({"K": KS[0]})
    assert not res["converged"] and res["status"] == "horizon"
    assert res["cost"] > prob.params.failure_penalty
    assert not prob.evaluate_batch({"K": KS[:1]}).converged[0]


@pytest.mark.slow
def test_lowthrust_departures_times_steps():
    scen = [{"nu0_deg": nu, "control_step_s": dt} for nu in (30.0, 200.0) for dt in (70.0, 90.0)]
    prob = make("qlaw", "C", {"train_scenarios": scen})
    K = np.diag([1.0, 3.0, 1.0, 1.0, 1.0])
    want = np.mean([make("qlaw", "C", s).evaluate({"K": K})["cost"] for s in scen])
    assert prob.evaluate({"K": K})["cost"] == pytest.approx(want, rel=1e-12)
    assert prob.params.train_scenarios == tuple(scen)


@pytest.mark.parametrize("problem,case,over,match", [
    ("zermelo", None, {"train_scenarios": []}, "non-empty"),
    ("zermelo", None, {"train_scenarios": [{"x0": (2.0, 0.0)}]}, "held-out"),
    ("zermelo", None, {"train_scenarios": [{}], "train_aggregate": "median"}, "aggregate"),
    ("zermelo", None, {"train_scenarios": [5]}, "not a mapping"),
    ("zermelo", None, {"train_scenarios": [{}], "train_aggregate": "quantile",
                       "train_quantile": 1.5}, r"train_quantile.*\(0, 1\]"),
    ("zermelo", None, {"train_scenarios": [{}], "train_aggregate": "quantile",
                       "train_quantile": 0.0}, r"train_quantile.*\(0, 1\]"),
    ("zermelo", None, {"train_scenarios": [{}], "train_aggregate": "quantile",
                       "train_quantile": "high"}, r"train_quantile.*\(0, 1\]"),
    ("zermelo", None, {"train_scenarios": [{}], "train_quantile": 0.9},
     "train_quantile.*aggregate is 'mean'"),
    ("zermelo", None, {"train_scenarios": [{"nonsense": 1}]}, "nonsense"),
    ("qlaw", "A", {"train_scenarios": [{}, {"control_step_s": 40.0}]},
     "scenario 1 .* is also in the held-out set"),
    ("qlaw", "C", {"train_scenarios": [{}, {"e0": 0.9}]},
     r"scenario 1 .*periapsis a0\(1 - e0\) = 922.27 km is inside the Earth"),
    ("qlaw", "A", {"train_scenarios": [{"e0": 1.2}]}, r"scenario 0 .*e0.*\[0, 1\)"),
    ("qlaw", "A", {"train_scenarios": [{"holdout_de": 0.01}]},
     "sets holdout_de: the held-out set belongs to the run"),
    ("attitude_lyapunov", "detumble",
     {"train_scenarios": [{"attitude": (10.0, 10.0, 10.0), "omega0": (0.0, 0.0, 0.0)}]},
     "held-out"),
])
def test_bad_training_settings(problem, case, over, match):
    with pytest.raises(ConfigError, match=match):
        make(problem, case, over)


def test_bad_training_settings_on_the_command_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "problem=zermelo",
                           "problem.params.train_scenarios=[]", "runner.n_starts=1"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("penaltyrun: error: problem.params.train_scenarios")


def test_evaluate_mode_prints_the_aggregate(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                           "problem=zermelo", "matrices.K=[[1.7421,0.9560],[0.9560,1.1414]]",
                           "problem.params.train_scenarios=[{x0:[-8,6]},{x0:[3,-4]}]",
                           "problem.params.train_aggregate=max"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["train_aggregate"] == "max" and len(res["train_scenarios"]) == 2
    assert res["cost"] == max(d["cost"] for d in res["train_scenarios"])


@pytest.mark.parametrize("problem,case", [("zermelo", None),
                                          ("attitude_lyapunov", "schaub_detumble"),
                                          ("qlaw", "C")])
def test_seeded_training_sample(problem, case):
    prob = make(problem, case, {"train_sample": 3, "train_seed": 5})
    again = make(problem, case, {"train_sample": 3, "train_seed": 5})
    other = make(problem, case, {"train_sample": 3, "train_seed": 6})
    assert len(prob.scenarios) == 3 and prob.overrides == again.overrides
    assert prob.overrides != other.overrides
    assert (prob.params.train_sample, prob.params.train_seed) == (3, 5)
    assert prob.params.train_scenarios is None
    held = prob.base.holdout_keys()
    assert not any(p.scenario_key() in held for p in prob.scenarios)
    both = make(problem, case, {"train_scenarios": [{}], "train_sample": 2})
    assert len(both.scenarios) == 3 and both.overrides[0] == {}


def test_seeded_sample_mean_matches_members():
    prob = make("qlaw", "C", {"train_sample": 2, "train_seed": 3})
    K = np.eye(5)
    want = np.mean([make("qlaw", "C", o).evaluate({"K": K})["cost"] for o in prob.overrides])
    assert prob.evaluate({"K": K})["cost"] == pytest.approx(want, rel=1e-12)


@pytest.mark.parametrize("over,key", [({"train_sample": -1}, "train_sample"),
                                      ({"train_sample": 2, "train_seed": -3}, "train_seed")])
def test_bad_sample_settings(over, key):
    with pytest.raises(ConfigError, match=key):
        make("zermelo", None, over)


def test_training_scenarios_do_not_carry_a_held_out_set_of_their_own():
    """A training departure whose own perturbations would be invalid orbits is still fine:
    only the run's held-out set (around the case's departure) is built and checked."""
    # Case A: a0 = 7000 km, e0 = 0.01; around a training departure at e0 = 0.085 (periapsis
    # 6405 km), held-out perturbations with holdout_de 0.01 reach inside the Earth.
    over = {"holdout_de": 0.01, "train_scenarios": [{}, {"e0": 0.085}]}
    with pytest.raises(ConfigError):
        make("qlaw", "A", {"holdout_de": 0.01, "e0": 0.085})
    prob = make("qlaw", "A", over)
    assert [len(p.holdout_scenarios()) for p in prob.scenarios] == [0, 0]
    assert len(prob.holdout_scenarios()) == len(make("qlaw", "A", {"holdout_de": 0.01})
                                                .holdout_scenarios()) > 0


def test_invalid_seeded_training_departure_names_train_sample():
    with pytest.raises(ConfigError) as info:
        make("qlaw", "A", {"train_sample": 3, "holdout_n_perturbed": 0, "holdout_de": 0.3})
    assert info.value.key == "problem.params.train_sample"
    assert "inside the Earth" in str(info.value)
