"""`penaltyrun-report --export`: each cell's best matrices as JSON and MATLAB .mat."""

import json

import numpy as np
import pytest
from scipy.io import loadmat

from penaltyrun import io, runner
from penaltyrun.cli import report_main
from penaltyrun.io import decode_json
from penaltyrun.report.export import export_best

TINY = {"n_particles": 4, "iters": 2, "ftol_iter": 2}


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    jobs = []
    for problem, case, param, n in (("zermelo", "default", "diagonal", 2),
                                    ("zermelo", "default", "full", 2),
                                    ("attitude_lqr", "detumble", "full", 1)):
        params = {"holdout_n": 0} if problem != "zermelo" else {}
        jobs += runner.plan_jobs(problem, case, param, "pso", n_starts=n, root_seed=11,
                                 problem_params=params, optimizer_options=TINY,
                                 meta={"git_commit": "test"}, holdout=False)
    runner.execute(jobs, root / "run")
    return io.collect(root / "run")


def test_mat_and_json_hold_the_parquet_matrices(results, tmp_path):
    files = export_best(results, tmp_path / "export")
    df = io.read_results(results)
    assert len([f for f in files if f.suffix == ".mat"]) == 3
    for param, problem, case, names in (("diagonal", "zermelo", "default", ["K"]),
                                        ("full", "zermelo", "default", ["K"]),
                                        ("full", "attitude_lqr", "detumble", ["Q", "R"])):
        cell = df[(df["problem"] == problem) & (df["param"] == param)]
        best = cell.loc[cell["best_cost"].idxmin()]
        stem = f"{problem}_{case}_pso_{param}"
        mat = loadmat(tmp_path / "export" / f"{stem}.mat")
        doc = json.loads((tmp_path / "export" / f"{stem}.json").read_text())
        expected = decode_json(best["matrices"])
        assert sorted(expected) == names and sorted(doc["matrices"]) == names
        for name in names:
            want = np.asarray(expected[name])
            np.testing.assert_array_equal(mat[name], want)  # bit for bit
            np.testing.assert_array_equal(np.asarray(doc["matrices"][name]), want)
        assert mat["job_id"][0] == best["job_id"] == doc["job_id"]
        assert mat["case_name"][0] == case and mat["param"][0] == param
        assert float(mat["best_cost"][0, 0]) == best["best_cost"] == doc["best_cost"]
    index = (tmp_path / "export" / "index.csv").read_text().splitlines()
    assert len(index) == 4 and index[0].startswith("problem,case,variant,optimizer,param")


def test_report_cli_export_option(results, tmp_path, capsys):
    report_main([str(results), "-o", str(tmp_path / "report"), "--export",
                 str(tmp_path / "exp")])
    assert "exported" in capsys.readouterr().out
    assert (tmp_path / "report" / "report.md").exists()
    assert len(list((tmp_path / "exp").glob("*.mat"))) == 3


def test_a_metric_that_is_not_finite_is_exported_as_null(results, tmp_path):
    """JSON has no NaN or infinity: a stored metric that is not finite is written as null,
    and the file parses with a strict parser."""
    df = io.read_results(results)
    cell = df[(df["problem"] == "zermelo") & (df["param"] == "full")]
    best = cell["best_cost"].idxmin()
    metrics = decode_json(df.at[best, "metrics"])
    metrics.update({"final_distance": float("nan"), "extra": [1.0, float("inf")]})
    df.at[best, "metrics"] = json.dumps(metrics)
    folder = tmp_path / "in"
    folder.mkdir()
    df.to_parquet(folder / "results.parquet")
    export_best(folder, tmp_path / "export")

    def refuse(token):
        raise ValueError(token)

    text = (tmp_path / "export" / "zermelo_default_pso_full.json").read_text()
    doc = json.loads(text, parse_constant=refuse)
    assert doc["metrics"]["final_distance"] is None and doc["metrics"]["extra"] == [1.0, None]
    assert doc["metrics"]["cost"] == metrics["cost"]


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf"), 1.5, "a", None])
def test_strict_json_keeps_finite_values_and_nulls_the_rest(value):
    from penaltyrun.io import strict_json

    out = strict_json({"a": [value, (value,)], "b": {"c": value}})
    want = None if isinstance(value, float) and not np.isfinite(value) else value
    assert out == {"a": [want, [want]], "b": {"c": want}}
