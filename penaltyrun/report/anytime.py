"""Anytime views from the per-start traces (best-so-far cost vs cumulative evaluations).

A trace is the pair (``trace_evals``, ``trace_best``): after ``trace_evals[k]`` evaluations
the best cost so far was ``trace_best[k]``; best-so-far(n) is the step function through
these points (undefined before the first evaluation, constant after the start stopped).
Targets are f_t = f* + ε·|f*| with f* the best-known cost of the cell's map family
(:mod:`penaltyrun.report.bestknown`), ε ∈ :data:`EPSILONS`. Results without traces
(schema version 2) are skipped here.
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.report.bestknown import family, reference, with_problem_variant
from penaltyrun.report.rows import TRACE_COLUMNS, batches, groups, has, narrow

EPSILONS = (1e-2, 1e-3)
#: Most best-so-far values (starts × grid points) :func:`anytime_band` holds at once; the
#: quantiles of each grid point are the same in batches of grid points.
BAND_VALUES = 4_000_000
CELL = ["problem", "case", "problem_variant", "variant", "optimizer", "param"]


def trace_of(row: pd.Series | dict) -> tuple[np.ndarray, np.ndarray] | None:
    """(evaluations, best-so-far) of a job row, or None when it has no trace."""
    evals, best = row.get("trace_evals"), row.get("trace_best")
    if evals is None or best is None or len(evals) == 0 or len(evals) != len(best):
        return None
    return np.asarray(evals, float), np.asarray(best, float)


def best_so_far(evals: np.ndarray, best: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Best-so-far cost at each evaluation count of ``grid`` (NaN before the first point)."""
    idx = np.searchsorted(evals, grid, side="right") - 1
    out = np.where(idx >= 0, best[np.clip(idx, 0, None)], np.nan)
    return out.astype(float)


def hitting_evals(evals: np.ndarray, best: np.ndarray, target: float) -> float:
    """First evaluation count at which best-so-far ≤ ``target`` (``inf`` if never)."""
    hit = np.flatnonzero(best <= target)
    return float(evals[hit[0]]) if hit.size else float("inf")


def ecdf(hits: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Share of starts whose hitting evaluation count is ≤ n, for each n of ``grid``."""
    hits = np.asarray(hits, float)
    if hits.size == 0:
        return np.full(np.shape(grid), np.nan)
    return np.searchsorted(np.sort(hits), np.asarray(grid, float), side="right") / hits.size


def ert(hits: np.ndarray, spent: np.ndarray) -> float:
    """Expected running time (COCO): Σ evaluations until the target or the stop / successes.

    Parameters
    ----------
    hits : ndarray, shape (n,)
        Hitting evaluation count per start (``inf``: never reached).
    spent : ndarray, shape (n,)
        Evaluations each start spent in total.
    """
    hits, spent = np.asarray(hits, float), np.asarray(spent, float)
    success = np.isfinite(hits)
    if not success.any():
        return float("inf")
    return float(np.where(success, hits, spent).sum() / success.sum())


def cell_traces(g: pd.DataFrame) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """(evals, best, evaluations spent) of each non-failed start of a cell with a trace
    (the traces of a lazily read frame read for these rows only, a batch at a time)."""
    ran = g[~g["status"].isin(NO_RESULT_STATUSES)]
    if ran.empty or not all(has(ran, c) for c in TRACE_COLUMNS):
        return []
    out = []
    for part in batches(narrow(ran, ["n_evals", *TRACE_COLUMNS]), TRACE_COLUMNS):
        spent_all = part["n_evals"] if "n_evals" in part else [None] * len(part)
        for evals, best, spent in zip(part["trace_evals"], part["trace_best"], spent_all):
            tr = trace_of({"trace_evals": evals, "trace_best": best})
            if tr is not None:
                spent = float(spent) if spent is not None and np.isfinite(spent) \
                    else tr[0][-1]
                out.append((tr[0], tr[1], spent))
    return out


def target_table(df: pd.DataFrame, bk: pd.DataFrame,
                 epsilons: tuple[float, ...] = EPSILONS) -> pd.DataFrame:
    """ERT and success share per cell and target (cells without traces are left out).

    Columns: the cell, ``epsilon``, ``target``, ``n_starts`` (non-failed starts with a
    trace), ``n_reached``, ``share_reached``, ``ert_evals`` (``inf`` if none reached) and
    ``median_evals_to_target`` over the starts that reached it.
    """
    df = narrow(with_problem_variant(df), [*CELL, "status", "n_evals", *TRACE_COLUMNS])
    rows = []
    for key, g in groups(df[df["optimizer"] != "baseline"], CELL):
        traces = cell_traces(g)
        ref = reference(bk, key[0], key[1], key[2], family(key[5]))
        if not traces or not np.isfinite(ref):
            continue
        spent = np.array([t[2] for t in traces])
        for eps in epsilons:
            target = ref + eps * abs(ref)
            hits = np.array([hitting_evals(e, b, target) for e, b, _ in traces])
            reached = hits[np.isfinite(hits)]
            rows.append({**dict(zip(CELL, key)), "epsilon": eps, "target": target,
                         "n_starts": len(traces), "n_reached": int(reached.size),
                         "share_reached": reached.size / len(traces),
                         "ert_evals": ert(hits, spent),
                         "median_evals_to_target": float(np.median(reached))
                         if reached.size else np.nan})
    return pd.DataFrame(rows)


def anytime_band(traces: list[tuple[np.ndarray, np.ndarray, float]], grid: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Median, 25 % and 75 % quantiles of best-so-far over starts at each grid point.

    A start that stopped keeps its final best; before a start's first evaluation it does
    not count (NaN, ignored by the quantiles).
    """
    if not traces:
        nan = np.full(np.shape(grid), np.nan)
        return nan, nan, nan
    grid = np.asarray(grid)
    q = np.empty((3, grid.size))
    step = max(1, BAND_VALUES // len(traces))  # grid points per batch: bounded memory
    for j in range(0, grid.size, step):
        values = np.array([best_so_far(e, b, grid[j:j + step]) for e, b, _ in traces])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns stay NaN
            q[:, j:j + step] = np.nanquantile(values, [0.5, 0.25, 0.75], axis=0)
    return q[0], q[1], q[2]
