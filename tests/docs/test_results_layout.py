"""Results pages readable: no table wider than ten columns outside a fold, shares as
percentages, the equal-budget tests as an A12 figure whose numbers are checked."""

from __future__ import annotations

from pathlib import Path

import markdown
import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import comparefig, layout, resultpages, results
from penaltyrun.report.compare import a12_interval, pairwise

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("page", sorted((ROOT / "docs" / "results").glob("*.md")),
                         ids=lambda p: p.name)
def test_committed_results_pages_have_no_wide_table_outside_a_fold(page):
    assert layout.wide_tables(page.read_text()) == []


def test_wide_tables_sees_tables_outside_folds_only():
    wide = "| " + " | ".join(f"c{i}" for i in range(11)) + " |\n|" + "---|" * 11 + "\n"
    narrow = "| a | b |\n|---|---|\n| 1 | 2 |\n"
    assert layout.wide_tables(f"text\n\n{wide}\n{narrow}") == [(3, 11)]
    assert layout.wide_tables(layout.fold("more", wide)) == []
    assert layout.wide_tables(layout.fold("more", narrow) + f"\n\n{wide}") != []
    assert layout.wide_tables(wide.replace("c3", "c3 \\| x")) == [(1, 11)]  # escaped pipe


def _frame(columns: int) -> pd.DataFrame:
    data = {"problem": ["p", "p"], "optimizer": ["cmaes", "pso"]}
    data.update({f"v{i}": [float(i), i + 0.5] for i in range(columns - 2)})
    return pd.DataFrame(data)


def test_a_wide_table_is_cut_into_tables_of_ten_columns_with_the_rest_behind_a_fold():
    text = layout.narrow_table(_frame(25))
    assert layout.wide_tables(text) == []
    head, folded = text.split(layout.FOLD_OPEN)
    assert head.strip().splitlines()[0].startswith("| problem | optimizer | v0 |")
    tables = [block for block in folded.split("\n\n") if block.startswith("|")]
    assert len(tables) == 2  # 17 further columns, 8 per table beside the two keys
    for table in tables:
        header = table.splitlines()[0]
        assert header.startswith("| problem | optimizer |")
        assert header.count("|") - 1 <= layout.MAX_COLUMNS
    headers = [head.strip().splitlines()[0], *(t.splitlines()[0] for t in tables)]
    shown = [c.strip() for h in headers for c in h.strip("| ").split(" | ")]
    assert set(shown) == {"problem", "optimizer", *(f"v{i}" for i in range(23))}
    assert len(shown) == 25 + 2 * 2  # each column once, the keys repeated per table
    assert layout.narrow_table(_frame(10)) == layout.markdown_table(_frame(10))


def test_main_columns_choose_the_answer_and_keep_the_others_behind_the_fold():
    text = layout.narrow_table(_frame(12), main=["problem", "optimizer", "v9"])
    head, folded = text.split(layout.FOLD_OPEN)
    assert head.strip().splitlines()[0] == "| problem | optimizer | v9 |"
    assert "More columns: v0, v1" in folded and "v9" not in folded.split("</summary>")[1]


def test_the_fold_renders_as_a_table_with_the_site_markdown_extensions():
    html = markdown.markdown(layout.narrow_table(_frame(14)),
                             extensions=["md_in_html", "tables", "pymdownx.details"])
    inside = html.split("<details>")[1]
    assert "<summary>More columns:" in inside and "<table>" in inside


def test_a_cell_with_pipes_and_line_breaks_stays_one_cell_of_one_row():
    frame = pd.DataFrame({"a": ["x | y\nz"], "b": [1]})
    table = layout.markdown_table(frame)
    assert table.splitlines()[-1] == "| x \\| y z | 1 |"
    html = markdown.markdown(table, extensions=["tables"])
    assert html.count("<td>") == 2 and "x | y z" in html


