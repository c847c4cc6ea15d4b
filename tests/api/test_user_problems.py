"""The Python API with problems of the user's own: what makes a job the same job, names that
would pass for a built-in problem, the protocol's contract, and options only the command
line used to reach."""

from __future__ import annotations

import logging
import sys

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import BatchEvaluation, checked_batch
from penaltyrun.runner.usercode import object_code_hash

SPEC = {"K": (2, (0.1, 10.0))}
TINY = {"max_evals": 40}


def _cost_a(K):
    return float(np.sum((K - np.eye(2)) ** 2))


def _cost_b(K):
    return 100.0 + float(np.sum((K - 3.0 * np.eye(2)) ** 2))


def _closing_over(target):
    return lambda K: float(np.sum((K - target) ** 2))


def test_two_costs_under_one_name_are_two_configurations(tmp_path):
    """The cost function is part of a job's identity: the same name and matrices with
    another cost give other job ids, so reading both folders together loses no row, and a
    resume after editing the cost runs every job again."""
    a = penaltyrun.tune(penaltyrun.from_cost(_cost_a, SPEC), n_starts=2, workers=1,
                        optimizer_options=TINY, run_dir=tmp_path / "a")
    b = penaltyrun.tune(penaltyrun.from_cost(_cost_b, SPEC), n_starts=2, workers=1,
                        optimizer_options=TINY, run_dir=tmp_path / "b")
    assert not set(a.records["job_id"]) & set(b.records["job_id"])
    assert len(penaltyrun.load(tmp_path).records) == 4
    again = penaltyrun.tune(penaltyrun.from_cost(_cost_b, SPEC), n_starts=2, workers=1,
                            optimizer_options=TINY, run_dir=tmp_path / "a", resume=True)
    assert set(again.records["job_id"]) == set(b.records["job_id"])
    assert (again.records["best_cost"] >= 100.0).all()  # _cost_b's records, not _cost_a's


def test_the_code_hash_follows_code_closures_and_specs_not_bookkeeping():
    one = penaltyrun.from_cost(_cost_a, SPEC)
    assert object_code_hash(one) == object_code_hash(penaltyrun.from_cost(_cost_a, SPEC))
    assert object_code_hash(one) != object_code_hash(penaltyrun.from_cost(_cost_b, SPEC))
    assert object_code_hash(one) != object_code_hash(
        penaltyrun.from_cost(_cost_a, {"K": (2, (0.1, 5.0))}))
    near, far = (penaltyrun.from_cost(_closing_over(np.eye(2) * s), SPEC) for s in (1, 2))
    assert object_code_hash(near) != object_code_hash(far)
    assert object_code_hash(near) == object_code_hash(
        penaltyrun.from_cost(_closing_over(np.eye(2)), SPEC))
    before = object_code_hash(one)
    one._warned = True  # the object's own bookkeeping is no part of what it computes
    assert object_code_hash(one) == before


def test_a_user_problem_may_not_take_a_built_in_name(tmp_path, monkeypatch):
    with pytest.raises(ConfigError, match="name: 'zermelo' is the name of a built-in"):
        penaltyrun.from_cost(_cost_a, SPEC, name="zermelo")
    package = tmp_path / "mylab"
    package.mkdir()
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / "lqr.py").write_text("raise RuntimeError('must not be imported')\n",
                                    encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigError, match="'lqr' is the name of a built-in.*rename the "
                                          "module"):
        penaltyrun.tune("mylab.lqr", n_starts=1, workers=1, run_dir=tmp_path / "run")
    assert "mylab.lqr" not in sys.modules
    assert penaltyrun.evaluate("lqr", {"Q": np.eye(3), "R": np.eye(2)})["converged"]


def test_a_gradient_optimizer_without_a_gradient_is_refused_before_any_job(tmp_path):
    with pytest.raises(ConfigError, match="optimizer: lbfgs needs the exact gradient"):
        penaltyrun.tune(penaltyrun.from_cost(_cost_a, SPEC), optimizer="lbfgs",
                        n_starts=1, workers=1, run_dir=tmp_path)
    assert not (tmp_path / "jobs").exists()


def test_grad_cost_is_an_optimizer_option_from_python(tmp_path):
    gradient = {"K": lambda K: 2.0 * (K - np.eye(2))}
    prob = penaltyrun.from_cost(_cost_a, SPEC, gradient=lambda K: {"K": gradient["K"](K)})
    result = penaltyrun.tune(prob, n_starts=1, workers=1, run_dir=tmp_path,
                             optimizer_options={"max_evals": 300, "polish": "gradient",
                                                "grad_cost": 3})
    record = result.records.iloc[0]
    assert record["status"] == "ok" and record["grad_cost"] == 3.0


MODULE = """
import numpy as np
from penaltyrun.problems.base import BatchEvaluation, MatrixSpec
CASES = ("only",)
DEFAULT_CASE = "only"


class P:
    name = "{name}"

    def __init__(self, case):
        self.case = case
        self.matrices = (MatrixSpec("Q", 2, (1e-3, 10.0)),)
        self.scalars = ()

    def evaluate_batch(self, mats, scalars=None):
        n = len(mats["Q"])
        {body}

    def evaluate(self, mats, scalars=None):
        ev = self.evaluate_batch({{k: np.asarray(v, float)[None] for k, v in mats.items()}})
        return {{"cost": float(np.ravel(ev.cost)[0]),
                 "converged": bool(np.ravel(ev.converged)[0]),
                 "status": str(np.ravel(ev.status)[0]), "t_final": 1.0}}

    def simulate(self, mats, scalars=None):
        return {{}}


def make_problem(case, params):
    return P(case)
"""


