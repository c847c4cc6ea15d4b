"""The report's trade-off fronts section: tables, sentences and one figure per sweep (the
fronts themselves: :mod:`penaltyrun.report.fronts`)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.report import fronts
from penaltyrun.report.compare import map_order
from penaltyrun.report.tables import file_stem, fmt, markdown, md_text, save_figure

ALPHA = fronts.ALPHA
METHOD = (
    "Each value of the price of a second ρ (criterion J = E(t_f) + ρ·t_f) is a "
    "single-objective tune with the same optimizer, budget and records as every other cell. "
    "A start's front is the (energy E, arrival time t_f) of its tuned matrices across the "
    "values of ρ (same start index), reduced to its non-dominated set; its hypervolume is "
    "the area it dominates in decades (log10 E × log10 t_f) up to a reference point common "
    "to the sweep: per coordinate the largest converged value of the sweep (every map, start "
    "and ρ) plus {margin:g} of its range. A start that converged at no ρ has hypervolume 0. "
    "A sweep of ρ is a weighted sum of the two objectives: it finds the supported points of "
    "a front (those on its convex hull), never a point in a concave dent; each point is a "
    "tune a user would deploy at that price of time, and both maps are swept at the same "
    "prices. Hypervolume tests: two-sided Mann–Whitney U over the starts, A12 = P(a full "
    "start's hypervolume exceeds a diagonal start's), Holm over {family}. Pooled fronts: "
    "every converged point of a map over all starts and ρ, reduced to its non-dominated set.")


def _per_rho(comp: pd.DataFrame, pts: pd.DataFrame, key: tuple, b: str) -> pd.DataFrame:
    """One row per ρ of a sweep: medians of J and of the arrival time per map and the
    report's equal-budget test of J (its Holm p is of the comparison family)."""
    problem, case, sweep, optimizer = key
    sel = pts[(pts["problem"] == problem) & (pts["case"] == case) & (pts["sweep"] == sweep)
              & (pts["optimizer"] == optimizer)]
    rows = []
    for rho, g in sel.groupby(fronts.SWEPT, sort=True):
        variant = g["variant"].iloc[0]
        c = comp[(comp["problem"] == problem) & (comp["case"] == case)
                 & (comp["variant"] == variant) & (comp["optimizer"] == optimizer)
                 & (comp["map_a"] == "diagonal") & (comp["map_b"] == b)] \
            if not comp.empty else comp
        conv = g[g["converged"]]
        ta = conv.loc[conv["param"] == "diagonal", "arrival_time"]
        tb = conv.loc[conv["param"] == b, "arrival_time"]
        r = c.iloc[0] if len(c) else None
        rows.append({"ρ": rho, "median J diagonal": np.nan if r is None else r["median_a"],
                     f"median J {b}": np.nan if r is None else r["median_b"],
                     "median t_f diagonal": float(ta.median()) if len(ta) else np.nan,
                     f"median t_f {b}": float(tb.median()) if len(tb) else np.nan,
                     "A12": np.nan if r is None else r["a12_b_beats_a"],
                     "Holm p": np.nan if r is None else r["p_holm"]})
    return pd.DataFrame(rows)


def _where(per_rho: pd.DataFrame, b: str) -> str:
    """Which values of ρ favour which map (equal-budget tests of J at each ρ)."""
    lower = [fmt(r["ρ"], 3) for _, r in per_rho.iterrows()
             if np.isfinite(r["Holm p"]) and r["Holm p"] < ALPHA and r["A12"] > 0.5]
    higher = [fmt(r["ρ"], 3) for _, r in per_rho.iterrows()
              if np.isfinite(r["Holm p"]) and r["Holm p"] < ALPHA and r["A12"] < 0.5]
    none = [fmt(r["ρ"], 3) for _, r in per_rho.iterrows()
            if not (np.isfinite(r["Holm p"]) and r["Holm p"] < ALPHA)]
    parts = []
    if lower:
        parts.append(f"{b} reaches a lower J at ρ = {', '.join(lower)}")
    if higher:
        parts.append(f"the diagonal map reaches a lower J at ρ = {', '.join(higher)}")
    if none:
        parts.append(f"at ρ = {', '.join(none)} there is no evidence of a difference in J")
    return "; ".join(parts)


def sentence(t: pd.Series, per_rho: pd.DataFrame) -> str:
    """The answer of one sweep × full map in words, with its hedge."""
    b = t["map_b"]
    if not t["equal_budget"]:
        head = "budgets differ: no hypervolume test"
    elif np.isfinite(t["p_holm"]) and t["p_holm"] < ALPHA:
        better = b if t["a12_b_beats_a"] > 0.5 else "diagonal"
        head = (f"the {better} fronts are larger (hypervolume: A12 = "
                f"{fmt(t['a12_b_beats_a'], 2)}, Holm p {fmt(t['p_holm'], 2)})")
    else:
        head = (f"no evidence of a difference between the hypervolumes of the fronts (A12 = "
                f"{fmt(t['a12_b_beats_a'], 2)}, Holm p {fmt(t['p_holm'], 2)}; n = "
                f"{t['n_a']}/{t['n_b']})")
    pooled = (f"the pooled {b} front dominates {fmt(100 * t['dominated_a'], 3)} % of the "
              "pooled diagonal front" + (f" (arrival times {t['b_dominates_times']})"
                                          if t["b_dominates_times"] else "")
              + f", the pooled diagonal front {fmt(100 * t['dominated_b'], 3)} % of the "
              f"{b} front")
    parts = [head, pooled]
    where = _where(per_rho, b)
    if where:
        parts.append(where)
    return "; ".join(parts) + "."


