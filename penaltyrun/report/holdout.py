"""Held-out scenarios in the report: one section per problem and the discretization check.

Every job stores its best matrices' results on the problem's held-out set (``holdout``
column, see :meth:`Problem.holdout`); the problem says what that set is
(``ReportInfo.holdout_description``). Two kinds of pairing, scenario by scenario (by
label):

* per cell (problem × case × variant × optimizer): that cell's best diagonal start vs the
  best start of each full map;
* per problem × case × problem variant (``optimizer`` = :data:`BEST_KNOWN`): the starts that
  hold the best-known diagonal and full costs (over every optimizer) — the verdict's row.

Statistics: convergence rates; improvement (J_diag − J_full)/J_diag per scenario where both
converge (median, 5 / 95 % quantiles); the share of those where full is better; the
two-sided Wilcoxon signed-rank test (``scipy.stats.wilcoxon``), Holm-corrected over every
held-out test of the report (:data:`FAMILY`), "underpowered" below 10 pairs.

Scenarios whose ``kind`` the problem lists in ``ReportInfo.discretization_kinds`` re-run the
training scenario at another discretization: they are left out of the pairing and give the
discretization check instead (:func:`discretization_rows`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy import stats  # noqa: E402

from penaltyrun.io import decode_json  # noqa: E402
from penaltyrun.report import protocol  # noqa: E402
from penaltyrun.report.bestknown import best_rows, with_problem_variant  # noqa: E402
from penaltyrun.report.stats import holm  # noqa: E402
from penaltyrun.report.tables import (  # noqa: E402
    alt_text,
    file_stem,
    markdown,
    md_text,
    save_figure,
)

#: Fewer pairs than this: the Wilcoxon test is reported as underpowered.
MIN_PAIRS = 10
#: ``optimizer`` label of the rows pairing the best-known starts (over all optimizers).
BEST_KNOWN = "best-known (all optimizers)"
#: Holm family of the held-out tests, named in the report.
FAMILY = "every held-out Wilcoxon test of this report (all problems, cases and rows)"


def scenario_table(holdout: Any, drop_kinds: tuple[str, ...] = ()) -> pd.DataFrame | None:
    """Held-out JSON of one job as a table indexed by scenario label.

    Results written before scenarios had labels are indexed by position. Scenarios whose
    ``kind`` is in ``drop_kinds`` (discretization re-runs) are left out.

    Returns
    -------
    DataFrame or None
        Columns ``cost``, ``converged`` and, where stored, ``kind``; None if empty.
    """
    data = decode_json(holdout) if isinstance(holdout, str) else holdout
    if not data or "cost" not in data:
        return None
    n = len(data["cost"])
    labels = data.get("scenario") or [str(k) for k in range(n)]
    table = pd.DataFrame({"cost": np.asarray(data["cost"], float),
                          "converged": np.asarray(data["converged"], bool)},
                         index=pd.Index([str(s) for s in labels], name="scenario"))
    if "kind" in data:
        table["kind"] = list(data["kind"])
        table = table[~table["kind"].isin(drop_kinds)]
    return table if len(table) else None


def best_start(g: pd.DataFrame) -> pd.Series | None:
    """Best non-failed start with a held-out result (converged starts first)."""
    ok = g[(g["status"] != "failed") & g["holdout"].notna()]
    if ok.empty:
        return None
    conv = ok[ok["best_converged"].astype(bool)]
    pick = conv if not conv.empty else ok
    return pick.loc[pick["best_cost"].idxmin()]


def _rate_all(g: pd.DataFrame, drop: tuple[str, ...] = ()) -> float:
    """Share of (start, scenario) pairs that converge, over all starts of ``g``."""
    hits = total = 0
    for h in g["holdout"].dropna():
        t = scenario_table(h, drop)
        if t is not None:
            hits += int(t["converged"].sum())
            total += len(t)
    return hits / total if total else np.nan


def paired(diag: pd.DataFrame, full: pd.DataFrame) -> dict[str, Any]:
    """Paired statistics of two held-out tables (see the module docstring).

    Returns
    -------
    dict
        ``scenarios``, ``diag_conv``, ``full_conv`` (rates), ``pairs`` (both converged),
        ``full_better_share``, ``median_imp_pct``, ``q05_imp_pct``, ``q95_imp_pct``,
        ``wilcoxon_p`` and ``note``; plus ``improvements`` (ndarray, %).
    """
    common = diag.index.intersection(full.index)
    d, f = diag.loc[common], full.loc[common]
    both = d["converged"].to_numpy() & f["converged"].to_numpy()
    jd, jf = d["cost"].to_numpy()[both], f["cost"].to_numpy()[both]
    imp = 100.0 * (jd - jf) / jd if jd.size else np.zeros(0)
    p, note = np.nan, ""
    diff = jd - jf
    if diff.size and np.any(diff != 0.0):
        p = float(stats.wilcoxon(jd, jf, zero_method="wilcox",
                                 alternative="two-sided").pvalue)
    elif diff.size:
        note = "identical costs"
    if diff.size < MIN_PAIRS:
        note = (note + "; " if note else "") + f"underpowered (n = {diff.size} < {MIN_PAIRS})"
    return {"scenarios": len(common),
            "diag_conv": float(d["converged"].mean()) if len(common) else np.nan,
            "full_conv": float(f["converged"].mean()) if len(common) else np.nan,
            "pairs": int(both.sum()),
            "full_better_share": float(np.mean(jf < jd)) if jd.size else np.nan,
            "median_imp_pct": float(np.median(imp)) if imp.size else np.nan,
            "q05_imp_pct": float(np.quantile(imp, 0.05)) if imp.size else np.nan,
            "q95_imp_pct": float(np.quantile(imp, 0.95)) if imp.size else np.nan,
            "wilcoxon_p": p, "note": note, "improvements": imp}


def _row(problem: str, case: str, variant: str, optimizer: str, param: str,
         drow: pd.Series, frow: pd.Series, drop: tuple[str, ...]) -> dict[str, Any] | None:
    dtab = scenario_table(drow["holdout"], drop)
    ftab = scenario_table(frow["holdout"], drop)
    if dtab is None or ftab is None:
        return None
    return {"problem": problem, "case": case, "variant": variant, "optimizer": optimizer,
            "full_map": param, **paired(dtab, ftab)}


def holdout_rows(df: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """Paired held-out statistics: one row per cell × full map, and one per problem × case
    × problem variant for the best-known starts (``optimizer`` = :data:`BEST_KNOWN`).

    Returns
    -------
    table : DataFrame
        Columns of :func:`paired` plus ``p_holm`` (Holm over every row with a p-value) and
        the convergence rates over all starts of the cell.
    improvements : dict label → ndarray of per-scenario improvements (%)
    """
    if "holdout" not in df or df.empty:
        return pd.DataFrame(), {}
    df = with_problem_variant(df)
    if "variant" not in df:
        df = df.assign(variant=df["problem_variant"])
    rows = []
    for (problem, case, pvar, variant, optimizer), g in df.groupby(
            ["problem", "case", "problem_variant", "variant", "optimizer"], sort=True):
        drop = protocol.info_of(g).discretization_kinds
        dg = g[g["param"] == "diagonal"]
        drow = best_start(dg)
        if drow is None:
            continue
        for param, fg in g[g["param"] != "diagonal"].groupby("param", sort=True):
            frow = best_start(fg)
            res = None if frow is None else _row(problem, case, variant, optimizer, param,
                                                 drow, frow, drop)
            if res is not None:
                rows.append({**res, "problem_variant": pvar,
                             "diag_conv_all_starts": _rate_all(dg, drop),
                             "full_conv_all_starts": _rate_all(fg, drop)})
    for (problem, case, pvar), g in df.groupby(["problem", "case", "problem_variant"],
                                               sort=True):
        best = best_rows(g[g["holdout"].notna()])
        if set(best) >= {"diagonal", "full"}:
            drop = protocol.info_of(g).discretization_kinds
            res = _row(problem, case, pvar, BEST_KNOWN, best["full"]["param"],
                       best["diagonal"], best["full"], drop)
            if res is not None:
                rows.append({**res, "problem_variant": pvar})
    table = pd.DataFrame(rows)
    imps: dict[str, np.ndarray] = {}
    if table.empty:
        return table, imps
    for _, r in table.iterrows():
        if r["improvements"].size:
            variant = f" [{r['variant']}]" if r["variant"] else ""
            label = f"{r['problem']} / {r['case']}{variant} / {r['optimizer']} / {r['full_map']}"
            imps[label] = r["improvements"]
    table["label"] = [f"{r['problem']} / {r['case']}"
                      f"{' [' + r['variant'] + ']' if r['variant'] else ''} / "
                      f"{r['optimizer']} / {r['full_map']}" for _, r in table.iterrows()]
    table = table.drop(columns="improvements")
    table.insert(table.columns.get_loc("wilcoxon_p") + 1, "p_holm",
                 holm(table["wilcoxon_p"].to_numpy(float)))
    return table, imps


def discretization_check(diag: pd.Series, full: pd.Series,
                         kinds: tuple[str, ...]) -> dict[str, Any] | None:
    """Discretization check of one diagonal and one full start.

    spread = max − min of a start's cost over its training run and its held-out scenarios
    of ``kinds`` (converged runs only); the saving (diagonal − full, training runs) is
    *within discretization noise* when its magnitude is below the larger spread.

    Returns
    -------
    dict or None
        ``saving``, ``diag_spread``, ``full_spread``, ``verdict``; None without data.
    """
    spread, nominal = {}, {}
    for name, row in (("diagonal", diag), ("full", full)):
        data = None if row is None else decode_json(row["holdout"])
        if not kinds or not data or "kind" not in data or "training" not in data:
            return None
        sel = np.isin(np.asarray(data["kind"]), kinds) & np.asarray(data["converged"], bool)
        costs = list(np.asarray(data["cost"], float)[sel])
        train = data["training"] or {}
        if not train.get("converged"):
            return None
        nominal[name] = float(train["cost"])
        costs.append(nominal[name])
        spread[name] = float(np.ptp(costs)) if len(costs) >= 2 else np.nan
    saving = nominal["diagonal"] - nominal["full"]
    noise = np.nanmax([spread["diagonal"], spread["full"]]) \
        if np.isfinite([spread["diagonal"], spread["full"]]).any() else np.nan
    verdict = "—" if not np.isfinite(noise) else (
        "within discretization noise" if abs(saving) < noise else "beyond the spread")
    return {"saving": saving, "diag_spread": spread["diagonal"],
            "full_spread": spread["full"], "verdict": verdict}


def discretization_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The discretization check of each cell's best diagonal vs best full start, for the
    problems that declare discretization scenario kinds."""
    rows = []
    if "holdout" not in df:
        return pd.DataFrame(rows)
    for (problem, case, variant, optimizer), g in df.groupby(
            ["problem", "case", "variant", "optimizer"], sort=True):
        kinds = protocol.info_of(g).discretization_kinds
        drow = best_start(g[g["param"] == "diagonal"])
        if not kinds or drow is None:
            continue
        for param, fg in g[g["param"] != "diagonal"].groupby("param", sort=True):
            res = discretization_check(drow, best_start(fg), kinds)
            if res is not None:
                rows.append({"problem": problem, "case": case, "variant": variant,
                             "optimizer": optimizer, "full_map": param, **res})
    return pd.DataFrame(rows)


