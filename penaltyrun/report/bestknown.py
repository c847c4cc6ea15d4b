"""Best-known optima per problem × case × problem variant and map family, their
certification, and each optimizer's shortfall against them.

A map family is ``diagonal`` or ``full`` (every orthogonal map — full/geagsp, givens,
cayley, cayley_tan — spans the same set of positive-definite matrices). Best-known values are taken
over every converged start of every optimizer, budget and warm-start variant that solved
the same problem (equal ``problem_variant``); the baseline (K = I) is not a search and does
not enter. Evidence for a best-known value (:data:`LEVELS`): *certified* when the grid
optimizer (exhaustive grid + local search) reached it within :data:`CERTIFY_RTOL` relative;
*agreement (k optimizers; reached by m of n starts)* when k ≥ 2 different optimizers did;
otherwise *first-order certified local optimum* when the best start's projected gradient
(``grad_norm`` of its record: the problem's exact gradient, a problem with a gradient only)
is at most :data:`FIRST_ORDER_RTOL` × max(1, |cost|), else *single optimizer (reached by m
of n starts)*: m of the cell's n starts (every optimizer, converged or not) came within the
tolerance. A first-order certificate says the value is a stationary point of the box (a
local optimum for a convex neighbourhood), not that it is the global one; beside the
*certified* and *agreement* levels the evidence text names it too.
"""

from __future__ import annotations

import json
from collections.abc import Hashable

import numpy as np
import pandas as pd

from penaltyrun.io import decode_json
from penaltyrun.report.rows import full_row, groups, narrow
from penaltyrun.report.stats import converged

#: Relative tolerance within which two optimizers "agree" on a best-known value.
CERTIFY_RTOL = 1e-4
KEY = ["problem", "case", "problem_variant"]
#: Evidence levels, strongest first.
LEVELS = ("certified", "agreement", "first-order certified local optimum", "single optimizer")
#: Projected-gradient norm, relative to max(1, |cost|), below which the best start is a
#: first-order certified local optimum (the cost unit per unit of the decision variables).
FIRST_ORDER_RTOL = 1e-6
#: Optimizer whose best is exhaustive (grid + local search).
EXHAUSTIVE = "grid"
FAMILIES = ("diagonal", "full")


def family(param: str) -> str:
    """Map family of a parameterization: ``diagonal`` or ``full``."""
    return "diagonal" if param == "diagonal" else "full"


