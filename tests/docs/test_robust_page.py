"""The robust-tuning page's template functions: the late gain from the anytime traces, the
recorded problem parameters and optimizer settings, and the page and answer row pending
until their data is committed (the page filled from real data:
``tests/docs/test_studies.py``)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import resultpages, results

ROOT = Path(__file__).resolve().parents[2]


def _context(tmp_path: Path, frame: pd.DataFrame) -> results.Context:
    """A context whose study ``s`` holds ``frame`` as its records."""
    folder = tmp_path / "studies" / "s"
    folder.mkdir(parents=True)
    (folder / "study.yaml").write_text(
        "title: t\nquestion: q\ncommands:\n- subdir: main\n  args: [problem=zermelo]\n")
    ctx = results.Context(tmp_path)
    ctx.study("s").__dict__["df"] = frame  # the cached records
    return ctx


def _frame() -> pd.DataFrame:
    return pd.DataFrame({
        "problem": ["p"] * 4, "param": ["diagonal", "diagonal", "geagsp", "geagsp"],
        "status": ["ok", "ok", "ok", "failed"],
        "best_converged": [True, True, True, False],
        # best-so-far change points (evaluations, best cost)
        "trace_evals": [np.array([10, 40, 90]), np.array([10, 60]), np.array([5]),
                        np.array([10])],
        "trace_best": [np.array([3.0, 2.0, 1.0]), np.array([4.0, 2.0]), np.array([7.0]),
                       np.array([1.0])],
        "n_evals": [100, 100, 100, 100],
        "problem_params": [json.dumps({"train_sample": 8, "rho": 1e-3})] * 3
        + [json.dumps({"train_sample": 4, "rho": 1e-3})],
        "optimizer_settings": [json.dumps({"polish": "gradient", "polish_share": 0.2})] * 4,
    })


def test_late_gain_is_the_median_fall_over_the_second_half(tmp_path):
    ctx = _context(tmp_path, _frame())
    # diagonal: best at 50 evaluations 2.0 then 1.0 (100 %); 4.0 then 2.0 (100 %)
    assert ctx.late_gain("s", {"param": "diagonal"}) == pytest.approx(100.0)
    # geagsp: the finished start never improved after 5 evaluations; the failed one is left out
    assert ctx.late_gain("s", {"param": "geagsp"}) == 0.0
    # a quarter: at 25 evaluations the bests are 3.0 (200 % above 1.0) and 4.0 (100 %)
    assert ctx.late_gain("s", {"param": "diagonal"}, share=0.25) == pytest.approx(150.0)
    assert math.isnan(ctx.late_gain("s", {"param": "cayley"}))


def test_late_gain_leaves_out_what_the_polish_gained(tmp_path):
    # the search spent 80 evaluations, the polish the last 20 (its gain at 90 not counted)
    frame = _frame().assign(polish_evals=[20, 20, 0, 0])
    ctx = _context(tmp_path, frame)
    # first start: best 2.0 at 40 (half of 80) and at the search's end, 1.0 only at 90
    # (the polish): 0 %; second start: 4.0 at 40, 2.0 at 60: 100 %
    assert ctx.late_gain("s", {"param": "diagonal"}) == pytest.approx(50.0)
    # a search that stalled and a polish that then gained: no late gain
    stalled = _frame().assign(trace_evals=[np.array([10, 90])] * 4,
                              trace_best=[np.array([2.0, 1.0])] * 4, polish_evals=20)
    assert _context(tmp_path / "b", stalled).late_gain("s", {"param": "diagonal"}) == 0.0


def _warm_frame(stage: dict) -> pd.DataFrame:
    """One warm-started start of 1 000 evaluations (max_evals 1 000, share 0.3, polish
    share 0.2): a diagonal stage of 300 (240 search, then 60 of polish), then the
    full-map search from 300 to 860 and its polish to 1 000."""
    return pd.DataFrame({
        "param": ["givens"], "status": ["ok"], "best_converged": [True],
        # the diagonal stage falls 9 → 5; the full search 5 → 2 by 500, 2 → 1.6 at 800;
        # the full polish gains 1.6 → 1.0 at 950 (not the search's)
        "trace_evals": [np.array([1, 100, 280, 320, 500, 800, 950])],
        "trace_best": [np.array([9.0, 7.0, 5.0, 4.0, 2.0, 1.6, 1.0])],
        "n_evals": [1000], "polish_evals": [200], "max_evals": [1000],
        "optimizer_settings": [json.dumps({"polish": "gradient", "polish_share": 0.2})],
        "warm_start": [json.dumps({"share": 0.3, **stage})]})


@pytest.mark.parametrize("stage", [{"n_evals": 300, "polish_evals": 60},
                                   {"n_evals": 300}])  # older records: inferred
def test_a_warm_started_start_is_judged_on_its_full_map_search(tmp_path, stage):
    """The window is the full-map search, 300 to 860 (the diagonal stage and both
    polishes left out): best 2.0 at its middle (580), 1.6 at its end: 25 %. Judged as a
    cold start's search (0 to 800: best 4.0 at its middle, 1.6 at its end: 150 %), the
    full search's early fall would count as a late one."""
    from penaltyrun.docsgen.convergence import search_window

    frame = _warm_frame(stage)
    assert search_window(frame.to_dict("records")[0]) == (300.0, 860.0)
    assert _context(tmp_path, frame).late_gain("s") == pytest.approx(25.0)
    cold = frame.assign(warm_start=None)
    assert search_window(cold.to_dict("records")[0]) == (0.0, 800.0)
    assert _context(tmp_path / "cold", cold).late_gain("s") == pytest.approx(150.0)


