"""The verdict: one row per problem × case × problem variant answering "does a full matrix
beat the diagonal one, by how much, how sure are we, and does it hold off the training
scenario?", and one generated sentence per row stating the answer with its hedge.

A row joins (all computed elsewhere, from the same data):

* the best-known diagonal and full costs with their evidence (:mod:`.bestknown`) and the
  best-known gain (diagonal − full)/diagonal;
* the equal-budget comparison of each optimizer (:mod:`.compare`: A12 = P(a full start beats
  a diagonal start) and Holm p, or "budgets differ: no test");
* the held-out pairing of the best-known starts (:mod:`.holdout`), judged at the held-out
  horizon: share of scenarios where full is cheaper, median cost ratio J_full / J_diag with
  its 5–95 % range, Wilcoxon p of the log ratios (Holm), arrival-time shift, and convergence
  at the horizon and by the training deadline (a column, never a gate);
* the discretization check where the problem declares one.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.jobrecord import final_search_stop
from penaltyrun.report import protocol
from penaltyrun.report.bestknown import CERTIFY_RTOL, best_rows
from penaltyrun.report.compare import NO_TEST
from penaltyrun.report.holdout import BEST_KNOWN, discretization_check
from penaltyrun.report.rows import has, present
from penaltyrun.report.tables import fmt, with_unit
from penaltyrun.report.tuning import aggregate_label, training_of

#: Significance level of the words in the sentences (the p-values are always printed).
ALPHA = 0.05
COLUMNS = ["question", "diagonal best-known", "full best-known", "gain", "equal budget",
           "held-out", "discretization"]


def _label(problem: str, case: str, variant: str) -> str:
    return f"{problem} / {case}" + (f" [{variant}]" if variant else "")


def _p(value: float) -> str:
    return "—" if not np.isfinite(value) else ("< 0.0001" if value < 1e-4 else
                                                "= " + fmt(value, 2))


def _equal_budget(comp: pd.DataFrame, problem: str, case: str, pvar: str) -> list[dict]:
    """Diagonal-vs-full comparisons of one row: one entry per variant × optimizer × map."""
    if comp.empty:
        return []
    sel = comp[(comp["problem"] == problem) & (comp["case"] == case)
               & (comp["map_a"] == "diagonal") & (comp["problem_variant"] == pvar)]
    return [r.to_dict() for _, r in sel.iterrows()]


def _budget_text(r: dict) -> str:
    who = r["optimizer"] + (f" [{r['variant']}]" if r["variant"] else "") + \
        (f" ({r['map_b']})" if r["map_b"] != "full" else "")
    if not r["equal_budget"]:
        return f"{who}: {NO_TEST}"
    if not np.isfinite(r["p_mwu"]):
        return f"{who}: n = {r['n_a']}/{r['n_b']}, no test"
    return f"{who}: A12 {fmt(r['a12_b_beats_a'], 2)}, Holm p {_p(r['p_holm'])}"


def _test_label(r: dict, tested: list[dict]) -> str:
    """The optimizer of an equal-budget test, with its full map and its variant where the
    tests of the sentence differ in them."""
    label = str(r["optimizer"])
    if len({t["map_b"] for t in tested}) > 1:
        label += f", {r['map_b']}"
    if len({t["variant"] for t in tested}) > 1:
        label += f" [{r['variant']}]" if r["variant"] else " [default]"
    return label


def _held(held: pd.DataFrame, problem: str, case: str, pvar: str) -> dict | None:
    if held.empty:
        return None
    sel = held[(held["problem"] == problem) & (held["case"] == case)
               & (held["variant"] == pvar) & (held["optimizer"] == BEST_KNOWN)]
    return None if sel.empty else sel.iloc[0].to_dict()


def _count(rate: float, n: int) -> int:
    return int(round(rate * n)) if np.isfinite(rate) else 0


def horizon_words(h: dict) -> str:
    """Where a held-out pairing was judged, and convergence by the training deadline."""
    n = int(h["scenarios"])

    def conv(diag: float, full: float) -> str:
        return f"diagonal {_count(diag, n)}/{n}, full {_count(full, n)}/{n}"

    if not np.isfinite(h["horizon"]):
        return ("judged at the training deadline (record older than the held-out horizon); "
                f"converged: {conv(h['diag_conv'], h['full_conv'])}")
    reach = (f"judged at horizon T = {fmt(h['horizon'], 4)}; converged by T: "
             f"{conv(h['diag_conv'], h['full_conv'])}")
    if h["horizon"] == h["training_horizon"]:  # free final time: no earlier deadline
        return reach + " (T is the training horizon)"
    return (f"{reach}; by the training deadline {fmt(h['training_horizon'], 4)}: "
            f"{conv(h['diag_conv_deadline'], h['full_conv_deadline'])}")


def ratio_words(h: dict) -> str:
    """The cost-ratio answer of a held-out pairing, e.g. "full cheaper on 9/216, median
    J_full/J_diag 4.1 (5–95 %: 0.9–30), Holm p < 0.0001"."""
    text = (f"full cheaper on {int(h['full_cheaper'])}/{int(h['scenarios'])}, median "
            f"J_full/J_diag {fmt(h['ratio_median'], 3)} (5–95 %: {fmt(h['ratio_q05'], 2)}–"
            f"{fmt(h['ratio_q95'], 2)}), Wilcoxon signed-rank of the log ratios, Holm p "
            f"{_p(h['ratio_p_holm'])}")
    if np.isfinite(h.get("arrival_shift_median", np.nan)):
        text += f", median arrival shift {fmt(h['arrival_shift_median'], 3)}"
    return text


