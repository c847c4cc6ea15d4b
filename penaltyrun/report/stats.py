"""Per-cell statistics and diagonal-vs-full comparisons from a results DataFrame."""

from __future__ import annotations

import json
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from penaltyrun.io import decode_json
from penaltyrun.report.paper import FULL_KINDS, paper_mean

CELL = ["problem", "case", "variant", "optimizer", "param"]


def add_variant(df: pd.DataFrame) -> pd.DataFrame:
    """Add a ``variant`` column: the problem parameters that differ from the case's defaults
    (e.g. ``objective=min_fuel``), so that cells run with other settings are not pooled."""
    from dataclasses import asdict

    from penaltyrun import problems

    labels: dict[tuple[str, str, str], str] = {}
    for key in df[["problem", "case", "problem_params"]].drop_duplicates().itertuples(
            index=False):
        problem, case, params = key
        try:
            ignore = getattr(problems.module(problem), "VARIANT_IGNORE", ())
            default = asdict(problems.make(problem, case, {}).params)
            used = asdict(problems.make(problem, case, decode_json(params) or {}).params)
            diff = [f"{k}={used[k]}" for k in sorted(used)
                    if used[k] != default[k] and k not in ignore]
            labels[key] = ",".join(diff)
        except Exception as exc:  # an unknown problem in old results still gets reported
            labels[key] = f"unresolved ({type(exc).__name__})"
    out = df.copy()
    out["variant"] = [labels[k] for k in zip(df["problem"], df["case"], df["problem_params"])]
    return _add_budget_variant(out)


def _canonical(settings_json: Any) -> str:
    """Optimizer settings as JSON with sorted keys (equal settings, equal strings)."""
    return json.dumps(decode_json(settings_json) or {}, sort_keys=True)


def _add_budget_variant(df: pd.DataFrame) -> pd.DataFrame:
    """Split cells whose jobs ran with different optimizer settings.

    Within one (problem, case, variant, optimizer), the settings used by most jobs keep the
    variant as it is; every other settings set gets its differences appended, e.g.
    ``iters=300,n_particles=100``, so a small-budget side study is never pooled into a
    main cell (nor the other way round).
    """
    if "optimizer_settings" not in df or df.empty:
        return df
    settings = df["optimizer_settings"].map(_canonical)
    suffix = pd.Series("", index=df.index)
    for _, g in settings.groupby([df["problem"], df["case"], df["variant"], df["optimizer"]]):
        counts = g.value_counts()
        if len(counts) < 2:
            continue
        main = max(counts.index, key=lambda k: (counts[k], k))
        reference = json.loads(main)
        for key in counts.index.drop(main):
            used = json.loads(key)
            diff = [f"{k}={used.get(k)}" for k in sorted(set(used) | set(reference))
                    if used.get(k) != reference.get(k)]
            suffix[g.index[g == key]] = ",".join(diff)
    out = df.copy()
    out["variant"] = [",".join(part for part in (v, b) if part)
                      for v, b in zip(df["variant"], suffix)]
    return out


def bootstrap_ci(values: np.ndarray, level: float = 0.95, n_boot: int = 2000,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean (NaN for < 2 values)."""
    values = np.asarray(values, float)
    if values.size < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    means = rng.choice(values, size=(n_boot, values.size), replace=True).mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def cell_summary(df: pd.DataFrame) -> pd.DataFrame:
    """One row per (problem, case, optimizer, param): cost statistics and success rate.

    Costs of failed jobs (no cost) are excluded from the statistics but counted in
    ``n_jobs``; ``success_rate`` is the share of jobs whose best candidate converged.
    """
    if "variant" not in df:
        df = df.assign(variant="")
    rows = []
    for key, g in df.groupby(CELL, sort=True):
        cost = g.loc[g["status"] != "failed", "best_cost"].astype(float).to_numpy()
        lo, hi = bootstrap_ci(cost)
        rows.append({
            **dict(zip(CELL, key)),
            "n_jobs": len(g),
            "n_failed": int((g["status"] == "failed").sum()),
            "success_rate": float((g["status"] == "ok").mean()),
            "best": float(np.min(cost)) if cost.size else np.nan,
            "median": float(np.median(cost)) if cost.size else np.nan,
            "mean": float(np.mean(cost)) if cost.size else np.nan,
            "worst": float(np.max(cost)) if cost.size else np.nan,
            "std": float(np.std(cost, ddof=1)) if cost.size > 1 else np.nan,
            "mean_ci95_lo": lo,
            "mean_ci95_hi": hi,
            "mean_evals": float(g["n_evals"].mean()),
            "mean_wall_s": float(g["wall_time_s"].mean()),
            "paper_mean": paper_mean(key[0], key[1], key[CELL.index("param")]),
        })
    return pd.DataFrame(rows)


def comparison(df: pd.DataFrame) -> pd.DataFrame:
    """Diagonal vs each full map per (problem, case, optimizer).

    Improvement is (diagonal − full) / diagonal in % (positive: full is better), for the
    means and for the bests. ``p_value`` is the one-sided Mann–Whitney U test that full
    costs are stochastically smaller than diagonal costs.
    """
    if "variant" not in df:
        df = df.assign(variant="")
    summary = cell_summary(df)
    rows = []
    for key, g in summary.groupby(["problem", "case", "variant", "optimizer"], sort=True):
        diag = g[g["param"] == "diagonal"]
        if diag.empty:
            continue
        d = diag.iloc[0]
        dcost = _costs(df, *key, "diagonal")
        for _, f in g[g["param"].isin(FULL_KINDS)].iterrows():
            fcost = _costs(df, *key, f["param"])
            p = np.nan
            if dcost.size and fcost.size:
                p = float(stats.mannwhitneyu(fcost, dcost, alternative="less").pvalue)
            rows.append({
                "problem": key[0], "case": key[1], "variant": key[2], "optimizer": key[3],
                "full_map": f["param"],
                "n_diagonal": int(d["n_jobs"]), "n_full": int(f["n_jobs"]),
                "diag_best": d["best"], "full_best": f["best"],
                "diag_mean": d["mean"], "full_mean": f["mean"],
                "diag_median": d["median"], "full_median": f["median"],
                "diag_worst": d["worst"], "full_worst": f["worst"],
                "diag_std": d["std"], "full_std": f["std"],
                "diag_success": d["success_rate"], "full_success": f["success_rate"],
                "improvement_mean_pct": 100.0 * (d["mean"] - f["mean"]) / d["mean"],
                "improvement_best_pct": 100.0 * (d["best"] - f["best"]) / d["best"],
                "p_value_mwu": p,
                "paper_diag_mean": d["paper_mean"], "paper_full_mean": f["paper_mean"],
                "paper_improvement_mean_pct": 100.0 * (d["paper_mean"] - f["paper_mean"])
                / d["paper_mean"],
                "full_worse_on_best": bool(f["best"] > d["best"] * (1 + 1e-9)),
            })
    return pd.DataFrame(rows)


def _costs(df: pd.DataFrame, problem: str, case: str, variant: str, optimizer: str,
           param: str) -> np.ndarray:
    sel = ((df["problem"] == problem) & (df["case"] == case) & (df["variant"] == variant)
           & (df["optimizer"] == optimizer) & (df["param"] == param)
           & (df["status"] != "failed"))
    return df.loc[sel, "best_cost"].astype(float).to_numpy()