def figure(imps: dict[str, np.ndarray], path: Path, title: str) -> Path:
    """Box plot of the per-scenario improvements (%), symlog axis (outliers of −1 000 %
    do not squash the boxes)."""
    fig, ax = plt.subplots(figsize=(10, 0.55 * len(imps) + 2.0))
    ax.boxplot(list(imps.values()), showfliers=True, orientation="horizontal")
    ax.set_yticks(range(1, len(imps) + 1), list(imps), fontsize=9)
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xscale("symlog", linthresh=1.0)
    ax.set_xlabel("(J_diag − J_full)/J_diag per held-out scenario, both converged (%; "
                  "symlog axis, linear within ±1 %)")
    ax.set_title(title)
    ax.grid(True, axis="x", alpha=0.3)
    return save_figure(fig, path)


COLUMNS = ["optimizer", "full_map", "pairs", "scenarios", "diag_conv", "full_conv",
           "full_better_share", "median_imp_pct", "wilcoxon_p", "p_holm"]
HEADERS = ["optimizer", "full map", "pairs (both conv.)", "scenarios", "diag conv.",
           "full conv.", "full better (of pairs)", "median change %", "Wilcoxon p", "Holm p"]


def problem_section(df: pd.DataFrame, table: pd.DataFrame, imps: dict[str, np.ndarray],
                    out: Path) -> list[str]:
    """Markdown lines of one problem case's held-out section (empty without data)."""
    df = with_problem_variant(df)
    first = df.iloc[0]
    sel = table[(table["problem"] == first["problem"]) & (table["case"] == first["case"])
                & (table["problem_variant"] == first["problem_variant"])] \
        if not table.empty else table
    if sel.empty:
        return []
    info = protocol.info_of(df)
    what = info.holdout_description or "the problem does not describe its held-out set"
    lines = ["### Held-out scenarios", "", f"Held-out set: {what}.", "",
             "Best diagonal vs best full start, re-evaluated on the held-out set and paired "
             "by scenario; change = (J_diag − J_full)/J_diag over the scenarios where both "
             "converge (positive: full is lower). Wilcoxon signed-rank, two-sided; Holm p "
             f"over {FAMILY}.", ""]
    shown = sel.assign(full_better_share=[
        "—" if not p else f"{int(round(s * p))}/{p}"
        for s, p in zip(sel["full_better_share"], sel["pairs"])])
    for variant, g in shown.groupby("variant", sort=True):
        if variant:
            lines += [f"Variant {md_text(variant)}:", ""]
        lines += [markdown(g, COLUMNS, HEADERS), ""]
    mine = {k: imps[k] for k in sel["label"] if k in imps}
    if mine:
        label = f"{first['problem']}_{first['case']}_{first['problem_variant']}"
        slug = file_stem(label.rstrip("_"))
        name = f"holdout_{slug}.png"
        figure(mine, out / name, f"{first['problem']} / {first['case']}: held-out scenarios")
        alt = alt_text(f"held-out {first['problem']} / {first['case']}")
        lines += [f"![{alt}]({name})", ""]
    disc = discretization_rows(df)
    if not disc.empty:
        lines += ["### Discretization check", "",
                  "Saving = training cost of the best diagonal − of the best full start "
                  f"({info.cost_label}); spread = max − min of one start's cost over the "
                  "training run and its discretization re-runs; a saving smaller than the "
                  "larger spread is within discretization noise.", "",
                  markdown(disc, ["optimizer", "full_map", "saving", "diag_spread",
                                  "full_spread", "verdict"]), ""]
    return lines


__all__ = ["BEST_KNOWN", "FAMILY", "best_start", "discretization_check",
           "discretization_rows", "holdout_rows", "paired", "problem_section",
           "scenario_table"]
