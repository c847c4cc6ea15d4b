"""The source of a problem module outside penaltyrun is part of the job identity: a module
edited between an interrupted run and its resume is a new configuration, and resume says
so (one warning) instead of mixing old and new objective values in one results file."""

import logging
import sys
import textwrap
import uuid

import pytest

import penaltyrun
from penaltyrun.problems import user_code_params
from penaltyrun.runner import module_source_hash, plan_jobs, user_code_hash
from penaltyrun.runner.records import read_record

SOURCE = textwrap.dedent('''
    import numpy as np
    from penaltyrun.problems.base import BatchEvaluation, MatrixSpec

    CASES = ("one",)
    DEFAULT_CASE = "one"
    OFFSET = 0.0


    class Fit:
        name = "fit"
        case = "one"
        matrices = (MatrixSpec("K", 1, (0.1, 10.0)),)
        scalars = ()

        def evaluate_batch(self, mats, scalars=None):
            cost = np.sum(np.asarray(mats["K"]) ** 2, axis=(1, 2)) + OFFSET
            return BatchEvaluation(cost, np.ones(len(cost), bool),
                                   np.array(["converged"] * len(cost), dtype=object))

        def evaluate(self, mats, scalars=None):
            return {"cost": float(np.sum(np.asarray(mats["K"]) ** 2)) + OFFSET,
                    "converged": True, "status": "converged", "t_final": 0.0}

        def simulate(self, mats, scalars=None):
            return {"t": np.zeros(1)}


    def make_problem(case, params):
        return Fit()
''')


@pytest.fixture
def module(tmp_path, monkeypatch):
    """A fresh package on ``sys.path`` with the problem module ``<pkg>.fit``; yields its
    dotted name and file."""
    pkg = f"identity_{uuid.uuid4().hex[:8]}"
    (tmp_path / pkg).mkdir()
    (tmp_path / pkg / "__init__.py").write_text("")
    path = tmp_path / pkg / "fit.py"
    path.write_text(SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield f"{pkg}.fit", path
    for name in [n for n in sys.modules if n == pkg or n.startswith(f"{pkg}.")]:
        del sys.modules[name]


def test_the_hash_follows_the_module_s_source(module):
    name, path = module
    before = module_source_hash(name)
    assert len(before) == 16 and module_source_hash(name) == before
    path.write_text(SOURCE.replace("OFFSET = 0.0", "OFFSET = 5.0"))
    assert module_source_hash(name) not in ("", before)
    for none in (None, "", "object:mine", "sys", "no_such_module_here.at_all"):
        assert module_source_hash(none) == ""


def test_modules_named_by_problem_parameters_count_too(module):
    name, _ = module
    own = module_source_hash(name)
    declared = user_code_params("lqr")
    assert declared == (("plant", "dynamics"), ("plant_file",))
    assert user_code_hash(name, {}) == own
    assert user_code_hash(None, {"dynamics": f"{name}:f"}, *declared) == own
    assert user_code_hash(None, {"dynamics": f"{name}:f"}) == ""  # not declared: not code
    assert user_code_hash(None, {"plant": "cw", "dynamics": None}, *declared) == ""
    both = user_code_hash(name, {"plant": f"{name}:P"}, *declared)
    assert both not in ("", own)
    assert module_source_hash("penaltyrun.problems") == ""  # recorded as the version


def test_the_job_ids_cover_the_module_s_source_and_only_then():
    plain = plan_jobs("fit", "one", "full", "pso", n_starts=2, root_seed=1,
                      problem_module="pkg.fit")
    same = plan_jobs("fit", "one", "full", "pso", n_starts=2, root_seed=1, problem_module="pkg.fit",
                     module_hash="")
    a = plan_jobs("fit", "one", "full", "pso", n_starts=2, root_seed=1, problem_module="pkg.fit",
                  module_hash="a" * 16)
    b = plan_jobs("fit", "one", "full", "pso", n_starts=2, root_seed=1, problem_module="pkg.fit",
                  module_hash="b" * 16)
    assert [j.job_id for j in plain] == [j.job_id for j in same]  # no hash: ids as before
    assert len({j.job_id for j in plain + a + b}) == 6
    assert [j.seed for j in a] == [j.seed for j in b] == [j.seed for j in plain]


def test_an_edited_module_is_a_new_configuration_and_resume_says_so(module, tmp_path,
                                                                    caplog):
    name, path = module
    kwargs = {"param": "diagonal", "optimizer": "baseline", "n_starts": 2, "workers": 1,
              "run_dir": tmp_path / "run"}
    first = penaltyrun.tune(name, **kwargs)
    records = [read_record(p) for p in sorted((tmp_path / "run" / "jobs").glob("*.json"))]
    assert [r["module_hash"] for r in records] == [module_source_hash(name)] * 2
    old_ids = set(first.records["job_id"])
    path.write_text(SOURCE.replace("OFFSET = 0.0", "OFFSET = 5.0"))
    with caplog.at_level(logging.WARNING):
        second = penaltyrun.tune(name, resume=True, **kwargs)
    new_ids = set(second.records["job_id"])
    assert len(new_ids) == 2 and not new_ids & old_ids  # nothing reused, nothing mixed
    lines = [r.getMessage() for r in caplog.records if "was edited since" in r.getMessage()]
    assert len(lines) == 1
    assert f"problem module {name} or a local module it imports was edited since 2 finished" \
        in lines[0]
    assert len(list((tmp_path / "run" / "jobs").glob("*.json"))) == 4  # old ones kept
