"""Cells (variants) and per-cell statistics of a results DataFrame.

Conventions (docs: explanation/statistics.md): cost statistics use converged starts only (status
``ok`` and ``best_converged``), the success rate stands beside them; confidence intervals
are BCa bootstrap intervals from :func:`scipy.stats.bootstrap`; the effect size is
Vargha–Delaney A12 from the Mann–Whitney U statistic; multiple comparisons are corrected
with Holm's step-down procedure.
"""

from __future__ import annotations

import json
import warnings
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from penaltyrun.io import decode_json
from penaltyrun.jobrecord import DIVERGED, NO_RESULT_STATUSES, OK
from penaltyrun.report.rows import groups

CELL = ["problem", "case", "variant", "optimizer", "param"]
#: Per-group size below which a rank test is reported as underpowered.
MIN_N_TEST = 10
#: Relative spread below which a sample is treated as constant (no interval, no test).
DEGENERATE_RTOL = 1e-9
#: Largest sample with BCa bootstrap intervals (the bootstrap evaluates the statistic on
#: 9999 resamples of n values, O(n) each); beyond this n the intervals are the distribution-free
#: order-statistic interval of the median and Student's t interval of the mean
#: (:func:`large_sample_ci`), which BCa approaches as n grows.
BCA_MAX_N = 5000
#: Most values one vectorized bootstrap call holds (resamples × sample size, 8 bytes each):
#: a larger sample is resampled in batches of about this many
#: values, so a cell's interval needs a bounded amount of memory (a few copies of one
#: batch). Batches hold an even number of resamples, so the generator's stream, and the
#: interval, are the same as in one call.
BOOTSTRAP_BATCH_VALUES = 5_000_000
#: Largest number of paired differences for which scipy's Wilcoxon signed-rank test, given
#: ties or zeros, enumerates every sign pattern (2^13 is under its 9 999 resamples); above
#: it scipy uses the normal approximation (:func:`signed_rank_p`).
EXACT_FLIP_MAX = 13
#: |A12 − 0.5| thresholds of the magnitude labels (Vargha & Delaney 2000).
A12_THRESHOLDS = ((0.21, "large"), (0.14, "medium"), (0.06, "small"))


def add_variant(df: pd.DataFrame) -> pd.DataFrame:
    """Add ``variant`` (and ``problem_variant``) columns so that cells run with other settings
    are never pooled.

    ``problem_variant`` lists the problem parameters that differ from the case's defaults
    (e.g. ``objective=min_fuel``): jobs with equal ``problem_variant`` solve the same
    problem, so best-known optima are taken over them. ``variant`` adds a warm start
    (``warm_start=0.3``; the diagonal cell run beside warm-started full cells gets it too,
    :func:`_join_warm_diagonals`) and, within one optimizer, other optimizer settings
    (budgets).

    A problem's ``VARIANT_IGNORE`` names parameters of its held-out evaluation, which do
    not change what a run tunes; one of them that shapes the training scenarios a run
    draws (``train_sample``: an attitude problem perturbs its case's state by the held-out
    sizes) does, and is part of the label (:func:`_shapes_training`).

    Nothing named in the data is imported (:mod:`penaltyrun.problems.trust`): a problem
    whose module is not imported gets its label from the stored parameters alone.
    """
    from dataclasses import asdict

    from penaltyrun.report import protocol

    labels: dict[tuple[str, str, str], str] = {}
    keys = df[["problem", "case", "problem_params"]].drop_duplicates()
    for key in keys.itertuples(index=False):
        problem, case, params = key
        mod = protocol.module(problem)
        try:
            if mod is None:
                raise LookupError(problem)
            ignore = getattr(mod, "VARIANT_IGNORE", ())
            default = asdict(protocol.make(problem, case, {}).params)
            built = protocol.make(problem, case, params)
            used = asdict(built.params)
            diff = [f"{k}={used[k]}" for k in sorted(used)
                    if used[k] != default[k] and (
                        k not in ignore or _shapes_training(built, problem, case, params, k,
                                                            default[k]))]
            labels[key] = ",".join(diff)
        except Exception:  # module not importable, or old parameters: label from the data
            same = keys[(keys["problem"] == problem) & (keys["case"] == case)]
            labels[key] = _raw_label(params, list(same["problem_params"]))
    out = df.copy(deep=False)  # new columns only: the frame itself is not copied
    out["problem_variant"] = [labels[k] for k in zip(df["problem"], df["case"],
                                                     df["problem_params"])]
    warm = out["warm_start"] if "warm_start" in out else pd.Series(None, index=out.index)
    out["variant"] = [",".join(part for part in (v, _warm_label(w)) if part)
                      for v, w in zip(out["problem_variant"], warm)]
    return _add_budget_variant(_join_warm_diagonals(out))


