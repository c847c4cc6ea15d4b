"""Held-out scenarios in the report: one section per problem family, and the low-thrust
discretization check.

Every job stores its best matrices' results on the problem's held-out set (``holdout``
column, see :meth:`Problem.holdout`). For each cell (problem × case × variant × optimizer)
the best diagonal start and the best start of each full map are paired scenario by
scenario (by label):

* convergence rate of each matrix on the held-out set, and over all starts of the cell;
* improvement (J_diag − J_full)/J_diag per scenario where both converge: median and 5 / 95 %
  quantiles; the share of those scenarios where full is better;
* Wilcoxon signed-rank test of the paired costs (two-sided, ``scipy.stats.wilcoxon``),
  with "underpowered" below 10 pairs.

Low thrust adds the discretization check: each tuned K's cost at the other control steps
and RK4 substep counts of its held-out set; a nominal saving smaller than that spread is
labelled "within discretization noise".
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy import stats  # noqa: E402

from penaltyrun.io import decode_json  # noqa: E402
from penaltyrun.report.tables import markdown  # noqa: E402

#: Problem families: title → problem names.
FAMILIES = {"Zermelo": ("zermelo",), "attitude": ("attitude_lyapunov", "attitude_lqr"),
            "low thrust": ("qlaw", "lyapunov_transfer")}
#: Fewer pairs than this: the Wilcoxon test is reported as underpowered.
MIN_PAIRS = 10
#: Held-out scenario kinds that change the discretization, not the scenario.
DISCRETIZATION_KINDS = ("control_step", "substeps")


def scenario_table(holdout: Any) -> pd.DataFrame | None:
    """Held-out JSON of one job as a table indexed by scenario label.

    Results written before scenarios had labels are indexed by position.

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
    return table


def best_start(g: pd.DataFrame) -> pd.Series | None:
    """Best non-failed start with a held-out result (converged starts first)."""
    ok = g[(g["status"] != "failed") & g["holdout"].notna()]
    if ok.empty:
        return None
    conv = ok[ok["best_converged"].astype(bool)]
    pick = conv if not conv.empty else ok
    return pick.loc[pick["best_cost"].idxmin()]


def _rate_all(g: pd.DataFrame) -> float:
    """Share of (start, scenario) pairs that converge, over all starts of ``g``."""
    hits = total = 0
    for h in g["holdout"].dropna():
        t = scenario_table(h)
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


def holdout_rows(df: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, np.ndarray]]:
    """One row per cell × full map: paired held-out statistics vs the cell's best diagonal.

    Returns
    -------
    table : DataFrame
    improvements : dict label → ndarray of per-scenario improvements (%)
    """
    rows, imps = [], {}
    keys = ["problem", "case", "variant", "optimizer"]
    for (problem, case, variant, optimizer), g in df.groupby(keys, sort=True):
        dg = g[g["param"] == "diagonal"]
        drow = best_start(dg)
        if drow is None:
            continue
        dtab = scenario_table(drow["holdout"])
        for param, fg in g[g["param"] != "diagonal"].groupby("param", sort=True):
            frow = best_start(fg)
            ftab = None if frow is None else scenario_table(frow["holdout"])
            if dtab is None or ftab is None:
                continue
            res = paired(dtab, ftab)
            label = f"{problem} / {case}{' [' + variant + ']' if variant else ''} / " \
                    f"{optimizer} / {param}"
            if res["improvements"].size:
                imps[label] = res.pop("improvements")
            else:
                res.pop("improvements")
            rows.append({"problem": problem, "case": case, "variant": variant,
                         "optimizer": optimizer, "full_map": param, **res,
                         "diag_conv_all_starts": _rate_all(dg),
                         "full_conv_all_starts": _rate_all(fg)})
    return pd.DataFrame(rows), imps