def with_problem_variant(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with a ``problem_variant`` column (``variant`` or ``""`` when absent)."""
    if "problem_variant" in df:
        return df
    return df.assign(problem_variant=df["variant"] if "variant" in df else "")


def within(value: float, ref: float, rtol: float = CERTIFY_RTOL) -> bool:
    """True when ``value`` is at most ``ref + rtol·|ref|`` (reaches ``ref`` to ``rtol``)."""
    return bool(value <= ref + rtol * abs(ref))


def _matrices_text(matrices_json: str | None) -> str:
    mats = decode_json(matrices_json) or {}
    return json.dumps({k: np.round(np.asarray(v, float), 6).tolist() for k, v in mats.items()})


def best_known(df: pd.DataFrame) -> pd.DataFrame:
    """One row per problem × case × problem variant × map family with a converged start.

    Columns: ``best_known``, the ``optimizer``, ``param`` and ``job_id`` that found it, its
    ``matrices`` (JSON, 6 decimals), ``certified`` and ``certified_by`` (the optimizers
    whose best is within :data:`CERTIFY_RTOL`), and per-optimizer bests (``best_<opt>``).
    """
    whole = with_problem_variant(df)  # the best starts' other columns are read from it
    df = narrow(whole, [*KEY, "param", "optimizer", "status", "best_converged", "best_cost"])
    tuned = (df["optimizer"] != "baseline").to_numpy()
    fam = df["param"].map(family).rename("family")
    n_starts = fam[tuned].groupby([df[k][tuned] for k in KEY] + [fam[tuned]]).size()
    ok = df[converged(df).to_numpy() & tuned].assign(family=fam)
    rows = []
    for key, g in groups(ok, [*KEY, "family"]):
        top = full_row(whole, g["best_cost"].astype(float).idxmin())
        ref = float(top["best_cost"])
        per_opt = g.groupby("optimizer")["best_cost"].min().astype(float)
        agree = [o for o, v in per_opt.items() if within(v, ref)]
        n_at = int(sum(within(float(v), ref) for v in g["best_cost"].astype(float)))
        level, evidence = _evidence(agree, n_at, int(n_starts.loc[key]),
                                    first_order(top.get("grad_norm"), ref))
        certified = level == "certified"
        rows.append({
            **dict(zip(KEY + ["family"], key)), "best_known": ref,
            "optimizer": top["optimizer"], "param": top["param"], "job_id": top["job_id"],
            "certified": certified, "level": level, "evidence": evidence,
            "certified_by": (", ".join(agree) + f" (within {CERTIFY_RTOL:g} rel.)")
            if level != "single optimizer" else "—", "n_at_best": n_at,
            "n_converged": len(g),
            **{f"best_{o}": v for o, v in per_opt.items()},
            "matrices": _matrices_text(top["matrices"]),
        })
    return pd.DataFrame(rows)


def first_order(grad_norm: object, cost: float) -> bool:
    """Whether a start's projected-gradient norm certifies a first-order stationary point
    (≤ :data:`FIRST_ORDER_RTOL` × max(1, |cost|); missing or NaN: no)."""
    try:
        norm = float(grad_norm)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return False
    return bool(np.isfinite(norm) and norm <= FIRST_ORDER_RTOL * max(1.0, abs(cost)))


def _evidence(agree: list[str], n_at: int, n_starts: int, stationary: bool = False
              ) -> tuple[str, str]:
    """(level, text) of a best-known value reached by the optimizers ``agree`` (``n_at`` of
    the cell's ``n_starts`` starts, every optimizer, within :data:`CERTIFY_RTOL`);
    ``stationary``: the best start is a first-order certified local optimum."""
    also = "; first-order certified" if stationary else ""
    if EXHAUSTIVE in agree:
        return "certified", f"certified (grid + local search{also})"
    reached = f"reached by {n_at} of {n_starts} starts"
    if len(agree) >= 2:
        return "agreement", f"agreement ({len(agree)} optimizers; {reached}{also})"
    if stationary:
        return (LEVELS[2], f"first-order certified local optimum ({agree[0]}; projected "
                           f"gradient ≤ {FIRST_ORDER_RTOL:g}·max(1, |cost|); {reached})")
    return "single optimizer", f"single optimizer ({agree[0]}; {reached})"


def best_rows(df: pd.DataFrame) -> dict[str, pd.Series]:
    """The converged start with the lowest cost of each map family, over every optimizer
    (the baseline excluded): ``{"diagonal": row, "full": row}`` where present (the first
    such row of ``df`` where costs tie)."""
    return {fam: full_row(df, label) for fam, label in best_labels(df).get((), {}).items()}


def best_labels(df: pd.DataFrame, keys: tuple[str, ...] = ()
                ) -> dict[tuple, dict[str, Hashable]]:
    """The index labels of :func:`best_rows` of each group of ``df`` by the columns ``keys``
    (groups in sorted order, rows with a missing key left out; ``()``: the whole of
    ``df``, under the key ``()``), from the columns they are chosen by alone: no copy of
    the rows of ``df`` is made, whatever its size.

    Returns
    -------
    dict
        ``{group key: {family: label}}``, the families in sorted order; a group without a
        converged start is absent.
    """
    cost = df["best_cost"].astype(float)
    keep = (converged(df) & (df["optimizer"] != "baseline") & cost.notna()).to_numpy()
    # the keys as stored (categories of a lazily read frame stay codes, no text a row)
    chosen = pd.DataFrame({**{k: df[k].array[keep] for k in keys},
                           "family": df["param"][keep].map(family).to_numpy(),
                           "cost": cost.to_numpy()[keep]}, index=df.index[keep])
    out: dict[tuple, dict[str, Hashable]] = {}
    if chosen.empty:
        return out
    for key, label in chosen.groupby([*keys, "family"], sort=True)["cost"].idxmin().items():
        key = key if isinstance(key, tuple) else (key,)
        out.setdefault(tuple(key[:-1]), {})[str(key[-1])] = label
    return out


def reference(bk: pd.DataFrame, problem: str, case: str, problem_variant: str,
              fam: str) -> float:
    """Best-known cost of one family (NaN if none)."""
    if bk.empty:
        return float("nan")
    sel = bk[(bk["problem"] == problem) & (bk["case"] == case)
             & (bk["problem_variant"] == problem_variant) & (bk["family"] == fam)]
    return float(sel["best_known"].iloc[0]) if len(sel) else float("nan")


def shortfall(df: pd.DataFrame, bk: pd.DataFrame) -> pd.DataFrame:
    """Each cell's distance to its family's best-known value (converged starts only).

    ``gap_best_pct`` and ``gap_median_pct`` = (cell best or median − best-known) /
    best-known · 100. For a diagonal cell this gap is the optimizer's failure to reach the
    diagonal optimum, not a gain of any full map.
    """
    df = with_problem_variant(df)
    ok_mask = converged(df)
    rows = []
    cell = ["problem", "case", "problem_variant", "variant", "optimizer", "param"]
    for key, g in groups(df[df["optimizer"] != "baseline"], cell):
        cost = g.loc[ok_mask[g.index], "best_cost"].astype(float).to_numpy()
        ref = reference(bk, key[0], key[1], key[2], family(key[5]))
        best = float(cost.min()) if cost.size else np.nan
        med = float(np.median(cost)) if cost.size else np.nan
        rows.append({**dict(zip(cell, key)), "n_jobs": len(g), "n_converged": int(cost.size),
                     "best_known": ref, "best": best, "median": med,
                     "gap_best_pct": 100.0 * (best - ref) / abs(ref),
                     "gap_median_pct": 100.0 * (med - ref) / abs(ref),
                     "reached_best_known": bool(cost.size and within(best, ref))})
    return pd.DataFrame(rows)
