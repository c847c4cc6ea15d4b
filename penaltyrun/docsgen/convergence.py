"""How close a study's searches came to converged, from its records: the late gain of each
cell, and what running a cell again with more evaluations per start changed.

A *cell* is one problem × case × map × optimizer × budget (:data:`CELL_KEYS`): a cell run
again at a larger ``max_evals`` is a cell of its own, never pooled with the first. The
results pages call these through :class:`penaltyrun.docsgen.results.Context`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.docsgen.layout import fmt
from penaltyrun.io import decode_json
from penaltyrun.jobrecord import OK
from penaltyrun.optim.base import CommonSettings, main_budget_of
from penaltyrun.runner.plan import warm_stage_budget

#: What names one cell of a study: a cell run at two budgets is two cells.
CELL_KEYS = ("problem", "case", "param", "optimizer", "max_evals")
#: Columns of :func:`budget_check`.
BUDGET_CHECK_COLUMNS = ["problem", "case", "map", "optimizer", "evaluations per start",
                        "starts", "best", "median", "best: change (%)",
                        "median: change (%)", "late gain (%)"]
#: Columns of :func:`budget_check` shown outside a fold on the results pages.
BUDGET_CHECK_MAIN = tuple(c for c in BUDGET_CHECK_COLUMNS if c != "starts")
#: Columns of :func:`holdout_by_budget`.
HOLDOUT_BY_BUDGET_COLUMNS = ["problem", "case", "variant", "full records up to", "full cost",
                             "scenarios", "full cheaper", "median J_full/J_diag", "Holm p",
                             "verdict"]


def late_gain(frame: pd.DataFrame, share: float = 0.5) -> float:
    """How far the searches of ``frame``'s records were from converged: the median over
    the finished starts of the relative fall of the best-so-far cost over the last
    ``1 - share`` of each start's search, (best at its ``share`` point − best at its end)
    / |best at its end| in %, the search's window given by :func:`search_window` (a polish
    ends on its own criteria, and what it gains is not a search still improving; a
    warm-started start is judged on its full-map search). From the anytime trace; 0 where
    nothing improved; NaN without finished starts."""
    frame = frame[frame["status"] == OK]
    gains = []
    for row in frame.to_dict("records"):
        evals = np.asarray(row["trace_evals"], float)
        best = np.asarray(row["trace_best"], float)
        first, last = search_window(row)
        at_end = evals <= last
        before = evals <= first + share * (last - first)
        if not before.any():
            continue
        final = float(best[at_end][-1])
        if not np.isfinite(final) or final == 0.0:
            continue
        gains.append(100.0 * (float(best[before][-1]) - final) / abs(final))
    return float(np.median(gains)) if gains else float("nan")


def search_window(row: dict[str, Any]) -> tuple[float, float]:
    """Where a start's search lies on its evaluation count (that of its anytime trace):
    ``(0, n_evals − polish_evals)``, the polish after the search left out.

    A warm-started start (``warm_start`` holds the diagonal stage: its ``n_evals`` and, in
    records that have it, its ``polish_evals``) ran two searches: the diagonal stage, then
    the full-map search from the diagonal best, each followed by its polish. The window is
    the full-map search's: from the diagonal stage's last evaluation to the full stage's
    polish. Where the record lacks the diagonal stage's polish, it is what the stage spent
    beyond its search's share of its budget (``warm_start_share · max_evals`` less the
    ``polish_share``; a search of the budgeted optimizers spends its share).
    """
    spent = float(row["n_evals"])
    polish = _number(row.get("polish_evals"))
    warm = _warm(row.get("warm_start"))
    if warm is None:
        return 0.0, spent - polish
    stage = float(warm["n_evals"])
    stage_polish = _number(warm.get("polish_evals"), float("nan"))
    if not np.isfinite(stage_polish):
        stage_polish = max(0.0, stage - _stage_search(row, float(warm.get("share", 0.0))))
    return stage, spent - max(0.0, polish - stage_polish)


def _stage_search(row: dict[str, Any], share: float) -> float:
    """The evaluations the diagonal stage's search may spend, as the runner budgets it:
    the stage's budget less the polish share (infinite without a recorded budget: no
    polish inferred)."""
    budget = _number(row.get("max_evals"), float("nan"))
    settings = decode_json(row.get("optimizer_settings")) or {}
    if not np.isfinite(budget) or not isinstance(settings, dict):
        return float("inf")
    return float(main_budget_of(warm_stage_budget(share, int(budget)),
                                settings.get("polish", CommonSettings.polish),
                                float(settings.get("polish_share", CommonSettings.polish_share))))


def _warm(value: Any) -> dict[str, Any] | None:
    """The diagonal stage of a warm-started record (None for a cold start)."""
    warm = decode_json(value) if isinstance(value, str) else value
    return warm if isinstance(warm, dict) and "n_evals" in warm else None


def _number(value: Any, missing: float = 0.0) -> float:
    """``value`` as a float; ``missing`` for None, NaN or text."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return missing
    return number if np.isfinite(number) else missing