def _shapes_training(built: Any, problem: str, case: str, params: Any, key: str,
                     default: Any) -> bool:
    """Whether the problem parameter ``key`` shapes the training scenarios that ``built``
    (rebuilt from the stored ``params``) drew: the scenarios it draws with ``key`` at its
    ``default`` differ. False for a problem that drew none (no ``train_sample``)."""
    from penaltyrun.report import protocol

    drawn = getattr(built, "overrides", None)
    if not getattr(built.params, "train_sample", 0) or drawn is None:
        return False
    other = protocol.make(problem, case, {**protocol.params_of(params), key: default})
    return getattr(other, "overrides", None) != drawn


def _raw_label(params: Any, all_params: list[Any]) -> str:
    """Variant label from the stored overrides alone: the keys whose values differ between
    the jobs of one problem case (``""`` when they all ran with the same overrides)."""
    dicts = [decode_json(p) or {} if isinstance(p, str) else (p or {}) for p in all_params]
    own = decode_json(params) or {} if isinstance(params, str) else (params or {})
    keys = sorted({k for d in dicts for k in d})
    varying = [k for k in keys if len({json.dumps(d.get(k), sort_keys=True, default=str)
                                       for d in dicts}) > 1]
    return ",".join(f"{k}={own.get(k)}" for k in varying)


def _warm_label(warm_json: Any) -> str:
    """``warm_start=<share>`` for a warm-started full job, else ``""``."""
    warm = decode_json(warm_json) if isinstance(warm_json, str) else warm_json
    if not isinstance(warm, dict) or not warm:  # None, NaN of older files, JSON null
        return ""
    return f"warm_start={warm.get('share', '?')}"


def _join_warm_diagonals(df: pd.DataFrame) -> pd.DataFrame:
    """A diagonal cell run beside warm-started full cells joins their variant.

    ``runner.warm_start`` warm-starts the full maps only: a full job spends a share of its
    budget on the diagonal map and the rest on the full map from the diagonal best, while
    a diagonal job of the same run spends the whole budget on the diagonal map. The two
    are the comparison the warm start asks for (full against diagonal at one total
    budget), so where the jobs of one problem, case, problem variant, optimizer and
    optimizer settings hold diagonal starts, full starts all warm-started with one share
    and no full start without a warm start, the diagonal starts get that share's label
    too. Anything else (full starts with and without a warm start, or two shares) keeps
    the diagonal starts in the variant without a warm start.
    """
    if "warm_start" not in df or df.empty:
        return df
    settings = (df["optimizer_settings"].map(_canonical) if "optimizer_settings" in df
                else pd.Series("", index=df.index))
    diagonal = (df["param"] == "diagonal") & (df["variant"] == df["problem_variant"])
    variant = df["variant"].copy()
    keys = [df["problem"], df["case"], df["problem_variant"], df["optimizer"], settings]
    used = df[["param", "variant", "problem_variant"]]  # a groupby copies what it groups
    for _, g in used.groupby(keys, sort=False):
        labels = set(g.loc[g["param"] != "diagonal", "variant"])
        own = diagonal[g.index]
        if own.any() and len(labels) == 1 and labels != {g["problem_variant"].iloc[0]}:
            variant[g.index[own]] = labels.pop()
    if variant.equals(df["variant"]):
        return df
    out = df.copy(deep=False)
    out["variant"] = variant
    return out


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
    out = df.copy(deep=False)
    out["variant"] = [",".join(part for part in (v, b) if part)
                      for v, b in zip(df["variant"], suffix)]
    return out


def converged(df: pd.DataFrame) -> pd.Series:
    """Boolean mask of converged starts: status ``ok`` and a converged best candidate.

    A ``diverged`` start (its best cost is a graded penalty) and a ``failed`` start (no
    cost) are failures: they count in the success rate, never in a cost statistic.
    """
    best = df["best_converged"] if "best_converged" in df else pd.Series(True, index=df.index)
    return (df["status"] == OK) & best.fillna(False).astype(bool)