def test_shares_print_as_percentages_and_counts_do_not():
    frame = pd.DataFrame({"optimizer": ["pso"], "success_b": [1.0],
                          "full_better_share": [1 / 3], "full_cheaper": [34],
                          "single: full cheaper": [0.009259], "success_a": [np.nan],
                          "diag_conv": ["24/24"]})
    row = layout.markdown_table(frame).splitlines()[2]
    assert row == "| pso | 100 % | 33.3 % | 34 | 0.926 % | — | 24/24 |"


def _records() -> pd.DataFrame:
    rng = np.random.default_rng(3)
    rows = []
    for optimizer, shift in (("cmaes", 0.5), ("pso", -0.2)):
        for param, offset in (("diagonal", 0.0), ("geagsp", shift), ("givens", 0.1)):
            for k, cost in enumerate(10.0 - offset + rng.normal(size=12)):
                rows.append({"problem": "toy", "case": "c", "optimizer": optimizer,
                             "param": param, "start": k, "status": "ok",
                             "best_cost": float(cost), "best_converged": True,
                             "n_evals": 500, "max_evals": 500, "problem_params": "{}"})
    return pd.DataFrame(rows)


def test_the_comparison_section_draws_the_diagonal_pairs_with_their_intervals(tmp_path):
    df = _records()
    comparison = pairwise(df.assign(variant=""))
    figures: dict[Path, str] = {}
    text = comparefig.section("toy_study", df, comparison, figures)
    assert "![A12" in text and "figures/toy_study_a12.png" in text
    assert layout.wide_tables(text) == [] and layout.FOLD_OPEN in text
    (rel, csv_text), = figures.items()
    assert rel == comparefig.FIGURES / "toy_study_a12.csv"
    drawn = pd.read_csv(pd.io.common.StringIO(csv_text))
    assert list(zip(drawn["optimizer"], drawn["map_b"])) == [
        ("cmaes", "geagsp"), ("cmaes", "givens"), ("pso", "geagsp"), ("pso", "givens")]
    sel = df[(df["optimizer"] == "pso")]
    expected = a12_interval(sel.loc[sel["param"] == "diagonal", "best_cost"],
                            sel.loc[sel["param"] == "geagsp", "best_cost"])
    got = drawn.iloc[2][["a12_b_beats_a", "a12_lo", "a12_hi"]].to_numpy(float)
    assert got == pytest.approx(expected[:3], rel=1e-5)
    png = comparefig.draw(csv_text, tmp_path / "toy.png", "toy")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_stale_comparison_table_is_refused():
    df = _records()
    comparison = pairwise(df.assign(variant=""))
    comparison.loc[0, "a12_b_beats_a"] += 0.01
    with pytest.raises(ValueError, match="regenerate the study's report"):
        comparefig.section("toy_study", df, comparison, {})


def test_check_wants_each_figure_png_and_no_stray_figure(tmp_path):
    folder = tmp_path / comparefig.FIGURES
    folder.mkdir(parents=True)
    numbers = comparefig.FIGURES / "a_a12.csv"
    (tmp_path / numbers).write_text("x\n")
    assert resultpages._check_figures(tmp_path, {numbers}) == [
        f"{numbers.with_suffix('.png')}: missing (run `make docs-results`)"]
    (tmp_path / numbers.with_suffix(".png")).write_bytes(b"png")
    (folder / "old_a12.png").write_bytes(b"png")
    assert resultpages._check_figures(tmp_path, {numbers}) == [
        f"{comparefig.FIGURES / 'old_a12.png'}: no results page draws it (delete it)"]


def test_the_verdict_shows_one_result_per_cell_and_the_tests_behind_a_fold():
    text = results.Context(ROOT).verdict("referee_attitude")
    head, folded = text.split(layout.FOLD_OPEN)
    assert head.strip().splitlines()[0] == \
        "| question | diagonal best-known | full best-known | gain |"
    assert "| question | equal budget | held-out | discretization |" in folded
    assert "Holm p" not in head  # the tests sit behind the fold, the sentences under it
    assert folded.split(layout.FOLD_CLOSE)[1].strip().startswith("- **attitude_lqr")