def _held_text(h: dict | None) -> str:
    if h is None or not h["scenarios"]:
        return "—"
    return f"{ratio_words(h)}; {horizon_words(h)}"


def verdict_rows(df: pd.DataFrame, bk: pd.DataFrame, comp: pd.DataFrame,
                 held: pd.DataFrame) -> pd.DataFrame:
    """One row per problem × case × problem variant with both families (see module doc).

    Returns
    -------
    DataFrame
        Display columns :data:`COLUMNS` plus ``sentence`` and the raw values
        (``diag_cost``, ``full_cost``, ``gain_pct``, ``diag_level``, ``full_level``, ...).
    """
    rows = []
    if bk.empty:
        return pd.DataFrame(rows)
    for (problem, case, pvar), g in bk.groupby(["problem", "case", "problem_variant"],
                                               sort=True):
        fams = {r["family"]: r for _, r in g.iterrows()}
        jobs = df[(df["problem"] == problem) & (df["case"] == case)
                  & (df["problem_variant"] == pvar)]
        info = protocol.info_of(jobs)
        unit = info.cost_unit
        d, f = fams.get("diagonal"), fams.get("full")
        gain = (100.0 * (d["best_known"] - f["best_known"]) / abs(d["best_known"])
                if d is not None and f is not None else np.nan)
        budgets = _equal_budget(comp, problem, case, pvar)
        h = _held(held, problem, case, pvar)
        disc = None
        if info.discretization_kinds and d is not None and f is not None:
            best = best_rows(jobs[present(jobs, "holdout")]) if has(jobs, "holdout") else {}
            if set(best) >= {"diagonal", "full"}:
                disc = discretization_check(best["diagonal"], best["full"],
                                            info.discretization_kinds)
        row: dict[str, Any] = {
            "problem": problem, "case": case, "problem_variant": pvar,
            "question": _label(problem, case, pvar) + f" — {info.cost_label}",
            "diagonal best-known": "—" if d is None else
            f"{with_unit(d['best_known'], unit)} ({d['evidence']})",
            "full best-known": "—" if f is None else
            f"{with_unit(f['best_known'], unit)} ({f['param']}; {f['evidence']})",
            "gain": "—" if not np.isfinite(gain) else f"{fmt(gain, 3)} %",
            "equal budget": "; ".join(_budget_text(r) for r in budgets) or "—",
            "held-out": _held_text(h),
            "discretization": "—" if disc is None else disc["verdict"],
            "diag_cost": np.nan if d is None else d["best_known"],
            "full_cost": np.nan if f is None else f["best_known"],
            "diag_level": None if d is None else d["level"],
            "full_level": None if f is None else f["level"],
            "gain_pct": gain, "unit": unit}
        row["sentence"] = sentence(row, d, f, budgets, h, disc, jobs)
        rows.append(row)
    return pd.DataFrame(rows)


def _evidence_words(d: Any, f: Any) -> str:
    levels = (d["level"], f["level"])
    if levels == ("certified", "certified"):
        return "both certified"
    return f"diagonal value: {d['evidence']}; full value: {f['evidence']}"


def training_words(jobs: pd.DataFrame) -> str:
    """What a verdict's gain was measured on: ``the training scenario``, or for a problem
    variant tuned on several (``train_scenarios``, ``train_sample``) e.g. ``the training
    scenarios (mean of 8)`` — the cost the optimizers minimized."""
    params = jobs["problem_params"].dropna() if "problem_params" in jobs else pd.Series()
    training = training_of(params.iloc[0]) if len(params) else {}
    if not training:
        return "the training scenario"
    return f"the training scenarios ({aggregate_label(training)})"