def bca_ci(values: np.ndarray, statistic: str = "median", level: float = 0.95,
           n_resamples: int = 9999, seed: int = 0) -> tuple[float, float, str]:
    """BCa bootstrap confidence interval, the interval of :func:`scipy.stats.bootstrap`
    (``method='BCa'``, same resamples for the same seed); for more than :data:`BCA_MAX_N`
    values, :func:`large_sample_ci`.

    The bootstrap distribution is scipy's (the same generator calls, in batches of
    :data:`BOOTSTRAP_BATCH_VALUES` values so that memory stays bounded); the acceleration's
    jackknife uses the closed forms of :func:`jackknife_values` (O(n log n)) instead of
    evaluating the statistic on n samples of n − 1 values (O(n²)).

    Parameters
    ----------
    values : ndarray, shape (n,)
        One sample (converged costs of one cell).
    statistic : {"median", "mean"}
        Statistic whose interval is wanted.
    level : float
        Confidence level.
    n_resamples : int
        Bootstrap resamples.
    seed : int
        Seed of the resampling generator (same seed, same interval).

    Returns
    -------
    lo, hi : float
        Interval bounds, NaN when no interval is defined.
    note : str
        Why the interval is NaN (``n < 3``, ``constant sample``, or the numerical reason),
        else ``""``.
    """
    x = np.asarray(values, float)
    if x.size < 3:
        return float("nan"), float("nan"), f"n = {x.size} < 3: no CI"
    if np.ptp(x) <= DEGENERATE_RTOL * max(1.0, float(np.max(np.abs(x)))):
        return float("nan"), float("nan"), "constant sample: no CI"
    if x.size > BCA_MAX_N:
        return large_sample_ci(x, statistic, level)
    func = {"median": np.median, "mean": np.mean}[statistic]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        dist = _bootstrap_distribution(x, func, n_resamples, np.random.default_rng(seed))
        p_lo, p_hi = _bca_levels(x, func(x), statistic, dist, (1.0 - level) / 2)
        ci = stats.quantile(dist, np.array([p_lo, p_hi]))
    lo, hi = float(ci[0]), float(ci[1])
    if not (np.isfinite(lo) and np.isfinite(hi)):
        reason = str(caught[0].message).split(".")[0] if caught else "degenerate bootstrap"
        return float("nan"), float("nan"), f"BCa undefined ({reason})"
    return lo, hi, ""


