"""The results pages' figure of the tuning cost against the plant size."""

from __future__ import annotations

import io
from pathlib import Path

import pandas as pd

from penaltyrun.docsgen import scalingfig
from penaltyrun.docsgen.comparefig import FIGURES, to_csv

TABLE = pd.DataFrame({
    "problem": "lqr", "case": "default", "variant": "", "optimizer": ["lbfgs", "cmaes"] * 2,
    "param": "givens", "size": [16, 16, 4, 4], "dim": [146, 146, 11, 11], "n_starts": 5,
    "n_reached": [5, 0, 5, 5], "cpu_s_to_reach_median": [1.0, float("nan"), 0.05, 1.2],
    "evals_to_reach_median": [775, float("nan"), 80, 4000],
    "cpu_s_spent_min": [9.0, 150.0, 0.4, 5.0], "evals_spent_median": [2e4, 2e5, 1e3, 2e4]})


def test_section_registers_the_numbers_it_draws_and_links_the_figure():
    figures: dict[Path, str] = {}
    text = scalingfig.section("study_x", TABLE, figures)
    rel = FIGURES / "study_x_scaling.csv"
    assert list(figures) == [rel] and "figures/study_x_scaling.png" in text
    drawn = pd.read_csv(io.StringIO(figures[rel]))
    assert list(drawn.columns) == scalingfig.CSV_COLUMNS
    assert drawn[["optimizer", "size"]].values.tolist() == [["cmaes", 4], ["cmaes", 16],
                                                           ["lbfgs", 4], ["lbfgs", 16]]


def test_draw_writes_a_png_with_a_cell_that_never_reached(tmp_path):
    out = scalingfig.draw(to_csv(scalingfig.points(TABLE)), tmp_path / "f.png", "title")
    assert Path(out).is_file() and Path(out).stat().st_size > 1000
