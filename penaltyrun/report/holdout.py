"""Held-out scenarios in the report: one section per problem and the discretization check.

Every job stores its best matrices' results on the problem's held-out set (``holdout``
column, see :meth:`Problem.holdout`); the problem says what that set is
(``ReportInfo.holdout_description``). Two kinds of pairing, scenario by scenario (by
label):

* per cell (problem × case × variant × optimizer): that cell's best diagonal start vs the
  best start of each full map;
* per problem × case × problem variant (``optimizer`` = :data:`BEST_KNOWN`): the starts that
  hold the best-known diagonal and full costs (over every optimizer) — the verdict's row.

The held-out answer is the paired cost ratio J_full / J_diag over *every* scenario of the
pairing (graded costs for runs that did not converge; see
:mod:`penaltyrun.problems.horizon` for the held-out horizon): median, 5 / 95 % quantiles,
the share of scenarios where full is cheaper, and the two-sided Wilcoxon signed-rank test of
the log ratios (``scipy.stats.wilcoxon``, zeros dropped), Holm-corrected over every
held-out ratio test of the report (:data:`FAMILY`); plus the median arrival-time shift
t_full − t_diag over the scenarios both reach. Records written before the long-horizon
evaluation were judged at the training deadline: their rows say so (``judged_at``).

Beside it, the older comparison over the scenarios both matrices bring to the target
(``pairs``): improvement (J_diag − J_full)/J_diag (median, 5 / 95 % quantiles), share where
full is better, Wilcoxon on the paired costs (``wilcoxon_p``, ``p_holm``), "underpowered"
below 10 pairs; and the convergence rates at the horizon and by the training deadline.

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

from penaltyrun.io import decode_json  # noqa: E402
from penaltyrun.jobrecord import NO_RESULT_STATUSES  # noqa: E402
from penaltyrun.report import protocol  # noqa: E402
from penaltyrun.report.bestknown import best_rows, with_problem_variant  # noqa: E402
from penaltyrun.report.rows import batches, full_row, groups, has, narrow, present  # noqa: E402
from penaltyrun.report.stats import holm, signed_rank_p  # noqa: E402
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
FAMILY = ("every held-out test of the same kind in this report (all problems, cases and rows; "
          "the log-ratio tests and the tests over converged pairs are two families)")
#: ``judged_at`` of records without a held-out horizon (written before it existed).
AT_DEADLINE = "training deadline (older record)"


def scenario_table(holdout: Any, drop_kinds: tuple[str, ...] = ()) -> pd.DataFrame | None:
    """Held-out JSON of one job as a table indexed by scenario label.

    Results written before scenarios had labels are indexed by position. Scenarios whose
    ``kind`` is in ``drop_kinds`` (discretization re-runs) are left out.

    Returns
    -------
    DataFrame or None
        Columns ``cost``, ``converged``, ``arrival_time`` (NaN where not stored),
        ``converged_by_deadline`` (= ``converged`` for records judged at the training
        deadline) and, where stored, ``kind``; ``attrs["horizon"]`` and
        ``attrs["training_horizon"]`` (NaN for older records). None if empty.
    """
    data = decode_json(holdout) if isinstance(holdout, str) else holdout
    if not data or "cost" not in data:
        return None
    n = len(data["cost"])
    labels = data.get("scenario") or [str(k) for k in range(n)]
    converged = np.asarray(data["converged"], bool)
    arrival = data.get("arrival_time")
    table = pd.DataFrame({
        "cost": np.asarray(data["cost"], float), "converged": converged,
        "arrival_time": np.full(n, np.nan) if arrival is None
        else np.asarray([np.nan if a is None else a for a in arrival], float),
        "converged_by_deadline": np.asarray(data.get("converged_by_deadline", converged),
                                            bool)},
        index=pd.Index([str(s) for s in labels], name="scenario"))
    if "kind" in data:
        table["kind"] = list(data["kind"])
        table = table[~table["kind"].isin(drop_kinds)]
    table.attrs["horizon"] = float(data.get("horizon", np.nan))
    table.attrs["training_horizon"] = float(data.get("training_horizon", np.nan))
    return table if len(table) else None


def best_start(g: pd.DataFrame) -> pd.Series | None:
    """Best non-failed start with a held-out result (converged starts first; of equal
    costs the first row); a lazily read frame's held-out data read a batch at a time."""
    ok = g[~g["status"].isin(NO_RESULT_STATUSES)]
    ok = ok[present(ok, "holdout")]
    if ok.empty:
        return None
    conv = ok[ok["best_converged"].astype(bool)]
    pick = conv if not conv.empty else ok
    return full_row(pick, pick["best_cost"].idxmin())