def figure(pts: pd.DataFrame, hv: pd.DataFrame, held: pd.DataFrame, title: str,
           path: Path) -> Path:
    """Left: every start's front (thin) and each map's pooled front (thick), energy against
    arrival time (log–log), the reference point as a cross. Right: training against mean
    held-out cost per start, one marker per ρ, each map's front per ρ as a line."""
    import matplotlib.pyplot as plt

    colors = {m: f"C{i}" for i, m in enumerate(map_order(pts["param"].unique()))}
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11.0, 4.4))
    for m, g in hv.groupby("param"):
        for text in g["front"]:
            f = np.asarray(json.loads(text), float).reshape(-1, 2)
            if len(f):
                ax.plot(f[:, 1], f[:, 0], "-", color=colors[m], alpha=0.25, lw=0.8)
        pooled = fronts.pooled_front(pts[pts["param"] == m])
        if len(pooled):
            ax.plot(pooled[:, 1], pooled[:, 0], "o-", color=colors[m], lw=2.0, ms=4,
                    label=f"{m}: pooled front")
    ref = hv.iloc[0]
    ax.plot(ref["ref_time"], ref["ref_energy"], "kx", label="reference point")
    ax.set(xscale="log", yscale="log", xlabel="arrival time t_f (s)", ylabel="energy E",
           title="energy against arrival time")
    ax.legend(fontsize=8)
    markers = "os^vD<>ph*"
    for (m, rho), g in held.groupby(["param", fronts.SWEPT]):
        f = np.asarray(json.loads(g["front"].iloc[0]), float).reshape(-1, 2)
        k = sorted(held[fronts.SWEPT].unique()).index(rho) % len(markers)
        if len(f):
            bx.plot(f[:, 0], f[:, 1], "-", color=colors.get(m, "k"), lw=1.0)
        sel = pts[(pts["param"] == m) & (pts[fronts.SWEPT] == rho)]
        bx.plot(sel["cost"], [fronts.heldout_mean(h) for h in sel["holdout"]],
                markers[k], color=colors.get(m, "k"), ms=4, alpha=0.7, linestyle="",
                label=f"{m}, ρ = {rho:g}")
    bx.set(xscale="log", yscale="log", xlabel="training cost J",
           ylabel="mean held-out cost", title="training against held-out cost")
    bx.legend(fontsize=7, ncol=2)
    fig.suptitle(title, fontsize=10)
    return save_figure(fig, path)


def section(tables: dict[str, pd.DataFrame], comp: pd.DataFrame, out: Path) -> list[str]:
    """Markdown lines of the trade-off fronts section (none without a sweep); one figure
    ``fronts_<stem>.png`` per sweep in ``out``."""
    hv, tests, held, pts = (tables[k] for k in ("fronts", "fronts_tests", "fronts_holdout",
                                                 "points"))
    if hv.empty:
        return []
    lines = ["## Trade-off fronts", "",
             METHOD.format(margin=fronts.REF_MARGIN, family=fronts.FAMILY), ""]
    for key, g in hv.groupby(fronts.SWEEP, sort=True):
        problem, case, sweep, optimizer = key
        label = f"{problem} / {case}" + (f" [{sweep}]" if sweep else "") + f" — {optimizer}"
        lines += [f"### {md_text(label)}", ""]
        summary = g.groupby("param", sort=False).agg(
            starts=("start", "size"), front_points=("n_front", "median"),
            hv_median=("hypervolume", "median"), hv_best=("hypervolume", "max"),
            no_point=("n_converged", lambda s: int((s == 0).sum()))).reset_index()
        lines += [markdown(summary, ["param", "starts", "front_points", "hv_median",
                                     "hv_best", "no_point"],
                           ["map", "starts", "median front points", "median hypervolume",
                            "largest hypervolume", "starts without a converged point"]), ""]
        sel = tests[(tests[fronts.SWEEP] == pd.Series(key, index=fronts.SWEEP)).all(axis=1)] \
            if not tests.empty else tests
        sweep_pts = pts[(pts[fronts.SWEEP] == pd.Series(key, index=fronts.SWEEP)).all(axis=1)]
        for _, t in sel.iterrows():
            per_rho = _per_rho(comp, pts, key, t["map_b"])
            lines += [markdown(per_rho), "", f"- {md_text(sentence(t, per_rho))}", ""]
        cell_held = held[(held["problem"] == problem) & (held["case"] == case)
                         & (held["optimizer"] == optimizer)
                         & held["variant"].isin(sweep_pts["variant"].unique())]
        if not cell_held.empty:
            lines += ["Training cost against mean held-out cost (per ρ and map: the front "
                      "over its starts; dominated: share of it dominated by the other "
                      "maps' fronts of that ρ):", "",
                      markdown(cell_held, [fronts.SWEPT, "param", "n_starts", "n_front",
                                           "hypervolume", "dominated"],
                               ["ρ", "map", "starts", "front points", "hypervolume",
                                "dominated"]), ""]
        stem = file_stem(f"fronts_{problem}_{case}_{sweep}_{optimizer}")
        path = figure(sweep_pts, g, cell_held, label, out / f"{stem}.png")
        lines += [f"![trade-off fronts]({path.name})", ""]
    return lines


__all__ = ["METHOD", "figure", "section", "sentence"]