def test_largest_late_gain_over_every_cell_or_the_best_known_cells(tmp_path):
    frame = _frame().assign(case="c", optimizer="cmaes", job_id=["d1", "d2", "g1", "g2"],
                            max_evals=100)
    ctx = _context(tmp_path, frame)
    assert ctx.largest_late_gain("s") == pytest.approx(100.0)  # diagonal 100 %, geagsp 0 %
    best = pd.DataFrame({"problem": ["p"], "case": ["c"], "param": ["geagsp"],
                         "optimizer": ["cmaes"], "job_id": ["g1"]})
    ctx.study("s").table = lambda stem: best  # the best-known table names geagsp alone
    assert ctx.largest_late_gain("s", best_known=True) == 0.0


def test_a_cell_run_again_at_a_larger_budget_is_a_cell_of_its_own(tmp_path):
    """The diagonal cell ran at 100 evaluations (late gain 100 %) and again at 400, where
    its search had stopped improving: two cells, the largest late gain of any cell judged
    at its largest budget, the best-known cell by its job, the budgets said per cell."""
    small = _frame().assign(case="c", optimizer="cmaes", job_id=["d1", "d2", "g1", "g2"],
                            max_evals=100)
    again = small.iloc[:2].assign(job_id=["D1", "D2"], max_evals=400, n_evals=400,
                                  trace_evals=[np.array([10, 40])] * 2,
                                  trace_best=[np.array([2.0, 0.5])] * 2)
    ctx = _context(tmp_path, pd.concat([small, again], ignore_index=True))
    assert [(c["param"], c["max_evals"]) for c in ctx.cells("s")] == [
        ("diagonal", 100), ("diagonal", 400), ("geagsp", 100)]
    assert ctx.late_gain("s", ctx.cells("s")[0]) == pytest.approx(100.0)
    assert ctx.late_gain("s", ctx.cells("s")[1]) == 0.0
    assert ctx.largest_late_gain("s") == 0.0  # the 100-evaluation diagonal cell ran again
    # a best-known value found at 100 evaluations: judged by the run at 400, whose
    # searches had stopped improving (more evaluations would not lower the value)
    ctx.study("s").table = lambda stem: pd.DataFrame({"job_id": ["d2"]})
    assert ctx.largest_late_gain("s", best_known=True) == 0.0
    ctx.study("s").table = lambda stem: pd.DataFrame({"job_id": ["g1"]})  # ran once
    assert ctx.largest_late_gain("s", best_known=True) == 0.0
    still = pd.concat([small, again.assign(trace_best=[np.array([2.0, 0.5])] * 2,
                                           trace_evals=[np.array([10, 300])] * 2)],
                      ignore_index=True)
    ctx = _context(tmp_path / "still", still)  # the 400 run still fell 2.0 → 0.5 late
    ctx.study("s").table = lambda stem: pd.DataFrame({"job_id": ["d2"]})
    assert ctx.largest_late_gain("s", best_known=True) == pytest.approx(300.0)
    assert ctx.budgets("s") == "100 (400 in 1 of 3 cells)"
    assert _context(tmp_path / "one", small).budgets("s") == "100"


def test_problem_params_agree_or_say_that_they_differ(tmp_path):
    ctx = _context(tmp_path, _frame())
    assert ctx.problem_params("s", "rho") == 1e-3
    assert ctx.problem_params("s", "train_sample") == "4 / 8"
    assert ctx.problem_params("s", "train_quantile") is None
    assert ctx.optimizer_setting("s", "polish") == "gradient"
    assert ctx.optimizer_setting("s", "polish_share") == 0.2


def test_polish_endings_are_counted_over_the_finished_starts(tmp_path):
    frame = _frame().assign(stop_reason=["max_evals+polish", "ftol+polish:no_gradient",
                                         "max_evals+polish:max_evals", "max_evals+polish"])
    ctx = _context(tmp_path, frame)  # the last start failed: not counted
    assert ctx.polish_endings("s") == ("on its own tolerances in 1, with the budget spent in "
                                       "1, without a gradient near the search's best in 1 "
                                       "of 3 starts")
    ctx = _context(tmp_path / "none", frame.assign(stop_reason="max_evals"))
    assert ctx.polish_endings("s") == ""


def test_polished_lists_the_committed_studies_polished_by_gradient(tmp_path):
    ctx = _context(tmp_path, _frame())
    assert ctx.polished(["s"]) == []  # records not committed (no results file)
    (tmp_path / "studies" / "s" / "results.parquet").write_bytes(b"")
    assert ctx.polished(["s"]) == ["s"]
    ctx = _context(tmp_path / "b", _frame().assign(optimizer_settings=json.dumps({})))
    (tmp_path / "b" / "studies" / "s" / "results.parquet").write_bytes(b"")
    assert ctx.polished(["s"]) == []


@pytest.mark.slow
def test_robust_page_and_answer_row_are_pending_without_their_data(tmp_path):
    """Before the studies are committed the page and the answer row name the command that
    fills them, never a number."""
    for name in ("robust_attitude", "robust_mpc"):
        if (ROOT / "studies" / name / "results.parquet").is_file():
            pytest.skip("the robust studies are committed: the page is filled from them")
    env = resultpages.environment(ROOT)
    page = env.get_template("robust.md").render()
    assert "make study-robust_attitude" in page and "make study-robust_mpc" in page
    assert "Basins of attraction," not in page
    answers = env.get_template(resultpages.ANSWERS_TEMPLATE).render()
    row = next(line for line in answers.splitlines() if "tuned to work everywhere" in line)
    assert "make study-robust_attitude" in row