def _rate_all(g: pd.DataFrame, drop: tuple[str, ...] = ()) -> float:
    """Share of (start, scenario) pairs that converge, over all starts of ``g``."""
    hits = total = 0
    for part in batches(narrow(g, ("holdout",)), ("holdout",)):
        for h in part["holdout"].dropna():
            t = scenario_table(h, drop)
            if t is not None:
                hits += int(t["converged"].sum())
                total += len(t)
    return hits / total if total else np.nan


def ratio_stats(jd: np.ndarray, jf: np.ndarray) -> dict[str, Any]:
    """Paired cost-ratio statistics of J_full / J_diag over every scenario.

    Ratios use the scenarios where both costs are finite and positive (``n_ratio``); the
    share where full is cheaper counts every scenario. Wilcoxon: two-sided signed-rank test
    of log(J_full / J_diag), zero differences dropped (``zero_method="wilcox"``).

    Returns
    -------
    dict
        ``n_ratio``, ``ratio_median``, ``ratio_q05``, ``ratio_q95``,
        ``full_cheaper_share``, ``full_cheaper``, ``ratio_p``.
    """
    jd, jf = np.asarray(jd, float), np.asarray(jf, float)
    good = np.isfinite(jd) & np.isfinite(jf) & (jd > 0.0) & (jf > 0.0)
    log_r = np.log(jf[good] / jd[good])
    p = np.nan
    if log_r.size and np.any(log_r != 0.0):
        p = signed_rank_p(log_r)
    ratio = np.exp(log_r)
    return {"n_ratio": int(good.sum()),
            "ratio_median": float(np.median(ratio)) if ratio.size else np.nan,
            "ratio_q05": float(np.quantile(ratio, 0.05)) if ratio.size else np.nan,
            "ratio_q95": float(np.quantile(ratio, 0.95)) if ratio.size else np.nan,
            "full_cheaper": int(np.sum(jf < jd)),
            "full_cheaper_share": float(np.mean(jf < jd)) if jd.size else np.nan,
            "ratio_p": p}


def _judged_at(diag: pd.DataFrame, full: pd.DataFrame) -> tuple[str, float, float]:
    """(label, horizon, training horizon) of a pairing: the held-out horizon when both
    records carry one, else :data:`AT_DEADLINE`."""
    hd, hf = diag.attrs.get("horizon", np.nan), full.attrs.get("horizon", np.nan)
    if not (np.isfinite(hd) and np.isfinite(hf)):
        return AT_DEADLINE, np.nan, np.nan
    train = diag.attrs.get("training_horizon", np.nan)
    label = f"{hd:g}" if hd == hf else f"{hd:g} / {hf:g}"
    return label, float(max(hd, hf)), float(train)


