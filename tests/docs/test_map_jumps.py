"""Where a study's GEAGSP searches ended relative to the map's own jumps (skip margins)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import probe
from penaltyrun.io.schema import read_results
from penaltyrun.penalty.orthogonal import GS_SKIP
from penaltyrun.report.cliffs import rebuilt_layout

ROOT = Path(__file__).resolve().parents[2]
NAME = "robust_mpc"


def _planted(tmp_path: Path, first_angle: float | None) -> Path:
    """A copy of the study whose full starts all end with the first angle of their first
    matrix set to ``first_angle`` (None: every angle 1.1 rad, far from a jump)."""
    folder = tmp_path / "studies" / NAME
    shutil.copytree(ROOT / "studies" / NAME, folder)
    df = pd.read_parquet(folder / "results.parquet")
    full = df["param"] == "geagsp"
    layout = rebuilt_layout(df[full].iloc[0])[1]
    first = layout.matrices[0][1].n  # the first angle follows the first block's eigenvalues
    moved = []
    for z in df.loc[full, "best_z"]:
        z = np.array(z, float)
        if first_angle is None:
            angles = np.array(["ang" in n for n in layout.names()])
            z[angles] = 1.1
        else:
            z[first] = first_angle
        moved.append(z)
    df.loc[full, "best_z"] = pd.Series(moved, index=df.index[full])
    df.to_parquet(folder / "results.parquet")
    return tmp_path


def test_committed_study_rows_cover_its_geagsp_cells_only():
    rows = probe.map_jumps(ROOT, NAME)
    df = read_results(ROOT / "studies" / NAME / "results.parquet")
    cells = df[(df["param"] == "geagsp") & (df["status"] == "ok")].groupby("optimizer").size()
    assert [(r["param"], r["optimizer"], r["starts"]) for r in rows] == [
        ("geagsp", opt, int(n)) for opt, n in cells.items()]
    for r in rows:
        assert 0 <= r["near"] <= r["starts"] and 0.0 <= r["baseline"] < 0.5
    assert probe.map_jumps(ROOT, NAME) == rows  # the baseline is seeded


def test_starts_on_a_pole_are_on_a_jump(tmp_path):
    rows = probe.map_jumps(_planted(tmp_path, 0.0), NAME)
    assert rows and all(r["near"] == r["starts"] for r in rows)
    assert all(r["median"] == pytest.approx(GS_SKIP, rel=1e-6) for r in rows)


def test_starts_far_from_a_pole_are_far_from_a_jump(tmp_path):
    rows = probe.map_jumps(_planted(tmp_path, None), NAME)
    assert rows and all(r["near"] == 0 and r["median"] > 0.1 for r in rows)


def test_a_study_without_results_has_no_rows(tmp_path):
    folder = tmp_path / "studies" / NAME
    folder.mkdir(parents=True)
    shutil.copy(ROOT / "studies" / NAME / "study.yaml", folder / "study.yaml")
    assert probe.map_jumps(tmp_path, NAME) == []


def test_answer_row_counts_are_the_studies_own():
    readme = (ROOT / "README.md").read_text()
    with_jumps = 0
    for name in ("robust_attitude", "robust_mpc"):
        rows = probe.map_jumps(ROOT, name)
        assert f"`{name}`" in readme
        if not rows:  # a continuous full map: the row says nothing of the map's jumps
            continue
        with_jumps += 1
        near, starts = sum(r["near"] for r in rows), sum(r["starts"] for r in rows)
        assert f"{near} of {starts} searches of the full map (GEAGSP) ended within" in readme
    assert readme.count("searches of the full map (GEAGSP) ended within") == with_jumps