def cells(frame: pd.DataFrame) -> list[dict[str, Any]]:
    """The distinct cells (:data:`CELL_KEYS`, those ``frame`` has) of the records
    ``frame``, sorted, each as ``{column: value}``."""
    keys = [key for key in CELL_KEYS if key in frame]
    return frame[keys].drop_duplicates().sort_values(keys).to_dict("records")


def rows_of(frame: pd.DataFrame, where: dict[str, Any] | None = None,
            converged: bool = False) -> pd.DataFrame:
    """The records of ``frame`` matching ``where`` (column → value or list of values; a
    missing value matches a missing one), only the finished starts that converged if
    ``converged``."""
    keep = np.ones(len(frame), dtype=bool)
    for key, value in (where or {}).items():
        keep &= frame[key].isin(value if isinstance(value, list) else [value]).to_numpy()
    frame = frame[keep]
    return _converged(frame) if converged else frame


def at_largest_budget(frame: pd.DataFrame) -> pd.DataFrame:
    """The records of each problem × case × map × optimizer at its largest budget (all of
    them where it has none)."""
    if "max_evals" not in frame:
        return frame
    largest = frame.groupby(list(CELL_KEYS[:-1]))["max_evals"].transform("max")
    return frame[(frame["max_evals"] == largest) | largest.isna()]


def largest_late_gain(frame: pd.DataFrame, best_jobs: pd.Series | None = None) -> float:
    """The largest :func:`late_gain` of the cells of ``frame``, each problem × case × map
    × optimizer at its largest budget (a cell run again with more evaluations is judged
    there), or, given ``best_jobs`` (the job ids of the best-known values), of the cells
    holding them, judged the same way; 0 where no cell has one.

    A best-known value found at a smaller budget of a cell that ran again is judged by
    the run at the larger budget: whether more evaluations lower the value is what that
    run measures (its searches' late gain), and a lower value found there would be the
    best-known value instead (the pages give by how much the larger budgets lowered a
    best-known value, :func:`budget_effect`)."""
    if best_jobs is not None:
        holding = cells(frame[frame["job_id"].isin(best_jobs)].drop(
            columns=["max_evals"], errors="ignore"))
        keep = np.zeros(len(frame), dtype=bool)
        for cell in holding:
            keep |= frame.index.isin(rows_of(frame, cell).index)
        frame = frame[keep]
    judged = cells(at_largest_budget(frame))
    gains = [late_gain(rows_of(frame, cell)) for cell in judged]
    return max([0.0, *(g for g in gains if g == g)])  # NaN: a cell without finished starts


def budgets(frame: pd.DataFrame, spec: str = ".0f") -> str:
    """The evaluations per start of the cells of ``frame`` as text: the budget of most
    cells, then each other budget with its count of cells, e.g. "50000 (200000 in 6 of
    22 cells)"; "—" without a ``max_evals``."""
    every = cells(frame)
    counts: dict[float, int] = {}
    for cell in every:
        budget = float(cell.get("max_evals", float("nan")))
        if budget == budget:
            counts[budget] = counts.get(budget, 0) + 1
    if not counts:
        return "—"
    main = max(sorted(counts), key=lambda budget: counts[budget])
    others = [f"{fmt(budget, spec)} in {counts[budget]} of {len(every)} cells"
              for budget in sorted(counts) if budget != main]
    return fmt(main, spec) + (f" ({'; '.join(others)})" if others else "")


def budget_check(frame: pd.DataFrame) -> pd.DataFrame:
    """Each problem × case × map × optimizer run at more than one budget, one row per
    budget (smallest first): its starts, the best and median of the converged starts'
    ``best_cost``, their change against the smallest budget's in % (negative: the larger
    budget found lower costs) and the late gain (:func:`late_gain`); empty
    (:data:`BUDGET_CHECK_COLUMNS`) when every cell ran at one budget."""
    rows = []
    if "max_evals" in frame:
        for key, group in frame.groupby(list(CELL_KEYS[:-1]), sort=True):
            if group["max_evals"].nunique() < 2:
                continue
            first = None
            for budget, runs in group.groupby("max_evals", sort=True):
                good = _converged(runs)["best_cost"]
                best, median = float(good.min()), float(good.median())
                first = first or (best, median)
                rows.append({"problem": key[0], "case": key[1], "map": key[2],
                             "optimizer": key[3], "evaluations per start": f"{budget:.0f}",
                             "starts": f"{len(good)} of {len(runs)}", "best": best,
                             "median": median,
                             "best: change (%)": 100.0 * (best - first[0]) / abs(first[0]),
                             "median: change (%)":
                                 100.0 * (median - first[1]) / abs(first[1]),
                             "late gain (%)": late_gain(runs)})
    return pd.DataFrame(rows, columns=BUDGET_CHECK_COLUMNS)


