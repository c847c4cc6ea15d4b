"""Probing a committed study's best points: the command writes what is committed (every
column but the CPU time), with its provenance, and refuses a study without results."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from penaltyrun.docsgen import probe
from penaltyrun.docsgen.__main__ import main
from penaltyrun.docsgen.studies import StudyError
from penaltyrun.optim.probe import STEPS

ROOT = Path(__file__).resolve().parents[2]


def _copy(tmp_path: Path, name: str) -> Path:
    shutil.copytree(ROOT / "studies" / name, tmp_path / "studies" / name,
                    ignore=shutil.ignore_patterns(probe.PROBE_FILE, probe.PROBE_PROVENANCE))
    return tmp_path


def _same_as_committed(root: Path, name: str) -> None:
    written = pd.read_csv(root / "studies" / name / probe.PROBE_FILE)
    committed = pd.read_csv(ROOT / "studies" / name / probe.PROBE_FILE)
    assert list(written.columns) == list(committed.columns)
    pd.testing.assert_frame_equal(written.drop(columns="cpu_s"),
                                  committed.drop(columns="cpu_s"), rtol=1e-4)
    info = json.loads((root / "studies" / name / probe.PROBE_PROVENANCE).read_text())
    assert info["steps"] == list(STEPS) and info["points"] == len(written)
    assert "numpy" in info["packages"] and info["git_commit"]


def test_robust_mpc_probe_is_the_committed_one(tmp_path):
    root = _copy(tmp_path, "robust_mpc")
    assert main(["--root", str(root), "study", "probe", "robust_mpc", "--workers", "1"]) == 0
    _same_as_committed(root, "robust_mpc")
    frame = pd.read_csv(root / "studies" / "robust_mpc" / probe.PROBE_FILE)
    # the recomputed cost is the record's: the problem and layout were rebuilt faithfully
    assert (abs(frame["cost"] / frame["record_cost"] - 1) < 1e-9).all()
    assert set(frame["map"]) == {"diagonal", "full"}


@pytest.mark.slow
def test_robust_attitude_probe_is_the_committed_one(tmp_path):
    root = _copy(tmp_path, "robust_attitude")
    probe.probe_study(root, "robust_attitude", workers=2)
    _same_as_committed(root, "robust_attitude")


def test_a_study_without_results_is_refused(tmp_path):
    root = _copy(tmp_path, "robust_mpc")
    (root / "studies" / "robust_mpc" / "results.parquet").unlink()
    with pytest.raises(StudyError, match="has no results.parquet"):
        probe.probe_study(root, "robust_mpc")
    assert main(["--root", str(root), "study", "probe", "robust_mpc"]) == 2


def test_cliff_table_and_counts_read_the_committed_probe(tmp_path):
    frame = pd.read_csv(ROOT / "studies" / "robust_mpc" / probe.PROBE_FILE)
    table = probe.cliff_table(ROOT, "robust_mpc").splitlines()
    assert len(table) == 2 + len(frame)
    assert all(f"at {s:g}" in table[0] for s in STEPS) and "≥ 1 %" in table[0]
    counts = probe.cliff_counts(ROOT, "robust_mpc")
    assert counts == {"points": len(frame),
                      "cliffs": int((frame["smallest_cliff_step"] <= 1e-4).sum()),
                      "improved": int((frame["lowest_change_pct"] < 0).sum())}
    for (_, row), line in zip(frame.iterrows(), table[2:]):
        assert line.startswith(f"| {row['problem']} / {row['case']} | {row['map']} |")
        assert ("none" in line.split("|")[-2]) == (row["lowest_change_pct"] >= 0)


def test_without_a_probe_the_page_names_the_command(tmp_path):
    assert "study probe robust_mpc" in probe.cliff_table(tmp_path, "robust_mpc")
    assert probe.cliff_counts(tmp_path, "robust_mpc") == {"points": 0, "cliffs": 0,
                                                           "improved": 0}


@pytest.mark.parametrize("workers", ["0", "two"])
def test_a_bad_worker_count_is_one_line_and_exit_2(tmp_path, capsys, workers):
    assert main(["--root", str(tmp_path), "study", "probe", "robust_mpc",
                 "--workers", workers]) == 2
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "--workers: must be a positive integer or auto" in lines[0]


def test_store_probes_writes_what_is_committed(tmp_path):
    import numpy as np

    from penaltyrun.io import storedprobe

    root = tmp_path
    shutil.copytree(ROOT / "studies" / "robust_mpc", root / "studies" / "robust_mpc",
                    ignore=shutil.ignore_patterns(storedprobe.PROBE_FILE))
    assert main(["--root", str(root), "study", "store-probes", "robust_mpc",
                 "--workers", "1"]) == 0
    written = storedprobe.read_one(root / "studies" / "robust_mpc" / storedprobe.PROBE_FILE)
    committed = storedprobe.read_one(ROOT / "studies" / "robust_mpc" / storedprobe.PROBE_FILE)
    assert list(written["job_id"]) == list(committed["job_id"])
    for a, b in zip(written.itertuples(), committed.itertuples()):
        np.testing.assert_array_equal(a.best_z, b.best_z)
        np.testing.assert_allclose(np.asarray(a.change, float), np.asarray(b.change, float),
                                   rtol=1e-7, atol=1e-12)
        np.testing.assert_array_equal(a.status_change, b.status_change)
    (root / "studies" / "robust_mpc" / "results.parquet").unlink()
    assert main(["--root", str(root), "study", "store-probes", "robust_mpc"]) == 2