def sentence(row: dict, d: Any, f: Any, budgets: list[dict], h: dict | None,
             disc: dict | None, jobs: pd.DataFrame) -> str:
    """The answer of one verdict row in words, with its hedge."""
    label = _label(row["problem"], row["case"], row["problem_variant"])
    if d is None or f is None:
        have = "diagonal" if f is None else "full"
        return f"**{label}**: only {have} starts converged or ran: no comparison."
    gain = row["gain_pct"]
    evidence = _evidence_words(d, f)
    trained = training_words(jobs)
    if abs(gain) <= 100.0 * CERTIFY_RTOL:
        head = (f"full and diagonal reach the same best-known cost within {CERTIFY_RTOL:g} "
                f"({evidence})")
    elif gain > 0:
        head = (f"on {trained} the best-known full cost is {fmt(gain, 3)} % below "
                f"the diagonal's ({with_unit(d['best_known'], row['unit'])} → "
                f"{with_unit(f['best_known'], row['unit'])}; {evidence})")
    else:
        head = (f"full is {fmt(-gain, 3)} % worse on {trained} ({evidence}); the "
                "diagonal set lies inside the full set, so this is an optimizer shortfall, "
                f"not a property of the map ({stop_advice(jobs[jobs['param'] != 'diagonal'])})")
    parts = [head]
    if h is not None and h["scenarios"] and h["n_ratio"]:
        p = h["ratio_p_holm"]
        if np.isfinite(p) and p < ALPHA and h["ratio_median"] > 1.0:
            parts.append(("but " if gain > 0 else "and ") + "from the held-out scenarios full "
                         f"costs more ({ratio_words(h)})" +
                         (f": the gain is specific to {trained}" if gain > 0
                          else ""))
        elif np.isfinite(p) and p < ALPHA:
            parts.append(f"and from the held-out scenarios full costs less "
                         f"({ratio_words(h)}): the gain holds off {trained}")
        else:
            parts.append("on the held-out scenarios there is no evidence of a difference "
                         f"({ratio_words(h)})")
        parts.append(horizon_words(h))
    elif h is not None and h["scenarios"]:
        parts.append(f"no held-out scenario has a positive finite cost under both matrices "
                     f"({horizon_words(h)})")
    else:
        parts.append("no held-out result")
    tested = [r for r in budgets if r["equal_budget"] and np.isfinite(r["p_mwu"])]
    if tested:  # every test, not only the most significant one
        each = [f"{fmt(r['a12_b_beats_a'], 2)} ({_test_label(r, tested)}, "
                f"n = {r['n_a']}/{r['n_b']}, Holm p {_p(r['p_holm'])})"
                for r in sorted(tested, key=lambda r: (str(r["optimizer"]), str(r["map_b"]),
                                                       str(r["variant"])))]
        parts.append("at equal budget a full start beats a diagonal start with probability "
                     "A12 = " + ", ".join(each))
    elif budgets:
        parts.append("no equal-budget test (" + (
            "budgets differ" if not any(r["equal_budget"] for r in budgets)
            else "too few converged starts") + ")")
    if d["level"] in ("single optimizer", "first-order certified local optimum"):
        parts.append("the diagonal value rests on a single optimizer: run `optimizer=grid` "
                     "or a second optimizer before calling the gain a property of the map")
    if disc is not None and disc["verdict"] == "within discretization noise":
        spread = np.nanmax([disc["diag_spread"], disc["full_spread"]])
        parts.append(f"the saving is within discretization noise (spread "
                     f"{with_unit(spread, row['unit'], 3)})")
    return f"**{label}**: " + "; ".join(parts) + "."


#: Stop reason → the settings that may have stopped the search (first one present in the
#: optimizer's settings is named).
STOP_SETTINGS = {
    "iters": ("max_iterations", "iters", "maxiter"),
    "ftol": ("max_stall_iterations", "function_tolerance", "ftol", "ftol_iter", "tol"),
    "max_evals": ("max_evals",),
    "restarts": ("restarts",),
}
STOP_WORDS = {"iters": "the iteration limit", "ftol": "the stall rule",
              "max_evals": "the evaluation budget", "restarts": "the restart limit"}


def stop_setting(reason: str, settings: dict[str, Any]) -> str:
    """The setting that stopped a search, e.g. ``optimizer.iters`` (``iters`` stop of
    PSO) or ``optimizer.max_iterations`` (pso_matlab); the stall rule names its keys."""
    base = final_search_stop(reason)
    keys = STOP_SETTINGS.get(base)
    if keys is None:
        return f"stop reason {reason!r}"
    present = [k for k in keys if k in settings] or list(keys[:1])
    if base == "ftol":
        return "the stall rule (" + ", ".join(f"`optimizer.{k}`" for k in present) + ")"
    return f"{STOP_WORDS[base]} (`optimizer.{present[0]}`)"


def stop_advice(rows: pd.DataFrame) -> str:
    """Which settings stopped the starts of ``rows``, e.g. "stopped by the iteration limit
    (`optimizer.iters`) in 4 of 4 starts: raise it". Starts are grouped by what stopped
    the search; how a polish after it ended (``+polish…``) does not split a group."""
    if rows.empty or "stop_reason" not in rows:
        return "stop reasons not recorded"
    parts = []
    rows = rows[rows["optimizer"] != "baseline"]
    totals = rows["optimizer"].value_counts()
    search_stop = rows["stop_reason"].fillna("?").astype(str).map(final_search_stop)
    for (opt, reason), g in rows.groupby(["optimizer", search_stop]):
        total = int(totals[opt])
        settings = protocol.params_of(g["optimizer_settings"].iloc[0]) \
            if "optimizer_settings" in g else {}
        parts.append(f"{opt}: {stop_setting(reason, settings)} in {len(g)} of {total} starts")
    return "stopped by " + "; ".join(parts) + "; raise that setting"


__all__ = ["COLUMNS", "sentence", "stop_advice", "stop_setting", "verdict_rows"]