def paired(diag: pd.DataFrame, full: pd.DataFrame) -> dict[str, Any]:
    """Paired statistics of two held-out tables (see the module docstring).

    Returns
    -------
    dict
        The cost-ratio statistics of :func:`ratio_stats` over every common scenario,
        ``arrival_shift_median`` (median t_full − t_diag where both arrive, s),
        ``judged_at``, ``horizon``, ``training_horizon``; ``scenarios``, ``diag_conv``,
        ``full_conv`` (rates at the horizon), ``diag_conv_deadline``,
        ``full_conv_deadline`` (by the training deadline), ``pairs`` (both converged),
        ``full_better_share``, ``median_imp_pct``, ``q05_imp_pct``, ``q95_imp_pct``,
        ``wilcoxon_p`` and ``note``; plus ``improvements`` (ndarray, %) and ``ratios``
        (ndarray).
    """
    common = diag.index.intersection(full.index)
    d, f = diag.loc[common], full.loc[common]
    both = d["converged"].to_numpy() & f["converged"].to_numpy()
    jd, jf = d["cost"].to_numpy()[both], f["cost"].to_numpy()[both]
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero cost (start on target)
        imp = 100.0 * (jd - jf) / jd
    imp[jd == jf] = 0.0  # equal costs, zero included: no improvement
    p, note = np.nan, ""
    diff = jd - jf
    if diff.size and np.any(diff != 0.0):
        p = signed_rank_p(diff)
    elif diff.size:
        note = "identical costs"
    if diff.size < MIN_PAIRS:
        note = (note + "; " if note else "") + f"underpowered (n = {diff.size} < {MIN_PAIRS})"
    all_d, all_f = d["cost"].to_numpy(float), f["cost"].to_numpy(float)
    ratios = ratio_stats(all_d, all_f)
    shift = (f["arrival_time"] - d["arrival_time"]).to_numpy(float)
    shift = shift[np.isfinite(shift)]
    judged, horizon, train = _judged_at(diag, full)
    good = np.isfinite(all_d) & np.isfinite(all_f) & (all_d > 0.0) & (all_f > 0.0)

    def rate(x: pd.Series) -> float:
        return float(x.mean()) if len(common) else np.nan

    return {**ratios, "arrival_shift_median": float(np.median(shift)) if shift.size else np.nan,
            "judged_at": judged, "horizon": horizon, "training_horizon": train,
            "scenarios": len(common),
            "diag_conv": rate(d["converged"]), "full_conv": rate(f["converged"]),
            "diag_conv_deadline": rate(d["converged_by_deadline"]),
            "full_conv_deadline": rate(f["converged_by_deadline"]),
            "pairs": int(both.sum()),
            "full_better_share": float(np.mean(jf < jd)) if jd.size else np.nan,
            "median_imp_pct": float(np.median(imp)) if imp.size else np.nan,
            "q05_imp_pct": float(np.quantile(imp, 0.05)) if imp.size else np.nan,
            "q95_imp_pct": float(np.quantile(imp, 0.95)) if imp.size else np.nan,
            "wilcoxon_p": p, "note": note, "improvements": imp,
            "ratios": all_f[good] / all_d[good]}


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
    ratios : dict label → ndarray of per-scenario cost ratios J_full / J_diag
    """
    if not has(df, "holdout") or df.empty:
        return pd.DataFrame(), {}
    df = with_problem_variant(df)
    if "variant" not in df:
        df = df.assign(variant=df["problem_variant"])
    rows = []
    for (problem, case, pvar, variant, optimizer), g in groups(
            df, ["problem", "case", "problem_variant", "variant", "optimizer"]):
        drop = protocol.info_of(g).discretization_kinds
        g = g[present(g, "holdout")]  # the rows with held-out data, read once here
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
    for (problem, case, pvar), g in groups(df, ["problem", "case", "problem_variant"]):
        best = best_rows(g[present(g, "holdout")])
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
        if r["ratios"].size:
            variant = f" [{r['variant']}]" if r["variant"] else ""
            label = f"{r['problem']} / {r['case']}{variant} / {r['optimizer']} / {r['full_map']}"
            imps[label] = r["ratios"]
    table["label"] = [f"{r['problem']} / {r['case']}"
                      f"{' [' + r['variant'] + ']' if r['variant'] else ''} / "
                      f"{r['optimizer']} / {r['full_map']}" for _, r in table.iterrows()]
    table = table.drop(columns=["improvements", "ratios"])
    table.insert(table.columns.get_loc("wilcoxon_p") + 1, "p_holm",
                 holm(table["wilcoxon_p"].to_numpy(float)))
    table.insert(table.columns.get_loc("ratio_p") + 1, "ratio_p_holm",
                 holm(table["ratio_p"].to_numpy(float)))
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
    if not has(df, "holdout"):
        return pd.DataFrame(rows)
    for (problem, case, variant, optimizer), g in groups(
            df, ["problem", "case", "variant", "optimizer"]):
        kinds = protocol.info_of(g).discretization_kinds
        drow = best_start(g[g["param"] == "diagonal"]) if kinds else None
        if drow is None:
            continue
        for param, fg in g[g["param"] != "diagonal"].groupby("param", sort=True):
            res = discretization_check(drow, best_start(fg), kinds)
            if res is not None:
                rows.append({"problem": problem, "case": case, "variant": variant,
                             "optimizer": optimizer, "full_map": param, **res})
    return pd.DataFrame(rows)


def figure(ratios: dict[str, np.ndarray], path: Path, title: str) -> Path:
    """Box plot of the per-scenario cost ratios J_full / J_diag on a log axis."""
    fig, ax = plt.subplots(figsize=(10, 0.55 * len(ratios) + 2.0))
    ax.boxplot(list(ratios.values()), showfliers=True, orientation="horizontal")
    ax.set_yticks(range(1, len(ratios) + 1), list(ratios), fontsize=9)
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("J_full / J_diag per held-out scenario (log axis; below 1: full is cheaper)")
    ax.set_title(title)
    ax.grid(True, axis="x", alpha=0.3)
    return save_figure(fig, path)


#: The held-out answer (cost ratios over every scenario) and, second table, convergence.
COLUMNS = ["optimizer", "full_map", "judged_at", "full_cheaper_share", "ratio_median",
           "ratio_range", "ratio_p_holm", "arrival_shift_median"]
HEADERS = ["optimizer", "full map", "horizon", "full cheaper", "median J_full/J_diag",
           "5–95 %", "Holm p (log ratio)", "median arrival shift"]
CONV_COLUMNS = ["optimizer", "full_map", "diag_conv", "full_conv", "diag_conv_deadline",
                "full_conv_deadline", "pairs", "median_imp_pct", "p_holm"]
CONV_HEADERS = ["optimizer", "full map", "diag conv.", "full conv.", "diag conv. by t_max",
                "full conv. by t_max", "pairs (both conv.)", "median change % (pairs)",
                "Holm p (pairs)"]


#: Columns of the held-out table holding a share of the scenarios (shown as k/n).
SHARE_COLUMNS = ("diag_conv", "full_conv", "diag_conv_deadline", "full_conv_deadline")


def counts(shares: Any, totals: Any) -> list[str]:
    """Shares of scenarios as counts ``k/n`` (``—`` where unknown): a share printed as a
    number (``1``) reads like a count."""
    out = []
    for share, total in zip(shares, totals):
        share, total = float(share), float(total)
        ok = np.isfinite(share) and np.isfinite(total) and total > 0
        out.append(f"{int(round(share * total))}/{int(total)}" if ok else "—")
    return out


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
             "Best diagonal vs best full start, re-evaluated on the held-out set at the "
             "held-out horizon (column *horizon*; a run not converged there costs the graded "
             "failure cost) and paired by scenario. The answer: the cost ratio J_full / "
             "J_diag over every scenario (median, 5–95 % range), the scenarios where full is "
             "cheaper, the two-sided Wilcoxon signed-rank test of the log ratios (Holm p "
             f"over {FAMILY}), and the median arrival-time shift t_full − t_diag. Beside it: "
             "convergence at the horizon and by the training deadline t_max, and the older "
             "comparison over the scenarios both converge (change = (J_diag − J_full)/J_diag, "
             "Wilcoxon on the paired costs). Rows judged at the training deadline come from "
             "records written before the held-out horizon existed.", ""]
    shown = sel.assign(full_cheaper_share=[
        "—" if not n else f"{int(c)}/{n}"
        for c, n in zip(sel["full_cheaper"], sel["scenarios"])],
        ratio_range=[f"{a:.3g}–{b:.3g}" for a, b in zip(sel["ratio_q05"], sel["ratio_q95"])],
        **{c: counts(sel[c], sel["scenarios"]) for c in SHARE_COLUMNS})
    for variant, g in shown.groupby("variant", sort=True):
        if variant:
            lines += [f"Variant {md_text(variant)}:", ""]
        lines += [markdown(g, COLUMNS, HEADERS), "", markdown(g, CONV_COLUMNS, CONV_HEADERS),
                  ""]
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


__all__ = ["BEST_KNOWN", "FAMILY", "SHARE_COLUMNS", "best_start", "counts",
           "discretization_check",
           "discretization_rows", "holdout_rows", "paired", "problem_section",
           "scenario_table"]