def _write_module(folder, name, body):
    """Write a problem module ``<package>/<name>.py`` under ``folder`` (a package of its
    own per test: an earlier test's is still imported) whose ``evaluate_batch`` of ``n``
    candidates runs the one statement ``body``; returns its dotted path."""
    package = folder / f"userpkg{abs(hash(str(folder))) % 10**9}"
    package.mkdir(exist_ok=True)
    (package / "__init__.py").write_text("", encoding="utf-8")
    (package / f"{name}.py").write_text(MODULE.format(name=name, body=body),
                                        encoding="utf-8")
    return f"{package.name}.{name}"


def test_a_nan_cost_called_converged_is_not_counted_converged(tmp_path, monkeypatch):
    path = _write_module(tmp_path, "nan_user", (
        "return BatchEvaluation(cost=np.full(n, np.nan), converged=np.ones(n, bool), "
        "status=np.array(['converged'] * n, dtype=object))"))
    monkeypatch.syspath_prepend(str(tmp_path))
    result = penaltyrun.tune(path, n_starts=1, workers=1, optimizer_options=TINY,
                             run_dir=tmp_path / "run")
    record = result.records.iloc[0]
    assert record["status"] == "diverged" and not record["best_converged"]
    assert record["best_status"] == "nonfinite"
    assert result.summary().loc[0, "converged"] == 0.0


@pytest.mark.parametrize("body, words", [
    ("return np.zeros(n)", "must return a BatchEvaluation(cost, converged, status)"),
    ("return BatchEvaluation(cost=np.zeros(1), converged=np.ones(1, bool), "
     "status=np.array(['converged'], dtype=object))", "cost of shape (1,) for"),
])
def test_a_batch_that_breaks_the_protocol_fails_its_job_in_one_line(tmp_path, monkeypatch,
                                                                   body, words):
    name = f"broken_{abs(hash(body)) % 10_000}"
    path = _write_module(tmp_path, name, body)
    monkeypatch.syspath_prepend(str(tmp_path))
    result = penaltyrun.tune(path, n_starts=1, workers=1, optimizer_options=TINY,
                             run_dir=tmp_path / "run")
    record = result.records.iloc[0]
    assert record["status"] == "failed"
    first = record["error"].splitlines()[0]
    assert first.startswith(f"TypeError: problem {name!r}: evaluate_batch") and words in first


def test_checked_batch_takes_a_well_formed_batch_as_it_is():
    batch = BatchEvaluation(cost=np.zeros(3), converged=np.ones(3, bool),
                            status=np.array(["converged"] * 3, dtype=object))
    assert checked_batch(batch, 3, object()) is batch
    with pytest.raises(TypeError, match="status of shape"):
        checked_batch(BatchEvaluation(np.zeros(3), np.ones(3, bool), np.array(["x"])), 3,
                      object())


def test_a_cost_that_always_raises_is_said_once_and_named_in_the_record(tmp_path, caplog):
    prob = penaltyrun.from_cost(lambda Q: 0.0, SPEC)  # the matrix is K: every call raises
    with caplog.at_level(logging.WARNING, logger="penaltyrun.problems.user_cost"):
        result = penaltyrun.tune(prob, n_starts=2, workers=1, optimizer_options=TINY,
                                 run_dir=tmp_path)
    said = [r for r in caplog.records if "raised TypeError" in r.getMessage()]
    assert len(said) == 1 and "status 'error'" in said[0].getMessage()
    assert all("TypeError" in e and "unexpected keyword argument 'K'" in e
               for e in result.records["error"])


def test_map_and_runner_options_from_python(tmp_path):
    result = penaltyrun.tune(penaltyrun.from_cost(_cost_a, SPEC), param="cayley",
                             n_starts=1, workers=1, optimizer_options=TINY,
                             param_options={"cayley_bound": 5.0},
                             runner_options={"holdout": False, "warm_start": True},
                             run_dir=tmp_path / "run")
    import yaml

    config = yaml.safe_load(result.records["config"].iloc[0])
    assert config["param"]["cayley_bound"] == 5.0 and config["runner"]["warm_start"]
    assert result.records["warm_start"].notna().all()
    prob = penaltyrun.from_cost(_cost_a, SPEC)
    for bad, key in [({"runner_options": {"n_starts": 3}}, "runner_options.n_starts"),
                     ({"runner_options": {"bogus": 1}}, "runner.bogus"),
                     ({"runner_options": [1]}, "runner_options"),
                     ({"param_options": {"eig_bound": [1, 2]}}, "param.eig_bound")]:
        with pytest.raises(ConfigError) as err:
            penaltyrun.tune(prob, n_starts=1, workers=1, run_dir=tmp_path / "bad", **bad)
        assert str(err.value).startswith(f"{key}: ")


def test_load_refuses_what_is_not_a_problem(tmp_path):
    penaltyrun.tune(penaltyrun.from_cost(_cost_a, SPEC), n_starts=1, workers=1,
                    optimizer_options=TINY, run_dir=tmp_path)
    with pytest.raises(ConfigError, match="^problem: expected a problem name"):
        penaltyrun.load(tmp_path, problem=42)


def test_the_errors_are_importable_from_the_package():
    from penaltyrun import errors

    for name in ("ConfigError", "RunInterruptedError", "RunAbortedError",
                 "EnvironmentProblemError", "ResultsUnreadableError"):
        assert getattr(penaltyrun, name) is getattr(errors, name)
        assert name in penaltyrun.__all__
