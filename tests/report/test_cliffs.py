"""The report's cliff probe: a smooth criterion (Zermelo) shows no cliff and its changes
shrink with the step; the free-final-time attitude criterion shows the jump the study
probe found; a problem that cannot be rebuilt gets no section; `--no-probe` leaves it out."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from penaltyrun.cli import report_main
from penaltyrun.io.schema import read_results
from penaltyrun.optim.probe import STEPS
from penaltyrun.penalty.orthogonal import GS_SKIP
from penaltyrun.report import cliffs
from penaltyrun.report.bestknown import best_rows

ROOT = Path(__file__).resolve().parents[2]
GOLDEN = Path(__file__).parent / "golden" / "zermelo" / "input"


def test_smooth_zermelo_cost_has_no_cliff_and_changes_shrink_with_the_step(tmp_path):
    df = read_results(GOLDEN / "results.parquet")
    lines = cliffs.section(df, tmp_path, "z")
    assert lines[0] == "### Cliffs next to the best points"
    assert (tmp_path / "cliffs_z.png").read_bytes()[:4] == b"\x89PNG"
    for fam, row in best_rows(df).items():
        result, names = cliffs.probe_row(row)
        assert len(names) == len(row["best_z"]) and result.converged
        largest = result.largest()
        assert np.all(np.diff(np.log10(largest)) > 1.5), fam  # ≈ h² at a minimum
        assert np.isnan(result.smallest_cliff_step())
    table = cliffs.table({fam: (row, *cliffs.probe_row(row))
                          for fam, row in best_rows(df).items()})
    assert list(table.columns) == ["map", "by", "cost",
                                   *(f"largest change (%) at {s:g}" for s in STEPS),
                                   cliffs.CLIFF_COLUMN, "lowest change found (%)",
                                   cliffs.MARGIN_COLUMN] and len(table) == 2
    assert (table[cliffs.CLIFF_COLUMN] == f"none up to {STEPS[-1]:g}").all()
    # The map's own jumps: GEAGSP of a 2 x 2 K jumps where |sin φ| crosses the skip threshold.
    for fam, row in best_rows(df).items():
        margin = cliffs.skip_margin(row)
        if fam == "diagonal":
            assert margin == np.inf
        else:
            phi = np.asarray(row["best_z"])[2]
            assert margin == pytest.approx(abs(abs(np.sin(phi)) - GS_SKIP), rel=1e-9)
        assert cliffs.margin_text(margin) in set(table[cliffs.MARGIN_COLUMN])


def test_attitude_free_final_time_point_is_next_to_a_jump():
    df = read_results(ROOT / "studies" / "robust_attitude" / "results.parquet")
    cell = df[(df["problem"] == "attitude_lyapunov") & (df["case"] == "detumble")]
    row = best_rows(cell)["full"]
    result, _ = cliffs.probe_row(row)
    committed = pd.read_csv(ROOT / "studies" / "robust_attitude" / "probe.csv")
    same = committed[(committed["problem"] == "attitude_lyapunov")
                     & (committed["case"] == "detumble") & (committed["map"] == "full")]
    assert result.smallest_cliff_step() == float(same["smallest_cliff_step"].iloc[0]) <= 1e-4
    assert result.cost == float(row["best_cost"])


def test_no_section_without_a_rebuildable_problem_or_a_decision_vector(tmp_path):
    df = read_results(GOLDEN / "results.parquet")
    row = best_rows(df)["full"].copy()
    assert cliffs.probe_row({**row.to_dict(), "best_z": None}) is None
    assert cliffs.probe_row({**row.to_dict(), "problem": "no_such_problem"}) is None
    assert cliffs.section(df.assign(problem="no_such_problem"), tmp_path, "x") == []


def test_report_no_probe_leaves_the_section_out(tmp_path):
    report_main([str(GOLDEN / "results.parquet"), "-o", str(tmp_path / "a"),
                 "--basin-points", "0", "--no-probe"])
    assert "Cliffs next to the best points" not in (tmp_path / "a" / "report.md").read_text()
    assert not list((tmp_path / "a").glob("cliffs_*.png"))


def test_the_report_and_the_results_pages_render_one_summary(tmp_path):
    """A probe summarized by the report equals the same probe written to and read back from
    a study's probe.csv, rendered by the same table."""
    df = read_results(GOLDEN / "results.parquet")
    rows = [cliffs.summary({**row, "family": fam}, *cliffs.probe_row(row))
            for fam, row in best_rows(df).items()]
    frame = pd.DataFrame(rows)
    frame.to_csv(tmp_path / "probe.csv", index=False, float_format="%.6g")
    assert list(frame.columns[:len(cliffs.KEYS)]) == cliffs.KEYS
    shown = cliffs.summary_table(frame)
    read_back = cliffs.summary_table(pd.read_csv(tmp_path / "probe.csv"))
    assert list(shown.columns) == list(read_back.columns)
    assert (shown["problem / case"] == "zermelo / " + frame["case"]).all()
    for column in shown.columns:  # numbers to the CSV's 6 digits, text exactly
        if not pd.api.types.is_numeric_dtype(shown[column]):
            assert list(shown[column]) == list(read_back[column]), column
        else:
            np.testing.assert_allclose(shown[column], read_back[column], rtol=1e-5)
