"""What a larger budget changed: the budget check and the budget effect of
:mod:`penaltyrun.docsgen.convergence` on small hand-made records."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import convergence


def _records(param: str, budget: int, costs: list[float], case: str = "c") -> pd.DataFrame:
    """Finished, converged starts of one cell with best costs ``costs`` (flat traces)."""
    n = len(costs)
    return pd.DataFrame({
        "problem": "p", "case": case, "param": param, "optimizer": "cmaes",
        "max_evals": budget, "status": "ok", "best_converged": True, "best_cost": costs,
        "job_id": [f"{param}-{budget}-{case}-{i}" for i in range(n)],
        "n_evals": budget, "trace_evals": [np.array([1.0])] * n,
        "trace_best": [np.array([c]) for c in costs]})


def test_budget_check_compares_each_budget_with_the_smallest():
    frame = pd.concat([_records("diagonal", 100, [2.0, 3.0]),
                       _records("givens", 100, [1.0, 1.2, 1.6]),
                       _records("givens", 400, [0.9, 1.0])], ignore_index=True)
    table = convergence.budget_check(frame)
    assert list(table.columns) == convergence.BUDGET_CHECK_COLUMNS
    # only the Givens cell ran at two budgets: one row per budget, the smallest first
    assert table["map"].tolist() == ["givens", "givens"]
    assert table["evaluations per start"].tolist() == ["100", "400"]
    assert table["starts"].tolist() == ["3 of 3", "2 of 2"]
    assert table["best: change (%)"].tolist() == pytest.approx([0.0, -10.0])
    assert table["median: change (%)"].tolist() == pytest.approx([0.0, 100 * (0.95 - 1.2) / 1.2])
    assert table["late gain (%)"].tolist() == [0.0, 0.0]


def test_budget_effect_is_the_largest_fall_of_a_best_known_value():
    # the full best fell from 1.0 to 0.9 with the larger budget: 10 % of the new best
    # (11.1 %); the diagonal best is unchanged; another case ran at one budget only
    frame = pd.concat([_records("diagonal", 100, [2.0, 3.0]),
                       _records("givens", 100, [1.0, 1.2]),
                       _records("givens", 400, [0.9]),
                       _records("givens", 100, [5.0], case="d")], ignore_index=True)
    assert convergence.budget_effect(frame) == pytest.approx(100 * 0.1 / 0.9)
    # a larger budget that found nothing lower changed nothing
    worse = frame.assign(best_cost=np.where(frame["max_evals"] == 400, 1.5,
                                            frame["best_cost"]))
    assert convergence.budget_effect(worse) == pytest.approx(0.0)


def test_one_budget_everywhere_has_no_budget_check():
    frame = pd.concat([_records("diagonal", 100, [2.0]), _records("givens", 100, [1.0])],
                      ignore_index=True)
    assert convergence.budget_check(frame).empty
    assert math.isnan(convergence.budget_effect(frame))
    assert convergence.budgets(frame) == "100"
    assert convergence.budgets(frame.drop(columns="max_evals")) == "—"


def test_the_late_gain_of_a_best_known_cell_is_over_all_its_starts():
    """The cell holding a best-known value is judged on every start, not on the best one:
    here its best start improved late by 100 %, its median start not at all."""
    frame = _records("givens", 100, [1.0, 1.2, 1.4])
    frame["trace_evals"] = [np.array([10.0, 90.0]), np.array([10.0]), np.array([10.0])]
    frame["trace_best"] = [np.array([2.0, 1.0]), np.array([1.2]), np.array([1.4])]
    assert convergence.largest_late_gain(frame, frame["job_id"].iloc[:1]) == 0.0
    assert convergence.largest_late_gain(frame) == 0.0


def _held_out(costs: list[float]) -> str:
    import json
    return json.dumps({"scenario": [f"s{k}" for k in range(len(costs))], "cost": costs,
                       "converged": [True] * len(costs), "horizon": 50.0})


def test_holdout_by_budget_judges_the_best_full_point_of_each_budget():
    """Each budget's row pairs the best full start of the records up to that budget with
    the best diagonal start over the held-out scenarios; a later, better-trained full
    point that costs more off the training set turns the verdict, which the stability
    count reports."""
    n = 12
    rows = [("diagonal", 100, 2.0, [1.0] * n), ("givens", 100, 1.5, [0.5] * n),
            ("givens", 100, 1.8, [3.0] * n), ("givens", 400, 1.2, [2.0] * n)]
    frame = pd.concat([_records(param, budget, [cost]).assign(
        problem="zermelo", case="default", problem_params="{}", job_id=f"j{k}",
        holdout=_held_out(held)) for k, (param, budget, cost, held) in enumerate(rows)],
        ignore_index=True)
    table = convergence.holdout_by_budget(frame)
    assert list(table.columns) == convergence.HOLDOUT_BY_BUDGET_COLUMNS
    assert table["full records up to"].tolist() == ["100", "400"]
    assert table["full cost"].tolist() == [1.5, 1.2]
    assert table["full cheaper"].tolist() == [f"{n}/{n}", f"0/{n}"]
    assert table["median J_full/J_diag"].tolist() == pytest.approx([0.5, 2.0])
    # twelve equal signs: exact two-sided signed-rank p = 2 / 2**12, Holm over two rows
    assert table["Holm p"].tolist() == pytest.approx([2 * 2 / 2 ** n] * 2)
    assert table["verdict"].tolist() == ["full cheaper", "diagonal cheaper"]
    assert convergence.verdict_stability(table) == (0, 1)
    same = frame.assign(holdout=[_held_out(h) for h in ([1.0] * n, [0.5] * n, [3.0] * n,
                                                        [0.6] * n)])
    assert convergence.verdict_stability(convergence.holdout_by_budget(same)) == (1, 1)
    assert convergence.holdout_by_budget(frame[frame["max_evals"] == 100]).empty