def _bootstrap_distribution(x: np.ndarray, func: Any, n_resamples: int,
                            rng: np.random.Generator) -> np.ndarray:
    """The statistic of ``n_resamples`` resamples of ``x`` with replacement, drawn as
    :func:`scipy.stats.bootstrap` draws them (``rng.integers(0, n, (batch, n))`` per batch),
    in batches of an even number of resamples holding about
    :data:`BOOTSTRAP_BATCH_VALUES` values (the stream does not depend on the batch)."""
    n = x.size
    batch = n_resamples
    if n * n_resamples > BOOTSTRAP_BATCH_VALUES:
        batch = max(2, BOOTSTRAP_BATCH_VALUES // n // 2 * 2)
    out = np.empty(n_resamples)
    for k in range(0, n_resamples, batch):
        m = min(batch, n_resamples - k)
        out[k:k + m] = func(x[rng.integers(0, n, (m, n))], axis=-1)
    return out


def jackknife_values(x: np.ndarray, statistic: str) -> np.ndarray:
    """The statistic of each leave-one-out sample ``x`` without ``x[i]``, in closed form.

    The mean's is (Σx − xᵢ) / (n − 1). The median's depends only on the rank r of xᵢ in
    the sorted sample s: removing it shifts the order statistics above r down by one, so
    for odd n − 1 (k = (n − 2) / 2) the median is s[k] when r > k and s[k + 1] otherwise,
    and for even n − 1 (k = (n − 1) / 2) it is the mean of the two middle values chosen
    the same way. Ties give the same value whichever tied element is removed.

    Parameters
    ----------
    x : ndarray, shape (n,)
        The sample, n ≥ 2.
    statistic : {"median", "mean"}

    Returns
    -------
    ndarray, shape (n,)
        Element i is the statistic of x with element i left out.
    """
    x = np.asarray(x, float)
    n = x.size
    if statistic == "mean":
        return (np.sum(x) - x) / (n - 1)
    order = np.argsort(x, kind="stable")
    s = x[order]
    rank = np.empty(n, dtype=np.intp)
    rank[order] = np.arange(n)
    m = n - 1
    k = m // 2
    upper = np.where(rank > k, s[k], s[k + 1])
    if m % 2:
        return upper
    lower = np.where(rank > k - 1, s[k - 1], s[k])
    return np.mean(np.stack([lower, upper]), axis=0)


def _bca_levels(x: np.ndarray, theta: float, statistic: str, dist: np.ndarray,
                alpha: float) -> tuple[float, float]:
    """BCa's adjusted percentile levels (Efron & Tibshirani 1993, 14.3 and eq. 15.36),
    with scipy's conventions: the bias correction from the share of the bootstrap
    distribution below the estimate ``theta`` (ties counted half), the acceleration from
    the jackknife values of :func:`jackknife_values`."""
    from scipy.special import ndtr, ndtri

    share = (np.count_nonzero(dist < theta) + np.count_nonzero(dist <= theta)) / (2 * dist.size)
    z0 = ndtri(np.float64(share))
    jack = jackknife_values(x, statistic)
    n = float(jack.size)
    u = (n - 1) * (np.mean(jack) - jack)
    a_hat = 1 / 6 * (np.sum(u**3) / n**3) / (np.sum(u**2) / n**2) ** (3 / 2)
    z_alpha = float(ndtri(alpha))
    num1, num2 = z0 + z_alpha, z0 - z_alpha
    return ndtr(z0 + num1 / (1 - a_hat * num1)), ndtr(z0 + num2 / (1 - a_hat * num2))


def a12(x: np.ndarray, y: np.ndarray) -> float:
    """Vargha–Delaney A12 = P(X > Y) + ½ P(X = Y) from the Mann–Whitney U statistic of x.

    For costs, ``a12(cost_a, cost_b)`` is the probability that a start of b beats (is
    lower than) a start of a. NaN if a sample is empty.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    if x.size == 0 or y.size == 0:
        return float("nan")
    return float(stats.mannwhitneyu(x, y, alternative="two-sided").statistic / (x.size * y.size))


def a12_magnitude(value: float) -> str:
    """Label of |A12 − 0.5|: negligible (< 0.06), small, medium (≥ 0.14), large (≥ 0.21)."""
    if not np.isfinite(value):
        return "—"
    d = round(abs(value - 0.5), 12)  # 0.71 − 0.5 is 0.2099…9 in binary
    return next((label for bound, label in A12_THRESHOLDS if d >= bound), "negligible")


def holm(p_values: np.ndarray) -> np.ndarray:
    """Holm (1979) step-down adjusted p-values; NaN entries stay NaN and are not counted.

    scipy.stats has no Holm correction (``false_discovery_control`` is Benjamini–Hochberg),
    so the formula is written out: with the m finite p-values sorted ascending,
    p̃_(i) = max_{j ≤ i} min(1, (m − j + 1) · p_(j)).
    """
    p = np.asarray(p_values, float)
    out = np.full(p.shape, np.nan)
    idx = np.flatnonzero(np.isfinite(p))
    m = idx.size
    if m == 0:
        return out
    order = idx[np.argsort(p[idx], kind="stable")]
    scaled = np.minimum(1.0, (m - np.arange(m)) * p[order])
    out[order] = np.maximum.accumulate(scaled)
    return out


def signed_rank_p(d: np.ndarray) -> float:
    """Two-sided Wilcoxon signed-rank p-value of the paired differences ``d``, zeros dropped
    (Wilcoxon's method): the value of ``scipy.stats.wilcoxon(d, zero_method="wilcox")``.

    With ties or zeros among at most :data:`EXACT_FLIP_MAX` differences, scipy runs an exact
    permutation test that evaluates the statistic once per sign pattern in a Python loop
    (about 0.7 s at n = 12); here the 2^m patterns of the m nonzero differences are summed
    in one matrix product, with scipy's comparison tolerance, so the p-value is the same.
    Every other sample goes to scipy itself. NaN when no difference is nonzero.
    """
    d = np.asarray(d, float).ravel()
    nonzero = d[d != 0.0]
    if not nonzero.size:
        return float("nan")
    ranks = stats.rankdata(np.abs(nonzero))
    tied = np.unique(ranks).size < ranks.size
    if d.size > EXACT_FLIP_MAX or not (tied or nonzero.size < d.size):
        return float(stats.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue)
    m = nonzero.size
    positive = (np.arange(2**m)[:, None] >> np.arange(m)) & 1  # every sign pattern
    null = positive @ ranks
    observed = float(ranks[nonzero > 0.0].sum())
    gamma = abs(100 * np.finfo(float).eps * observed)
    less = np.mean(null <= observed + gamma)
    greater = np.mean(null >= observed - gamma)
    return float(np.clip(2.0 * min(less, greater), 0.0, 1.0))


def large_sample_ci(values: np.ndarray, statistic: str = "median",
                    level: float = 0.95) -> tuple[float, float, str]:
    """Confidence interval of a large sample without resampling.

    The median's is the distribution-free order-statistic interval [x₍ⱼ₎, x₍ₙ₋ⱼ₊₁₎] with
    the largest j such that 2 P(B ≤ j − 1) ≤ 1 − level, B ~ Binomial(n, ½) (coverage at
    least ``level`` for any continuous distribution); the mean's is Student's t interval
    x̄ ± t_{n−1} s / √n.

    Parameters
    ----------
    values : ndarray, shape (n,)
        One sample, n ≥ 3.
    statistic : {"median", "mean"}
    level : float
        Confidence level.

    Returns
    -------
    lo, hi : float
        Interval bounds.
    note : str
        ``""``.
    """
    x = np.sort(np.asarray(values, float))
    n = x.size
    alpha = 1.0 - level
    if statistic == "mean":
        half = stats.t.ppf(1.0 - alpha / 2, n - 1) * np.std(x, ddof=1) / np.sqrt(n)
        return float(np.mean(x) - half), float(np.mean(x) + half), ""
    k = int(stats.binom.ppf(alpha / 2, n, 0.5))  # smallest k with P(B <= k) >= alpha/2
    if stats.binom.cdf(k, n, 0.5) > alpha / 2:
        k -= 1
    k = max(k, 0)  # j - 1 = k: P(B <= j - 1) <= alpha/2
    return float(x[k]), float(x[n - 1 - k]), ""


def cell_summary(df: pd.DataFrame, seed: int = 0) -> pd.DataFrame:
    """One row per cell (problem, case, variant, optimizer, param).

    ``n_jobs`` counts every start, ``n_converged`` the converged ones, ``success_rate`` is
    their share. best / median / mean / worst / std and the BCa 95 % intervals of the
    median and the mean use converged starts only; ``ci_note`` says why an interval is
    missing. Evaluations and wall time are means over all starts that produced a result;
    ``n_failed`` counts those that did not (``failed`` and ``timeout``).
    """
    if "variant" not in df:
        df = df.assign(variant="")
    ok_mask = converged(df)
    rows = []
    for key, g in groups(df, CELL):
        cost = g.loc[ok_mask[g.index], "best_cost"].astype(float).to_numpy()
        mlo, mhi, note = bca_ci(cost, "median", seed=seed)
        alo, ahi, _ = bca_ci(cost, "mean", seed=seed)
        ran = g[~g["status"].isin(NO_RESULT_STATUSES)]
        rows.append({
            **dict(zip(CELL, key)),
            "n_jobs": len(g), "n_converged": int(cost.size),
            "n_diverged": int((g["status"] == DIVERGED).sum()),
            "n_failed": int(g["status"].isin(NO_RESULT_STATUSES).sum()),
            "success_rate": cost.size / len(g),
            "best": float(np.min(cost)) if cost.size else np.nan,
            "median": float(np.median(cost)) if cost.size else np.nan,
            "median_ci95_lo": mlo, "median_ci95_hi": mhi,
            "mean": float(np.mean(cost)) if cost.size else np.nan,
            "mean_ci95_lo": alo, "mean_ci95_hi": ahi,
            "worst": float(np.max(cost)) if cost.size else np.nan,
            "std": float(np.std(cost, ddof=1)) if cost.size > 1 else np.nan,
            "ci_note": note,
            "max_evals": _max_evals(g),
            "mean_evals": float(ran["n_evals"].mean()) if len(ran) else np.nan,
            "mean_wall_s": float(ran["wall_time_s"].mean()) if len(ran) else np.nan,
            "paper_mean": paper_mean(g, key[CELL.index("param")]),
        })
    return pd.DataFrame(rows)


def _max_evals(g: pd.DataFrame) -> float:
    """The cell's evaluation budget (NaN without one or in results before budgets)."""
    if "max_evals" not in g:
        return float("nan")
    values = pd.to_numeric(g["max_evals"], errors="coerce").dropna().unique()
    return float(values[0]) if values.size == 1 else float("nan")


def paper_value(paper: Any, param: str, kind: str = "mean_cost") -> float:
    """A published value for one map (``kind``: ``mean_cost`` or ``median_cost``) from a
    problem's :class:`~penaltyrun.problems.base.PaperValues`; NaN where it has none. A
    specific map's value takes precedence over the ``full`` family's."""
    values = getattr(paper, kind, None) or {}
    if param in values:
        return float(values[param])
    if param != "diagonal" and "full" in values and param in ("full", "geagsp"):
        return float(values["full"])
    return float("nan")


def paper_mean(g: pd.DataFrame, param: str) -> float:
    """The paper's mean cost of a cell (NaN where the problem declares none)."""
    from penaltyrun.report import protocol

    return paper_value(protocol.info_of(g).paper, param)
