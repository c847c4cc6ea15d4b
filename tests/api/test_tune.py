"""penaltyrun.tune on from_cost problems: optimum, reproducibility, statuses, side effects."""

from __future__ import annotations

import math
import os
import signal

import numpy as np
import pytest
from known_optimum import BUDGET, DIAGONAL_FLOOR, K_STAR

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.problems.user_cost import FAILURE_COST


def test_full_reaches_a_non_diagonal_optimum_that_diagonal_cannot(quad, tmp_path):
    full = penaltyrun.tune(quad, param="full", n_starts=3, seed=1, optimizer_options=BUDGET,
                           workers=1, run_dir=tmp_path / "full")
    diag = penaltyrun.tune(quad, param="diagonal", n_starts=3, seed=1,
                           optimizer_options=BUDGET, workers=1, run_dir=tmp_path / "diag")
    assert full.best.converged and full.best.cost < 1e-3
    np.testing.assert_allclose(full.best.matrices["K"], K_STAR, atol=0.05)
    assert diag.best.cost >= DIAGONAL_FLOOR - 1e-12
    assert diag.best.cost == pytest.approx(DIAGONAL_FLOOR, rel=1e-3)
    assert list(full.records["status"]) == ["ok"] * 3 and len(full.records) == 3
    summary = full.summary()
    assert summary.loc[0, "n_starts"] == 3 and summary.loc[0, "converged"] == 1.0
    assert summary.loc[0, "best_cost"] == full.best.cost
    table = penaltyrun.compare(diag, full)
    row = table.iloc[0]
    assert (row["map_a"], row["map_b"]) == ("diagonal", "full")
    assert row["median_b"] < row["median_a"] and row["a12_b_beats_a"] == 1.0


def test_results_do_not_depend_on_the_number_of_workers(quad, tmp_path):
    runs = [penaltyrun.tune(quad, n_starts=3, seed=7, optimizer_options=BUDGET, workers=w,
                            run_dir=tmp_path / f"w{w}").records.sort_values("job_id")
            for w in (1, 2)]
    for column in ("job_id", "seed", "best_cost", "n_evals", "matrices", "config_hash"):
        assert list(runs[0][column]) == list(runs[1][column]), column
    for a, b in zip(runs[0]["best_z"], runs[1]["best_z"]):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("optimizer", ["cmaes", "pso"])
def test_the_callers_global_random_state_is_untouched(quad, tmp_path, optimizer):
    np.random.seed(12345)  # noqa: NPY002  (the caller's global state under test)
    before = np.random.get_state()  # noqa: NPY002
    options = BUDGET if optimizer == "cmaes" else {"n_particles": 10, "iters": 5}
    penaltyrun.tune(quad, optimizer=optimizer, n_starts=2, optimizer_options=options,
                    workers=1, run_dir=tmp_path)
    after = np.random.get_state()  # noqa: NPY002
    assert before[0] == after[0] and np.array_equal(before[1], after[1])
    assert before[2:] == after[2:]


def test_raising_and_nan_costs_are_recorded_statuses(tmp_path):
    def raising(K):
        raise RuntimeError("plant model missing")

    bad = penaltyrun.from_cost(raising, {"K": (2, (0.1, 10.0))}, name="raising")
    nan = penaltyrun.from_cost(lambda K: math.nan, {"K": (2, (0.1, 10.0))}, name="nancost")
    for prob, status, text in ((bad, "error", "RuntimeError: plant model missing"),
                               (nan, "nonfinite", "nan")):
        res = penaltyrun.tune(prob, n_starts=1, optimizer_options={"max_evals": 40},
                              workers=1, run_dir=tmp_path / status)
        row = res.records.iloc[0]
        assert row["status"] == "diverged" and row["best_status"] == status
        assert row["best_cost"] == FAILURE_COST and f"({status})" in row["error"]
        assert text in row["metrics"]
        assert not res.best.converged


def test_resume_runs_only_the_missing_jobs(quad, tmp_path):
    first = penaltyrun.tune(quad, n_starts=2, seed=3, optimizer_options=BUDGET, workers=1,
                            run_dir=tmp_path)
    records = sorted((tmp_path / "jobs").glob("*.json"))
    stamps = [p.stat().st_mtime_ns for p in records]
    again = penaltyrun.tune(quad, n_starts=3, seed=3, optimizer_options=BUDGET, workers=1,
                            run_dir=tmp_path, resume=True)
    assert [p.stat().st_mtime_ns for p in records] == stamps
    assert len(again.records) == 3
    assert set(first.records["job_id"]) < set(again.records["job_id"])


def test_report_and_load_round_trip(quad, tmp_path):
    res = penaltyrun.tune(quad, n_starts=2, optimizer_options=BUDGET, workers=1,
                          run_dir=tmp_path / "run")
    out = res.report(tmp_path / "report", workers=2)  # a problem object: in this process
    assert out == tmp_path / "report" and (out / "report.md").is_file()
    with pytest.raises(ConfigError, match="workers"):
        res.report(tmp_path / "other", workers=0)
    assert (out / "report.html").is_file()
    res.report(tmp_path / "again", cache_dir=tmp_path / "cache")
    assert not (tmp_path / "cache").exists()  # a problem object's code is outside any key
    for source in (tmp_path / "run", tmp_path / "run" / "results.parquet"):
        loaded = penaltyrun.load(source)
        assert loaded.run_dir == tmp_path / "run"
        assert loaded.records.equals(res.records)
        assert loaded.best.cost == res.best.cost
    meta = res.records.iloc[0]
    assert meta["package_version"] == penaltyrun.__version__ and meta["git_commit"]
    assert "object:quad" in meta["config"]