def discretization_rows(df: pd.DataFrame) -> pd.DataFrame:
    """Low-thrust discretization check of each cell's best diagonal and best full K.

    spread = max − min of a K's cost over the training run and its held-out control-step /
    substep scenarios (converged runs only); the nominal saving (diagonal − full, training
    runs) is "within discretization noise" when it is smaller than the larger spread.
    """
    rows = []
    keys = ["problem", "case", "variant", "optimizer"]
    for (problem, case, variant, optimizer), g in df.groupby(keys, sort=True):
        best = {"diagonal": best_start(g[g["param"] == "diagonal"])}
        for param, fg in g[g["param"] != "diagonal"].groupby("param", sort=True):
            best[param] = best_start(fg)
        spread, nominal = {}, {}
        for param, row in best.items():
            data = None if row is None else decode_json(row["holdout"])
            if not data or "kind" not in data or "training" not in data:
                continue
            kinds = np.asarray(data["kind"])
            sel = np.isin(kinds, DISCRETIZATION_KINDS) & np.asarray(data["converged"], bool)
            costs = list(np.asarray(data["cost"], float)[sel])
            train = data["training"]
            if train.get("converged"):
                costs.append(float(train["cost"]))
                nominal[param] = float(train["cost"])
            spread[param] = float(np.ptp(costs)) if len(costs) >= 2 else np.nan
        if "diagonal" not in nominal:
            continue
        for param in [p for p in nominal if p != "diagonal"]:
            saving = nominal["diagonal"] - nominal[param]
            noise = np.nanmax([spread.get("diagonal", np.nan), spread.get(param, np.nan)])
            verdict = "—" if not np.isfinite(noise) else (
                "within discretization noise" if abs(saving) < noise else "beyond the spread")
            rows.append({"problem": problem, "case": case, "variant": variant,
                         "optimizer": optimizer, "full_map": param,
                         "diag_nominal": nominal["diagonal"], "full_nominal": nominal[param],
                         "saving": saving, "diag_spread": spread.get("diagonal", np.nan),
                         "full_spread": spread.get(param, np.nan), "verdict": verdict})
    return pd.DataFrame(rows)


def _figure(imps: dict[str, np.ndarray], path: Path, title: str) -> None:
    fig, ax = plt.subplots(figsize=(9, 0.5 * len(imps) + 1.8))
    horizontal = ({"orientation": "horizontal"}
                  if tuple(int(v) for v in matplotlib.__version__.split(".")[:2]) >= (3, 10)
                  else {"vert": False})
    ax.boxplot(list(imps.values()), showfliers=True, **horizontal)
    ax.set_yticks(range(1, len(imps) + 1), list(imps), fontsize=7)
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel("improvement of full over diagonal per held-out scenario (%), both converged")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


COLUMNS = ["problem", "case", "variant", "optimizer", "full_map", "scenarios", "diag_conv",
           "full_conv", "pairs", "full_better_share", "median_imp_pct", "q05_imp_pct",
           "q95_imp_pct", "wilcoxon_p", "note", "diag_conv_all_starts",
           "full_conv_all_starts"]
HEADERS = ["problem", "case", "variant", "optimizer", "full map", "scenarios",
           "diag conv.", "full conv.", "pairs (both conv.)", "full better (share)",
           "median impr. %", "5 % q.", "95 % q.", "Wilcoxon p", "note",
           "diag conv. (all starts)", "full conv. (all starts)"]


def family_section(family: str, df: pd.DataFrame, out: Path) -> list[str]:
    """Markdown lines of one family's held-out section (empty without held-out data)."""
    table, imps = holdout_rows(df)
    if table.empty:
        return []
    slug = family.replace(" ", "_").lower()
    table.to_csv(out / f"holdout_{slug}.csv", index=False)
    lines = [f"## Held-out scenarios: {family}", "",
             "Best diagonal vs best full matrices of each cell, re-evaluated on the "
             "problem's held-out set and paired by scenario. Conv. = share of held-out "
             "scenarios where the terminal condition is met; improvement = (J_diag − J_full)"
             "/J_diag over the scenarios where both converge; Wilcoxon signed-rank, "
             "two-sided, on those pairs (raw p, no multiplicity correction). The last two "
             "columns pool every start of the cell.", "",
             markdown(table, COLUMNS, HEADERS), ""]
    if imps:
        name = f"holdout_{slug}.png"
        _figure(imps, out / name, f"Held-out scenarios: {family}")
        lines += [f"![held-out {family}]({name})", ""]
    if family == "low thrust":
        disc = discretization_rows(df)
        if not disc.empty:
            disc.to_csv(out / "holdout_discretization.csv", index=False)
            lines += ["### Low thrust: discretization check", "",
                      "Saving = cost of the best diagonal K − cost of the best full K at the "
                      "training control step (days or kg). Spread = max − min of one K's "
                      "cost over the training step and the held-out control steps / RK4 "
                      "substeps (converged runs). A saving smaller than the larger spread is "
                      "within discretization noise.", "",
                      markdown(disc), ""]
    return lines


def study_sections(df: pd.DataFrame, out: Path, paper: bool) -> list[str]:
    """Held-out sections of every problem family present in ``df``."""
    if "holdout" not in df:
        return []
    lines: list[str] = []
    for family, names in FAMILIES.items():
        sel = df[df["problem"].isin(names)]
        if not sel.empty:
            lines += family_section(family, sel, out)
    return lines


__all__ = ["best_start", "discretization_rows", "family_section", "holdout_rows", "paired",
           "scenario_table", "study_sections"]
