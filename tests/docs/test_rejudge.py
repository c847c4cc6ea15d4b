"""Re-judging a committed study: the long-horizon held-out file, its provenance, the tables,
and reading the results in preference to the stored held-out data."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from penaltyrun.docsgen import rejudge
from penaltyrun.docsgen.studies import StudyError
from penaltyrun.io import decode_json
from penaltyrun.io.longholdout import LONG_FILE, LONG_PROVENANCE
from penaltyrun.io.schema import read_results

ROOT = Path(__file__).resolve().parents[2]
STUDY = "pso_matlab_zermelo"


@pytest.fixture()
def copy(tmp_path: Path) -> Path:
    shutil.copytree(ROOT / "studies" / STUDY, tmp_path / "studies" / STUDY,
                    ignore=shutil.ignore_patterns(LONG_FILE, LONG_PROVENANCE))
    return tmp_path


@pytest.mark.slow
def test_rejudge_writes_data_provenance_and_tables(copy):
    folder = copy / "studies" / STUDY
    before = read_results(folder / "results.parquet")
    old = decode_json(before["holdout"].dropna().iloc[0])
    assert "horizon" not in old                     # stored at the training deadline
    out = rejudge.rejudge_study(copy, STUDY, jobs="all", workers=1)
    assert out == folder / LONG_FILE
    info = json.loads((folder / LONG_PROVENANCE).read_text())
    assert info["jobs"] == "all" and info["rejudged"] == before["holdout"].notna().sum()
    assert info["status"] == {"ok": info["rejudged"]} and "numpy" in info["packages"]
    assert info["horizons"][0]["horizon"] == 10_000.0 and info["git_commit"]
    assert info["machine"]["cores"] >= 1 and info["machine"]["cpu"]  # long paths vary by CPU
    after = read_results(folder / "results.parquet")
    held = decode_json(after["holdout"].dropna().iloc[0])
    assert held["horizon"] == 10_000.0 and held["training_horizon"] == 1000.0
    assert len(held["cost"]) == len(old["cost"])
    # every converged start by the training deadline keeps its cost (the event ends the run)
    for a, b, c in zip(old["cost"], held["cost"], held["converged_by_deadline"]):
        assert not c or a == pytest.approx(b, rel=1e-9)
    text = (folder / "tables" / "holdout.csv").read_text()
    assert "ratio_median" in text and "10000" in text


def test_paired_selection_keeps_the_starts_the_tables_pair(copy):
    df = read_results(copy / "studies" / STUDY / "results.parquet")
    paired = rejudge.select_jobs(df, "paired")
    assert 0 < len(paired) < len(rejudge.select_jobs(df, "all"))
    for param, g in df.groupby("param"):
        best = g[g["best_converged"].astype(bool)]["best_cost"].min()
        assert best in set(paired[paired["param"] == param]["best_cost"])
    with pytest.raises(StudyError, match="jobs must be one of"):
        rejudge.select_jobs(df, "some")


def test_a_failing_record_is_recorded_not_raised():
    row = rejudge.rejudge_record({"job_id": "x", "config_hash": "h", "problem": "zermelo",
                                 "case": "default", "problem_params": "{}",
                                 "matrices": '{"K": [[1.0, 0.0], [0.0, -1.0]]}',
                                 "scalars": None})
    assert row["holdout"] is None and row["status"].startswith("failed: ConfigError")


@pytest.mark.slow
def test_tables_rebuilt_from_the_committed_data(copy):
    from penaltyrun.docsgen import studies, tablecheck
    table = copy / "studies" / STUDY / "tables" / "holdout.csv"
    table.write_text(table.read_text().replace("ratio_median", "edited"))
    assert tablecheck.check_study(copy, STUDY)
    studies.rebuild_tables(copy, STUDY)
    assert tablecheck.check_study(copy, STUDY) == []
