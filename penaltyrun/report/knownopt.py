"""Time to a known optimum: evaluations and CPU seconds until a start comes within a
relative tolerance of the problem's own optimum J*.

Some problems know their global optimum independently of any search: ``problem=lqr``
without input limits or nonlinear dynamics records J* (the cost of the LQR of the
performance weights, infinite horizon) as ``metrics.optimum``. For those cells this table
says, per cell, how many starts reached J* within :data:`RTOL` (relative: best-so-far ≤
J* + RTOL·|J*|), after how many evaluations and how many CPU seconds (the first point of
the anytime trace at or below the target: ``trace_evals`` and ``trace_cpu_s``), and what a
start spent in all. A cell whose starts never reached J* carries the evaluations and CPU
seconds they spent without reaching it: a lower bound for its time to reach.

Unlike the fixed-target table (:mod:`penaltyrun.report.anytime`), the reference is not the
best cost found by any search but the known optimum, so a map that cannot reach it (the
diagonal, when the optimum is a non-diagonal matrix) is reported as not reaching it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.io.schema import decode_json
from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.report.anytime import CELL
from penaltyrun.report.bestknown import with_problem_variant
from penaltyrun.report.rows import TRACE_COLUMNS, batches, full_row, groups, has

#: Relative tolerance of "reached the known optimum".
RTOL = 1e-6
#: Per-row columns the table reads for every start (a lazily read frame reads them one cell
#: at a time); the matrices only for a cell's first row (its size).
ROW_COLUMNS_USED = ("metrics", "best_z", *TRACE_COLUMNS, "trace_cpu_s")
#: Evaluation methods whose cost the known optimum bounds from below (up to the horizon):
#: the closed-form continuous loop and the stepped discrete loop of a linear plant without
#: input limits (``problem=lqr``).
EXACT_METHODS = ("closed_form", "stepped")
#: Problem parameters that make J* of the linear model no longer the optimum.
NOT_EXACT_PARAMS = ("u_max", "dynamics")
#: Columns of the Markdown copy of the ratio table.
RATIO_COLUMNS = ["param", "size", "optimizer_a", "optimizer_b", "reached_a", "reached_b",
                 "cpu_s_a", "cpu_s_b", "relation", "cpu_ratio"]
#: Columns of the Markdown copy (the CSV has every column, the cell's labels among them).
COLUMNS = ["optimizer", "param", "size", "dim", "n_reached", "evals_to_reach_median",
           "cpu_s_to_reach_median", "cpu_s_spent_min", "gap_median", "max_evals"]


def known_optimum(row: pd.Series) -> float:
    """The row's known optimum J* (NaN when its problem declares none, or when J* is not
    the optimum of its evaluation: input limits, nonlinear dynamics)."""
    metrics = decode_json(row.get("metrics"))
    if not isinstance(metrics, dict) or metrics.get("method") not in EXACT_METHODS:
        return float("nan")
    params = decode_json(row.get("problem_params"))
    if isinstance(params, dict) and any(params.get(k) is not None for k in NOT_EXACT_PARAMS):
        return float("nan")
    value = metrics.get("optimum")
    return float(value) if isinstance(value, (int, float)) else float("nan")


def first_reach(row: pd.Series, target: float) -> tuple[float, float]:
    """(evaluations, CPU seconds) at the first trace point with best-so-far ≤ ``target``;
    ``inf`` when the start never reached it; the CPU seconds are NaN for a record without
    ``trace_cpu_s`` (schema version 7 and older)."""
    evals, best = row.get("trace_evals"), row.get("trace_best")
    if evals is None or best is None or len(evals) == 0:
        return float("inf"), float("inf")
    hit = np.flatnonzero(np.asarray(best, float) <= target)
    if not hit.size:
        return float("inf"), float("inf")
    cpu = row.get("trace_cpu_s")
    k = int(hit[0])
    seconds = float(cpu[k]) if cpu is not None and len(cpu) == len(evals) else float("nan")
    return float(evals[k]), seconds


def spent_cpu(row: pd.Series) -> float:
    """CPU seconds of the whole search (the last trace point; NaN without a CPU trace)."""
    cpu = row.get("trace_cpu_s")
    return float(cpu[-1]) if cpu is not None and len(cpu) else float("nan")


def _size(row: pd.Series) -> int:
    """Side of the first tuned matrix (problem=lqr: Q, the plant's states)."""
    mats = decode_json(row.get("matrices"))
    if not isinstance(mats, dict) or not mats:
        return 0
    return int(np.asarray(next(iter(mats.values())), float).shape[0])


def _stats(values: np.ndarray, name: str) -> dict[str, float]:
    if not values.size:
        return {f"{name}_median": np.nan, f"{name}_min": np.nan, f"{name}_max": np.nan}
    return {f"{name}_median": float(np.median(values)), f"{name}_min": float(values.min()),
            f"{name}_max": float(values.max())}


def _median_all(hit: np.ndarray, spent: np.ndarray, name: str) -> dict[str, Any]:
    """Median over every start of the time to reach (a start that never reached counts as
    +inf): ``<name>_all_median`` and ``<name>_all_bound`` — False when more than half of the
    starts reached (the median is exact), True otherwise: then the median of each start's
    time to reach, or what it spent when it never reached, is a lower bound of it."""
    finite = np.isfinite(hit)
    exact = 2 * int(finite.sum()) > hit.size
    values = np.where(finite, hit, np.inf if exact else spent)
    return {f"{name}_all_median": float(np.median(values)) if hit.size else np.nan,
            f"{name}_all_bound": not exact}


def _read_cell(g: pd.DataFrame, ref: float, target: float
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """Per start of the cell ``g``, in its row order, (evaluations, CPU seconds) to reach
    ``target`` (rows of :func:`first_reach`) and the CPU seconds it spent; None when the
    cell's starts do not share one known optimum (the first start's is ``ref``). A lazily
    read frame's per-row columns are read a batch of rows at a time
    (:func:`~penaltyrun.report.rows.batches`)."""
    hits, low, high = {}, ref, ref
    for part in batches(g, ROW_COLUMNS_USED):
        for label, row in part.iterrows():
            optimum = known_optimum(row)
            if not np.isfinite(optimum):
                return None
            low, high = min(low, optimum), max(high, optimum)
            hits[label] = (*first_reach(row, target), spent_cpu(row))
    if high - low > 1e-12 * abs(ref):
        return None
    table = np.array([hits[label] for label in g.index], float).reshape(-1, 3)
    return table[:, :2], table[:, 2]


def reach_table(df: pd.DataFrame, rtol: float = RTOL) -> pd.DataFrame:
    """One row per cell whose records carry a known optimum.

    Columns: the cell (:data:`~penaltyrun.report.anytime.CELL`), ``size`` (side of the
    first tuned matrix), ``dim`` (decision variables), ``optimum`` (J*), ``rtol``,
    ``target``, ``n_starts`` (non-failed starts), ``n_reached``, per reaching start the
    evaluations and CPU seconds to reach (``evals_to_reach_*``, ``cpu_s_to_reach_*``:
    median, min, max), the median over every start (``cpu_s_all_median``,
    ``evals_all_median``; with ``*_all_bound`` true, when at most half of the starts
    reached, a lower bound: the starts that never reached count with what they spent), per
    start what it spent (``evals_spent_median``,
    ``cpu_s_spent_median``, ``cpu_s_spent_min``: the least CPU any start spent, so a cell
    that never reached J* did not reach it within that much CPU), the relative gap of the
    final best (``gap_median``, ``gap_min``: best/J* − 1) and the budget ``max_evals``.
    """
    if df.empty or not has(df, "metrics"):
        return pd.DataFrame()
    df = with_problem_variant(df)
    df = df[(df["optimizer"] != "baseline") & ~df["status"].isin(NO_RESULT_STATUSES)]
    rows = []
    for key, g in groups(df, CELL):
        first = full_row(g, g.index[0])  # one row: a cell without J* reads no more
        ref = known_optimum(first)
        if not np.isfinite(ref):
            continue
        target = ref + rtol * abs(ref)
        read = _read_cell(g, ref, target)
        if read is None:
            continue
        hits, spent_s = read
        reached = np.isfinite(hits[:, 0])
        gaps = g["best_cost"].astype(float).to_numpy() / ref - 1.0
        budget = g["max_evals"].dropna() if "max_evals" in g else pd.Series(dtype=float)
        rows.append({
            **dict(zip(CELL, key)), "size": _size(first),
            "dim": len(first["best_z"]), "optimum": ref, "rtol": rtol, "target": target,
            "n_starts": len(g), "n_reached": int(reached.sum()),
            **_stats(hits[reached, 0], "evals_to_reach"),
            **_stats(hits[reached, 1], "cpu_s_to_reach"),
            **_median_all(hits[:, 1], spent_s, "cpu_s"),
            **_median_all(hits[:, 0], g["n_evals"].astype(float).to_numpy(), "evals"),
            "evals_spent_median": float(g["n_evals"].astype(float).median()),
            "cpu_s_spent_median": float(np.median(spent_s)),
            "cpu_s_spent_min": float(np.min(spent_s)),
            "gap_median": float(np.median(gaps)), "gap_min": float(np.min(gaps)),
            "max_evals": float(budget.iloc[0]) if len(budget) else np.nan})
    if not rows:
        return pd.DataFrame()
    return pd.DataFrame(rows).sort_values(["problem", "case", "size", "problem_variant",
                                           "param", "optimizer", "variant"],
                                          kind="stable").reset_index(drop=True)


def ratio_relation(a: pd.Series, b: pd.Series) -> str:
    """What the CPU ratio a / b of two :func:`reach_table` rows is: ``=`` (both medians
    exact), ``>`` (a's a lower bound: the ratio is a lower bound), ``<`` (b's a lower
    bound: the ratio is an upper bound), or empty (both bounds, a median missing or b's
    zero: no ratio)."""
    ta, tb = float(a["cpu_s_all_median"]), float(b["cpu_s_all_median"])
    bound_a, bound_b = bool(a["cpu_s_all_bound"]), bool(b["cpu_s_all_bound"])
    if not (np.isfinite(ta) and np.isfinite(tb) and tb > 0) or (bound_a and bound_b):
        return ""
    return ">" if bound_a else ("<" if bound_b else "=")


def ratio_table(reach: pd.DataFrame) -> pd.DataFrame:
    """CPU ratios of the time to reach J* between every two optimizers of the same problem,
    case, problem variant and map (rows of :func:`reach_table`; the optimizers' own
    budgets and settings, part of ``variant``, differ by design and are kept as
    ``variant_a``, ``variant_b``).

    ``cpu_s_a`` / ``cpu_s_b`` are the medians over every start (``cpu_s_all_median``);
    ``cpu_ratio`` is a / b and ``relation`` says what it is (:func:`ratio_relation`):
    ``=`` when both medians are exact, ``>`` when a's is a lower bound and b's exact (a
    needs more than ``cpu_ratio`` times b's CPU), ``<`` when a's is exact and b's a lower
    bound (a needs less than ``cpu_ratio`` times b's CPU: b did not reach J* in most
    starts, its starts count with the CPU they spent), and empty when both are bounds (no
    ratio follows; ``cpu_ratio`` NaN).
    """
    if reach.empty:
        return pd.DataFrame()
    rows = []
    keys = ["problem", "case", "problem_variant", "param"]
    for key, g in reach.groupby(keys, sort=True):
        g = g.sort_values("optimizer")
        for _, a in g.iterrows():
            for _, b in g.iterrows():
                if a["optimizer"] == b["optimizer"]:
                    continue
                relation = ratio_relation(a, b)
                rows.append({
                    **dict(zip(keys, key)), "size": a["size"], "dim": a["dim"],
                    "optimizer_a": a["optimizer"], "optimizer_b": b["optimizer"],
                    "variant_a": a["variant"], "variant_b": b["variant"],
                    "reached_a": f"{a['n_reached']} of {a['n_starts']}",
                    "reached_b": f"{b['n_reached']} of {b['n_starts']}",
                    "cpu_s_a": a["cpu_s_all_median"], "cpu_s_b": b["cpu_s_all_median"],
                    "evals_a": a["evals_all_median"], "evals_b": b["evals_all_median"],
                    "relation": relation,
                    "cpu_ratio": a["cpu_s_all_median"] / b["cpu_s_all_median"]
                    if relation else np.nan})
    if not rows:
        return pd.DataFrame()
    return pd.DataFrame(rows).sort_values(["problem", "case", "size", "problem_variant",
                                           "param", "optimizer_a", "optimizer_b"],
                                          kind="stable").reset_index(drop=True)


__all__ = ["COLUMNS", "RATIO_COLUMNS", "RTOL", "first_reach", "known_optimum",
           "ratio_relation", "ratio_table", "reach_table", "spent_cpu"]