def budget_effect(frame: pd.DataFrame) -> float:
    """What the larger budgets changed in the best-known values: the largest relative fall,
    in %, of a problem × case's best diagonal or best full converged cost (full: any map
    but ``diagonal``) from the records at each cell's smallest budget alone to all of them;
    NaN when every cell ran at one budget."""
    if "max_evals" not in frame or \
            not frame.groupby(list(CELL_KEYS[:-1]))["max_evals"].nunique().gt(1).any():
        return float("nan")
    good = _converged(frame)
    good = good.assign(family=np.where(good["param"] == "diagonal", "diagonal", "full"))
    smallest = good.groupby(list(CELL_KEYS[:-1]))["max_evals"].transform("min")
    keys = ["problem", "case", "family"]
    every = good.groupby(keys)["best_cost"].min()
    first = good[good["max_evals"] == smallest].groupby(keys)["best_cost"].min()
    return float((100.0 * (first - every) / every.abs()).max())


def holdout_by_budget(frame: pd.DataFrame, alpha: float = 0.05) -> pd.DataFrame:
    """The held-out verdict had the study stopped at each budget its full cells ran at.

    For each problem × case × problem variant whose full-map records ran at more than one
    budget, and each such budget b: the best-known full start among the full records at
    budgets up to b (every optimizer) against the best-known diagonal start (every
    record), paired over the held-out scenarios as the best-known row of the results
    pages: full cheaper on k of n, the median of J_full / J_diag, the two-sided Wilcoxon
    signed-rank test of the log ratios with Holm's correction over the rows of this table,
    and the verdict at ``alpha`` ("full cheaper", "diagonal cheaper" or "no evidence of a
    difference"). Empty (:data:`HOLDOUT_BY_BUDGET_COLUMNS`) where no full map ran at two
    budgets or the records carry no held-out data.
    """
    from penaltyrun.report import protocol
    from penaltyrun.report.bestknown import best_rows
    from penaltyrun.report.holdout import ratio_stats, scenario_table
    from penaltyrun.report.stats import add_variant, holm

    rows = []
    if "max_evals" in frame and "holdout" in frame:
        frame = add_variant(frame[frame["holdout"].notna()])
        for (problem, case, variant), g in frame.groupby(
                ["problem", "case", "problem_variant"], sort=True):
            full = g[g["param"] != "diagonal"]
            budgets_run = sorted(full["max_evals"].dropna().unique())
            diagonal = best_rows(g[g["param"] == "diagonal"]).get("diagonal")
            if len(budgets_run) < 2 or diagonal is None:
                continue
            drop = protocol.info_of(g).discretization_kinds
            dtab = scenario_table(diagonal["holdout"], drop)
            for budget in budgets_run:
                best = best_rows(full[full["max_evals"] <= budget]).get("full")
                ftab = None if best is None else scenario_table(best["holdout"], drop)
                if dtab is None or ftab is None:
                    continue
                common = dtab.index.intersection(ftab.index)
                stats = ratio_stats(dtab.loc[common, "cost"].to_numpy(float),
                                    ftab.loc[common, "cost"].to_numpy(float))
                rows.append({"problem": problem, "case": case, "variant": variant,
                             "full records up to": f"{budget:.0f}",
                             "full cost": float(best["best_cost"]),
                             "scenarios": len(common),
                             "full cheaper": f"{stats['full_cheaper']}/{len(common)}",
                             "median J_full/J_diag": stats["ratio_median"],
                             "Holm p": stats["ratio_p"]})
    table = pd.DataFrame(rows, columns=HOLDOUT_BY_BUDGET_COLUMNS)
    if not table.empty:
        table["Holm p"] = holm(table["Holm p"].to_numpy(float))
        table["verdict"] = [
            "no evidence of a difference" if not p < alpha
            else ("full cheaper" if ratio < 1 else "diagonal cheaper")
            for p, ratio in zip(table["Holm p"], table["median J_full/J_diag"])]
    return table


def verdict_stability(table: pd.DataFrame) -> tuple[int, int]:
    """(cases whose verdict is the same at every budget, cases) of a
    :func:`holdout_by_budget` table, a case being one problem × case × variant."""
    if table.empty:
        return 0, 0
    verdicts = table.groupby(["problem", "case", "variant"], sort=True)["verdict"].nunique()
    return int((verdicts == 1).sum()), int(len(verdicts))


def _converged(frame: pd.DataFrame) -> pd.DataFrame:
    """The finished starts of ``frame`` that converged."""
    return frame[(frame["status"] == OK) & frame["best_converged"].astype(bool)]


__all__ = ["BUDGET_CHECK_COLUMNS", "BUDGET_CHECK_MAIN", "CELL_KEYS",
           "HOLDOUT_BY_BUDGET_COLUMNS", "at_largest_budget", "budget_check", "budget_effect",
           "budgets", "cells", "holdout_by_budget", "largest_late_gain",
           "late_gain", "rows_of", "search_window", "verdict_stability"]
