"""Map-vs-map comparisons at equal budget: two-sided Mann–Whitney U, A12, Holm.

The confidence interval of A12 (:func:`a12_interval`) is the Brunner–Munzel (2000)
interval of the relative effect: its rank-based variance estimate with a Welch–
Satterthwaite t quantile, the interval behind :func:`scipy.stats.brunnermunzel`.

Every comparison is between two maps of one cell group — the same problem, case, variant
(problem parameters, warm start, optimizer settings and so the budget) and optimizer. No
comparison pools optimizers, budgets or variants. Costs are those of converged starts only.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
from scipy import stats

from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.report.rows import groups
from penaltyrun.report.stats import MIN_N_TEST, a12, a12_magnitude, converged, holm

GROUP = ["problem", "case", "variant", "optimizer"]
#: Display order of the maps (others follow alphabetically).
MAP_ORDER = ("diagonal", "full", "geagsp", "givens", "cayley", "cayley_tan")
#: Holm family named in the report text.
FAMILY = ("every equal-budget map-vs-map Mann–Whitney test of this report (all problems, "
          "cases, variants and optimizers together)")
#: Relative difference of the mean evaluations the searches spent within which two cells'
#: budgets are equal (their ``max_evals`` must be equal too).
SPENT_RTOL = 0.01
NO_TEST = "budgets differ: no test"


def budget(sel: pd.DataFrame) -> tuple[float, float]:
    """(``max_evals`` of a cell, NaN when none or mixed; mean evaluations its non-failed
    starts' searches spent).

    A polish (``optimizer.polish``) is left out of the spend (``n_evals`` less
    ``polish_evals``): it refines the search's best within the same cap and ends when it
    converges, so its spend differs between maps by design. Both cells still had the
    same ``max_evals``; the report states the polish's mean spend apart
    (:func:`polish_spend`)."""
    cap = np.nan
    if "max_evals" in sel:
        values = pd.to_numeric(sel["max_evals"], errors="coerce").dropna().unique()
        cap = float(values[0]) if values.size == 1 else np.nan
    ran = _ran(sel)
    spent = float((pd.to_numeric(ran["n_evals"], errors="coerce")
                   - polish_column(ran)).mean()) if "n_evals" in ran and len(ran) else np.nan
    return cap, spent


def _ran(sel: pd.DataFrame) -> pd.DataFrame:
    """The starts of ``sel`` that produced a result."""
    return sel[~sel["status"].isin(NO_RESULT_STATUSES)]


def polish_column(sel: pd.DataFrame) -> pd.Series:
    """Evaluations each start's polish spent (0 where none or not recorded)."""
    if "polish_evals" not in sel:
        return pd.Series(0.0, index=sel.index)
    return pd.to_numeric(sel["polish_evals"], errors="coerce").fillna(0.0)


def polish_spend(sel: pd.DataFrame) -> float:
    """Mean evaluations the polish spent over a cell's non-failed starts (NaN: none)."""
    ran = _ran(sel)
    spend = polish_column(ran)
    return float(spend.mean()) if len(ran) and spend.any() else np.nan


def equal_budget(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Two cells have equal budgets: equal ``max_evals`` (or none for both) and mean
    evaluations their searches spent (:func:`budget`) within :data:`SPENT_RTOL` of each
    other."""
    (cap_a, spent_a), (cap_b, spent_b) = a, b
    same_cap = (np.isnan(cap_a) and np.isnan(cap_b)) or cap_a == cap_b
    if not same_cap or not (np.isfinite(spent_a) and np.isfinite(spent_b)):
        return False
    return abs(spent_a - spent_b) <= SPENT_RTOL * max(spent_a, spent_b)


def map_order(params: list[str] | np.ndarray) -> list[str]:
    """Maps sorted diagonal, full, geagsp, givens, cayley, cayley_tan, then any other
    alphabetically."""
    rank = {m: i for i, m in enumerate(MAP_ORDER)}
    return sorted(set(params), key=lambda m: (rank.get(m, len(rank)), m))


def _costs(g: pd.DataFrame, param: str) -> tuple[np.ndarray, int]:
    sel = g[g["param"] == param]
    return sel.loc[converged(sel), "best_cost"].astype(float).to_numpy(), len(sel)


def pairwise(df: pd.DataFrame) -> pd.DataFrame:
    """Every pair of maps within each (problem, case, variant, optimizer).

    For the pair (a, b): converged counts and success rates, medians, the change of the
    median ``(median_a − median_b)/median_a`` in % (positive: b is lower), A12 = P(b start
    beats an a start) (+ ½ ties) with its magnitude, the two-sided Mann–Whitney U p-value,
    the Holm-adjusted p over all rows with a p-value, and a note when a group has fewer
    than :data:`~penaltyrun.report.stats.MIN_N_TEST` converged starts (underpowered). Only
    cells with equal budgets (:func:`equal_budget`) are tested; the others say
    :data:`NO_TEST`. With
    fewer than 2 converged starts in a group (e.g. the deterministic grid optimizer) there
    is no test and the row is not in the Holm family.
    """
    if "variant" not in df:
        df = df.assign(variant="")
    rows = []
    for key, g in groups(df[df["optimizer"] != "baseline"], GROUP):
        for a, b in itertools.combinations(map_order(g["param"].unique()), 2):
            xa, na = _costs(g, a)
            xb, nb = _costs(g, b)
            sel_a, sel_b = g[g["param"] == a], g[g["param"] == b]
            ba, bb = budget(sel_a), budget(sel_b)
            equal = equal_budget(ba, bb)
            p = np.nan
            if equal and min(xa.size, xb.size) >= 2:
                p = float(stats.mannwhitneyu(xa, xb, alternative="two-sided").pvalue)
            effect = a12(xa, xb) if equal else np.nan
            med_a = float(np.median(xa)) if xa.size else np.nan
            med_b = float(np.median(xb)) if xb.size else np.nan
            notes = [] if equal else [NO_TEST]
            if equal and min(xa.size, xb.size) < MIN_N_TEST:
                notes.append(f"underpowered (n < {MIN_N_TEST})")
            if equal and min(xa.size, xb.size) < 2:
                notes.append("fewer than 2 converged starts in a group: no test")
            rows.append({
                **dict(zip(GROUP, key)), "map_a": a, "map_b": b,
                "problem_variant": str(g["problem_variant"].iloc[0])
                if "problem_variant" in g else key[GROUP.index("variant")],
                "n_a": int(xa.size), "n_b": int(xb.size), "jobs_a": na, "jobs_b": nb,
                "max_evals_a": ba[0], "max_evals_b": bb[0], "evals_a": ba[1],
                "evals_b": bb[1], "polish_evals_a": polish_spend(sel_a),
                "polish_evals_b": polish_spend(sel_b), "equal_budget": equal,
                "success_a": xa.size / na, "success_b": xb.size / nb,
                "best_a": float(xa.min()) if xa.size else np.nan,
                "best_b": float(xb.min()) if xb.size else np.nan,
                "median_a": med_a, "median_b": med_b,
                "median_change_pct": 100.0 * (med_a - med_b) / med_a,
                "a12_b_beats_a": effect, "a12_magnitude": a12_magnitude(effect),
                "p_mwu": p, "note": "; ".join(notes),
            })
    out = pd.DataFrame(rows)
    if not out.empty:
        out.insert(out.columns.get_loc("p_mwu") + 1, "p_holm", holm(out["p_mwu"].to_numpy()))
    return out


def a12_interval(cost_a: np.ndarray, cost_b: np.ndarray,
                 level: float = 0.95) -> tuple[float, float, float, str]:
    """A12 = P(a start of b beats a start of a) + ½ P(tie) with its Brunner–Munzel interval.

    Brunner & Munzel (2000, Biometrical Journal 42, 17–25): with combined midranks R and
    midranks R⁽ⁱ⁾ within each sample, S_i² = Σ_k (R_ik − R⁽ⁱ⁾_ik − R̄_i + (n_i + 1)/2)² /
    (n_i − 1), the standard error of the relative effect is √(n_a S_a² + n_b S_b²) /
    (n_a n_b) and the interval is A12 ± t_{df, (1+level)/2} · SE with the Welch–
    Satterthwaite df = (n_a S_a² + n_b S_b²)² / ((n_a S_a²)²/(n_a − 1) + (n_b S_b²)²/
    (n_b − 1)), clipped to [0, 1]. ``(A12 − ½)/SE`` and df are the statistic and degrees
    of freedom of ``scipy.stats.brunnermunzel(cost_b, cost_a)``.

    Parameters
    ----------
    cost_a, cost_b : ndarray, shape (n_a,), (n_b,)
        Costs of the converged starts of maps a and b (lower is better).
    level : float
        Confidence level.

    Returns
    -------
    a12, lo, hi : float
        The effect and its interval (lo, hi NaN when no interval is defined).
    note : str
        Why there is no interval (``n < 2``; every start of one map beats every start of
        the other, where the variance estimate is zero), else ``""``.
    """
    x, y = np.asarray(cost_b, float), np.asarray(cost_a, float)
    effect = a12(y, x)
    if min(x.size, y.size) < 2:
        return effect, np.nan, np.nan, "fewer than 2 converged starts: no interval"
    ranks = stats.rankdata(np.concatenate([x, y]))
    rx, ry = ranks[:x.size], ranks[x.size:]
    sx = np.var(rx - stats.rankdata(x), ddof=1)
    sy = np.var(ry - stats.rankdata(y), ddof=1)
    spread = x.size * sx + y.size * sy
    if spread <= 0.0:
        return effect, np.nan, np.nan, "complete separation: no interval"
    se = np.sqrt(spread) / (x.size * y.size)
    df = spread ** 2 / ((x.size * sx) ** 2 / (x.size - 1) + (y.size * sy) ** 2 / (y.size - 1))
    half = float(stats.t.ppf(0.5 + level / 2.0, df)) * se
    return effect, max(0.0, effect - half), min(1.0, effect + half), ""


def a12_intervals(df: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """:func:`a12_interval` for every equal-budget pair of :func:`pairwise` (same groups,
    same converged costs): columns of :data:`GROUP`, ``map_a``, ``map_b``, ``n_a``,
    ``n_b``, ``a12_b_beats_a``, ``a12_lo``, ``a12_hi``, ``ci_note``. Pairs whose budgets
    differ have no row."""
    if "variant" not in df:
        df = df.assign(variant="")
    rows = []
    for key, g in groups(df[df["optimizer"] != "baseline"], GROUP):
        for a, b in itertools.combinations(map_order(g["param"].unique()), 2):
            if not equal_budget(budget(g[g["param"] == a]), budget(g[g["param"] == b])):
                continue
            xa, _ = _costs(g, a)
            xb, _ = _costs(g, b)
            effect, lo, hi, note = a12_interval(xa, xb, level)
            rows.append({**dict(zip(GROUP, key)), "map_a": a, "map_b": b,
                         "n_a": int(xa.size), "n_b": int(xb.size), "a12_b_beats_a": effect,
                         "a12_lo": lo, "a12_hi": hi, "ci_note": note})
    return pd.DataFrame(rows, columns=[*GROUP, "map_a", "map_b", "n_a", "n_b",
                                       "a12_b_beats_a", "a12_lo", "a12_hi", "ci_note"])