def test_load_reads_a_committed_study():
    from pathlib import Path

    study = Path(__file__).resolve().parents[2] / "studies" / "pso_matlab_zermelo"
    res = penaltyrun.load(study)
    assert len(res.records) > 0 and set(res.summary()["problem"]) == {"zermelo"}
    assert res.best.matrices["K"].shape == (2, 2)


def test_run_dir_defaults_to_a_temporary_folder(quad):
    res = penaltyrun.tune(quad, n_starts=1, optimizer_options={"max_evals": 40}, workers=1)
    assert (res.run_dir / "results.parquet").is_file()


@pytest.mark.parametrize("kwargs, key", [
    ({"param": "spiral"}, "param"),
    ({"optimizer": "annealing"}, "optimizer"),
    ({"optimizer_options": {"max_eval": 10}}, "optimizer.max_eval"),
    ({"n_starts": 0}, "runner.n_starts"),
    ({"workers": 0}, "runner.workers"),
    ({"params": {"x0": [1, 2]}}, "problem.params.x0"),
])
def test_bad_arguments_are_config_errors(quad, tmp_path, kwargs, key):
    with pytest.raises(ConfigError) as err:
        penaltyrun.tune(quad, run_dir=tmp_path, **kwargs)
    assert err.value.key == key


def test_unknown_problem_names_the_known_ones():
    with pytest.raises(ConfigError, match="unknown problem 'nope'.*zermelo"):
        penaltyrun.tune("nope")
    with pytest.raises(ConfigError, match="cannot import 'no_such_pkg.mod'"):
        penaltyrun.tune("no_such_pkg.mod")
    with pytest.raises(ConfigError, match="expected a problem name"):
        penaltyrun.tune(42)


def test_two_problems_of_one_name_in_one_process_do_not_mix(tmp_path):
    from penaltyrun import problems

    results = []
    for offset in (0.0, 5.0):
        prob = penaltyrun.from_cost(lambda K, c=offset: float(np.trace(K)) + c,
                                    {"K": (2, (0.1, 10.0))})
        res = penaltyrun.tune(prob, n_starts=1, optimizer_options={"max_evals": 100},
                              workers=1, run_dir=tmp_path / str(offset))
        res.report(tmp_path / f"report{offset}")
        penaltyrun.compare(res, res)
        results.append(res.best.cost)
    assert results[1] - results[0] == pytest.approx(5.0, abs=1e-3)
    assert "user" not in problems.trust.named() and not problems._OBJECTS


def test_an_interrupted_tune_keeps_its_jobs_and_resumes(tmp_path):
    from penaltyrun.errors import RunInterruptedError
    from penaltyrun.runner import lock

    calls = []

    def cost(K):
        calls.append(1)
        if len(calls) == 150:  # Ctrl-C in the middle of the second job
            os.kill(os.getpid(), signal.SIGINT)
        return float(np.sum((K - K_STAR) ** 2))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="interrupted")
    kwargs = {"n_starts": 2, "optimizer_options": {"max_evals": 100}, "workers": 1,
              "run_dir": tmp_path}
    with pytest.raises(RunInterruptedError):
        penaltyrun.tune(prob, **kwargs)
    assert len(list((tmp_path / "jobs").glob("*.json"))) == 1
    assert lock._key(tmp_path) not in lock._HELD  # free for the next run of this process
    res = penaltyrun.tune(prob, resume=True, **kwargs)
    assert len(res.records) == 2 and set(res.records["status"]) == {"ok"}


@pytest.mark.parametrize("call, key", [
    (lambda tmp: penaltyrun.from_cost(lambda K: 0.0, [("K", 2)]), "matrices"),
    (lambda tmp: penaltyrun.tune("..."), "problem"),
    (lambda tmp: penaltyrun.tune("zermelo", params=[1]), "params"),
    (lambda tmp: penaltyrun.tune("zermelo", run_dir=5), "run_dir"),
    (lambda tmp: penaltyrun.tune("zermelo", optimizer_options={"max_evals": object()}),
     "optimizer_options"),
    (lambda tmp: penaltyrun.load(None), "path"),
    (lambda tmp: penaltyrun.tune("zermelo", run_dir=tmp / "a_file"), "run_dir"),
], ids=["matrices-list", "relative-name", "params-list", "run_dir-int", "option-object",
        "load-none", "run_dir-file"])
def test_bad_arguments_raise_one_config_error_naming_them(tmp_path, call, key):
    (tmp_path / "a_file").write_text("")
    with pytest.raises(ConfigError) as err:
        call(tmp_path)
    assert err.value.key == key and "\n" not in str(err.value)
