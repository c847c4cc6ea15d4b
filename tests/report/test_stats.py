"""Cell statistics (converged starts only, BCa intervals), A12, Holm, and table formatting."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats as sps

from penaltyrun.report.stats import (
    BOOTSTRAP_BATCH_VALUES,
    EXACT_FLIP_MAX,
    a12,
    a12_magnitude,
    add_variant,
    bca_ci,
    cell_summary,
    converged,
    holm,
    jackknife_values,
    large_sample_ci,
    signed_rank_p,
)
from penaltyrun.report.tables import fmt, markdown, write_table

PENALTY = 1000.0  # a graded penalty: must never enter a cost statistic
DIAG = [4.0, 5.0, 9.0]


def rows(param, costs, problem="toy", case="c1", optimizer="pso", statuses=None):
    statuses = statuses or ["ok"] * len(costs)
    return [{"problem": problem, "case": case, "optimizer": optimizer, "param": param,
             "best_cost": c, "status": s, "best_converged": s == "ok", "n_evals": 100 + i,
             "wall_time_s": 1.0 + i}
            for i, (c, s) in enumerate(zip(costs, statuses))]


@pytest.fixture
def df():
    data = (rows("diagonal", [4.0, 5.0, PENALTY, 9.0, np.nan],
                 statuses=["ok", "ok", "diverged", "ok", "failed"])
            + rows("geagsp", [1.0, 2.0, 3.0, PENALTY], statuses=["ok", "ok", "ok", "diverged"])
            + rows("diagonal", [10.0, 20.0], optimizer="de"))
    return pd.DataFrame(data)


def cell(summary, param, optimizer="pso"):
    sel = summary[(summary["param"] == param) & (summary["optimizer"] == optimizer)]
    assert len(sel) == 1
    return sel.iloc[0]


def test_converged_mask_needs_status_ok_and_a_converged_best():
    frame = pd.DataFrame({"status": ["ok", "ok", "diverged", "failed"],
                          "best_converged": [True, False, False, None]})
    assert converged(frame).tolist() == [True, False, False, False]


def test_cell_summary_uses_converged_starts_only(df):
    s = cell_summary(df)
    assert len(s) == 3
    d = cell(s, "diagonal")
    assert d["n_jobs"] == 5 and d["n_converged"] == 3
    assert d["n_diverged"] == 1 and d["n_failed"] == 1
    assert d["success_rate"] == pytest.approx(3 / 5)
    assert (d["best"], d["median"], d["worst"]) == (4.0, 5.0, 9.0)
    assert d["mean"] == pytest.approx(6.0)  # the diverged start's 1000 is not in it
    assert d["std"] == pytest.approx(np.std(DIAG, ddof=1))
    assert d["median_ci95_lo"] <= d["median"] <= d["median_ci95_hi"] <= 9.0
    assert d["mean_ci95_lo"] <= d["mean"] <= d["mean_ci95_hi"] <= 9.0
    assert d["mean_evals"] == pytest.approx(np.mean([100, 101, 102, 103]))  # failed: no evals
    g = cell(s, "geagsp")
    assert (g["best"], g["mean"], g["median"], g["worst"]) == (1.0, 2.0, 2.0, 3.0)
    assert g["success_rate"] == pytest.approx(0.75)
    de = cell(s, "diagonal", "de")
    assert de["mean"] == 15.0 and de["n_jobs"] == 2
    assert math.isnan(de["median_ci95_lo"]) and de["ci_note"] == "n = 2 < 3: no CI"
    assert math.isnan(de["paper_mean"])  # no paper number for the toy problem


def test_cell_summary_all_diverged_or_failed():
    frame = pd.DataFrame(rows("diagonal", [PENALTY, PENALTY], statuses=["diverged"] * 2)
                         + rows("geagsp", [np.nan], statuses=["failed"]))
    s = cell_summary(frame)
    d = cell(s, "diagonal")
    assert d["success_rate"] == 0.0 and d["n_converged"] == 0
    assert all(math.isnan(d[k]) for k in ("best", "median", "mean", "worst", "std"))
    assert cell(s, "geagsp")["n_failed"] == 1


def test_cell_summary_separates_variants(df):
    df = df.assign(variant="")
    df.loc[df.index[:2], "variant"] = "objective=min_fuel"
    s = cell_summary(df)
    diag_pso = s[(s["param"] == "diagonal") & (s["optimizer"] == "pso")]
    assert sorted(diag_pso["n_jobs"]) == [2, 3]


def test_cell_summary_paper_mean_uses_the_parameterization():
    frame = pd.DataFrame(rows("diagonal", [0.5, 0.4], problem="attitude_lqr", case="detumble")
                         + rows("geagsp", [0.2, 0.1], problem="attitude_lqr", case="detumble"))
    s = cell_summary(frame)
    assert cell(s, "diagonal")["paper_mean"] == pytest.approx(0.423)
    assert cell(s, "geagsp")["paper_mean"] == pytest.approx(0.146)


# --------------------------------------------------------------------------- BCa


@pytest.mark.parametrize("statistic, func", [("median", np.median), ("mean", np.mean)])
def test_bca_matches_scipy_bootstrap(statistic, func):
    x = np.random.default_rng(3).lognormal(0.0, 0.5, 15)
    lo, hi, note = bca_ci(x, statistic, seed=7)
    ref = sps.bootstrap((x,), func, method="BCa", n_resamples=9999, confidence_level=0.95,
                        rng=np.random.default_rng(7)).confidence_interval
    assert (lo, hi) == pytest.approx((ref.low, ref.high), rel=1e-12)
    assert note == ""
    assert bca_ci(x, statistic, seed=7) == (lo, hi, "")  # seeded: same interval
    lo90, hi90, _ = bca_ci(x, statistic, level=0.90, seed=7)
    assert lo <= lo90 and hi90 <= hi


def test_bca_small_and_constant_samples_are_nan_with_a_note():
    for values, note in (([], "n = 0 < 3: no CI"), ([1.0], "n = 1 < 3: no CI"),
                         ([1.0, 2.0], "n = 2 < 3: no CI"),
                         ([3.0, 3.0, 3.0, 3.0], "constant sample: no CI")):
        lo, hi, text = bca_ci(np.array(values))
        assert math.isnan(lo) and math.isnan(hi) and text == note


def test_order_statistic_interval_of_the_median_is_the_binomial_one():
    """[x_(j), x_(n-j+1)] with the largest j such that 2 P(B <= j - 1) <= 0.05: checked
    against the binomial coverage computed directly."""
    n = 6001
    x = np.random.default_rng(4).permutation(np.arange(n, dtype=float))
    lo, hi, note = large_sample_ci(x, "median")
    j = int(lo) + 1  # x holds 0 .. n-1: x_(j) = j - 1
    assert hi == n - j and note == ""
    cover = 1 - 2 * sps.binom.cdf(j - 1, n, 0.5)
    assert cover >= 0.95 and 1 - 2 * sps.binom.cdf(j, n, 0.5) < 0.95


def test_large_sample_intervals_cover_at_their_level():
    """Coverage of the median's and the mean's interval over 400 lognormal samples of
    6000 (the true median 1, the true mean e^{1/8}): within binomial error of 95 %."""
    rng = np.random.default_rng(5)
    hits = {"median": 0, "mean": 0}
    truth = {"median": 1.0, "mean": math.exp(0.125)}
    for _ in range(400):
        x = rng.lognormal(0.0, 0.5, 6000)
        for statistic in hits:
            lo, hi, _ = large_sample_ci(x, statistic)
            hits[statistic] += lo <= truth[statistic] <= hi
    for statistic, k in hits.items():
        assert 0.92 <= k / 400 <= 0.985, (statistic, k)


def test_bca_of_a_large_cell_takes_the_large_sample_interval_and_bounded_memory():
    """L3: a cell of 100 000 starts asked for one 7.45 GiB array of bootstrap indices; now
    BCa stops at BCA_MAX_N (its resamples in batches) and the large-sample interval
    allocates a few copies of the sample."""
    import tracemalloc

    rng = np.random.default_rng(6)
    big = rng.lognormal(0.0, 0.5, 100_000)
    assert bca_ci(big, "median") == large_sample_ci(big, "median")
    mid = rng.lognormal(0.0, 0.5, 3000)  # unbatched: about 590 MB
    tracemalloc.start()
    try:
        lo, hi, note = bca_ci(mid, "median")
        bca_ci(big, "mean")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert note == "" and lo < np.median(mid) < hi
    assert peak < 6 * 8 * BOOTSTRAP_BATCH_VALUES, peak / 2**20
    ref_lo, ref_hi, _ = large_sample_ci(mid, "median")
    assert abs(lo - ref_lo) < 0.05 and abs(hi - ref_hi) < 0.05  # BCa ~ order statistics


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 6), min_size=2, max_size=40), st.integers(0, 2**32 - 1))
def test_jackknife_closed_forms_are_the_naive_leave_one_out_values(ints, seed):
    """The O(n log n) leave-one-out median and O(n) mean against the statistic evaluated
    on each of the n samples of n − 1 (ties, even and odd n)."""
    x = np.asarray(ints, float) + np.random.default_rng(seed).normal(0.0, 1e-3) * \
        (np.asarray(ints) % 2)
    for statistic, func in (("median", np.median), ("mean", np.mean)):
        naive = np.array([func(np.delete(x, i)) for i in range(x.size)])
        np.testing.assert_allclose(jackknife_values(x, statistic), naive, rtol=1e-13, atol=0)


@pytest.mark.parametrize("statistic, func", [("median", np.median), ("mean", np.mean)])
def test_bca_with_closed_form_jackknife_is_scipys_interval(statistic, func):
    """Random samples (continuous, rounded to ties, and a majority of one value, where
    the median's jackknife is constant and BCa undefined): the interval, or the note, of
    scipy's BCa with its O(n²) jackknife."""
    import warnings

    rng = np.random.default_rng(11)
    for trial in range(40):
        n = int(rng.integers(3, 80))
        x = rng.lognormal(0.0, 0.5, n)
        if trial % 3 == 1:
            x = np.round(x, 1)
        if trial % 5 == 2:
            x[: n // 2 + 1] = x[0]
        if np.ptp(x) == 0:
            continue
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ref = sps.bootstrap((x,), func, method="BCa", n_resamples=999,
                                rng=np.random.default_rng(trial)).confidence_interval
        lo, hi, note = bca_ci(x, statistic, n_resamples=999, seed=trial)
        if np.isfinite(ref.low) and np.isfinite(ref.high):
            assert (lo, hi) == pytest.approx((ref.low, ref.high), rel=1e-12)
            assert note == ""
        else:
            assert math.isnan(lo) and math.isnan(hi)
            assert note == f"BCa undefined ({str(caught[0].message).split('.')[0]})"


def test_bca_of_a_batched_sample_is_scipys_batched_interval():
    """1200 values (resampled in batches of 4166): scipy's interval with that batch."""
    x = np.random.default_rng(2).lognormal(0.0, 0.5, 1200)
    lo, hi, _ = bca_ci(x, "median", seed=3)
    ref = sps.bootstrap((x,), np.median, method="BCa", batch=4166,
                        rng=np.random.default_rng(3)).confidence_interval
    assert (lo, hi) == (ref.low, ref.high)


# --------------------------------------------------------------------------- A12, Holm


def test_a12_of_known_samples():
    # pairs (x, y): x > y once (3 > 2), ties twice (2 = 2, 3 = 3) of 9 → (1 + 2/2)/9
    assert a12([1.0, 2.0, 3.0], [2.0, 3.0, 4.0]) == pytest.approx(2 / 9)
    assert a12([5.0, 6.0], [1.0, 2.0]) == 1.0
    assert a12([1.0, 2.0], [5.0, 6.0]) == 0.0
    assert a12([1.0, 1.0], [1.0]) == 0.5
    assert math.isnan(a12([], [1.0]))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(0, 5), min_size=1, max_size=8),
       st.lists(st.integers(0, 5), min_size=1, max_size=8))
def test_a12_is_the_pair_count(x, y):
    wins = sum((a > b) + 0.5 * (a == b) for a in x for b in y)
    assert a12(x, y) == pytest.approx(wins / (len(x) * len(y)))
    assert a12(x, y) + a12(y, x) == pytest.approx(1.0)


@pytest.mark.parametrize("value, label", [
    (0.5, "negligible"), (0.559, "negligible"), (0.56, "small"), (0.44, "small"),
    (0.639, "small"), (0.64, "medium"), (0.36, "medium"), (0.71, "large"), (0.0, "large"),
    (float("nan"), "—")])
def test_a12_magnitude(value, label):
    assert a12_magnitude(value) == label


def test_holm_on_known_p_values():
    # sorted 0.005·4 = 0.02, 0.01·3 = 0.03, 0.03·2 = 0.06, 0.04·1 = 0.04 → max-accumulated 0.06
    p = np.array([0.01, 0.04, 0.03, np.nan, 0.005])
    adj = holm(p)
    assert adj[[0, 1, 2, 4]] == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert math.isnan(adj[3])
    assert holm(np.array([0.5, 0.9])) == pytest.approx([1.0, 1.0])  # capped at 1
    assert holm(np.array([0.02])) == pytest.approx([0.02])
    assert holm(np.array([np.nan])).size == 1 and holm(np.array([])).size == 0


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=12))
def test_holm_properties(p):
    p = np.array(p)
    adj = holm(p)
    assert np.all(adj >= p - 1e-15) and np.all(adj <= 1.0)
    order = np.argsort(p, kind="stable")
    assert np.all(np.diff(adj[order]) >= -1e-15)  # monotone in the raw p order
    assert adj.min() == pytest.approx(min(1.0, p.size * p.min()))


# --------------------------------------------------------------------------- tables


def test_fmt():
    assert fmt(float("nan")) == "—"
    assert fmt(np.float64("nan")) == "—"
    assert fmt(1.23456789) == "1.2346"
    assert fmt(1.23456789, digits=2) == "1.2"
    assert fmt(1234567.0) == "1.2346e+06"
    assert fmt(True) == "yes" and fmt(False) == "no"
    assert fmt(3) == "3"
    assert fmt("geagsp") == "geagsp"


def test_markdown():
    df = pd.DataFrame({"param": ["diagonal", "geagsp"], "mean": [1.0 / 3.0, np.nan],
                       "n": [4, 5]})
    text = markdown(df, columns=["param", "mean"], headers=["Map", "Mean J"], digits=3)
    lines = text.splitlines()
    assert lines == ["| Map | Mean J |", "|---|---|", "| diagonal | 0.333 |",
                     "| geagsp | — |"]
    full = markdown(df).splitlines()
    assert full[0] == "| param | mean | n |"
    assert len(full) == 4


def test_write_table(tmp_path):
    df = pd.DataFrame({"a": [1.5], "b": ["x"]})
    text = write_table(df, tmp_path / "out", "t")
    assert (tmp_path / "out" / "t.md").read_text() == text + "\n"
    back = pd.read_csv(tmp_path / "out" / "t.csv")
    assert back.equals(df)


def test_add_variant_splits_cells_run_with_another_budget():
    main = '{"n_particles": 200, "iters": 400, "ftol": 1e-06}'
    side = '{"iters": 300, "ftol": 1e-06, "n_particles": 100}'
    same_as_main = '{"ftol": 1e-06, "iters": 400, "n_particles": 200}'  # other key order
    frame = pd.DataFrame({
        "problem": ["zermelo"] * 6, "case": ["default"] * 6,
        "problem_params": ["{}"] * 5 + ['{"t_max": 500.0}'],
        "optimizer": ["pso"] * 5 + ["pso"], "param": ["diagonal", "full"] * 3,
        "optimizer_settings": [main, main, same_as_main, side, side, side],
    })
    variants = add_variant(frame)["variant"].tolist()
    assert variants[:3] == ["", "", ""]
    assert variants[3:5] == ["iters=300,n_particles=100"] * 2
    # alone in its problem variant, the side budget is that cell's main budget
    assert variants[5] == "t_max=500.0"


def _params_frame(problem, case, params):
    n = len(params)
    return pd.DataFrame({
        "problem": [problem] * n, "case": [case] * n, "problem_params": params,
        "optimizer": ["cmaes"] * n, "param": ["diagonal"] * n,
        "optimizer_settings": ['{"max_evals": 600}'] * n})


@pytest.mark.parametrize("problem, case, key, value", [
    ("attitude_lyapunov", "rest_to_rest", "holdout_perturb_deg", 180.0),
    ("attitude_lqr", "detumble", "holdout_rate_rel", 0.05),
    ("mpc_rendezvous", "scaled", "holdout_sphere_radius_m", 500.0),
])
def test_a_held_out_size_that_shapes_the_drawn_training_set_splits_cells(
        problem, case, key, value):
    """A held-out parameter is no variant of a run, unless the run draws its training
    scenarios with it (``train_sample``): then it changes what the run tunes."""
    held_only = _params_frame(problem, case, ["{}", json.dumps({key: value})])
    assert add_variant(held_only)["problem_variant"].tolist() == ["", ""]
    sample = {"train_sample": 2, "train_seed": 3}
    trained = _params_frame(problem, case, [json.dumps(sample),
                                            json.dumps({**sample, key: value})])
    labels = add_variant(trained)["problem_variant"].tolist()
    assert labels[0] == "train_sample=2,train_seed=3"
    assert labels[1] == f"{key}={value},train_sample=2,train_seed=3"
    # a held-out size the drawn sample does not use stays out of the label
    other = _params_frame(problem, case, [json.dumps({**sample, "holdout_seed": 5})])
    assert add_variant(other)["problem_variant"].tolist() == [labels[0]]


def test_add_variant_labels_a_warm_start_as_a_variant_of_its_own():
    frame = pd.DataFrame({
        "problem": ["zermelo"] * 3, "case": ["default"] * 3, "problem_params": ["{}"] * 3,
        "optimizer": ["pso"] * 3, "param": ["diagonal", "full", "full"],
        "optimizer_settings": ['{"max_evals": 600}'] * 3,
        "warm_start": [None, None, '{"share": 0.3, "n_evals": 180}'],
    })
    out = add_variant(frame)
    assert out["variant"].tolist() == ["", "", "warm_start=0.3"]
    assert out["problem_variant"].tolist() == ["", "", ""]


def _warm_frame(params, warm, optimizers=None):
    n = len(params)
    return pd.DataFrame({
        "problem": ["zermelo"] * n, "case": ["default"] * n, "problem_params": ["{}"] * n,
        "optimizer": optimizers or ["pso"] * n, "param": params,
        "optimizer_settings": ['{"max_evals": 600}'] * n, "warm_start": warm})


def test_a_diagonal_cell_run_beside_warm_started_full_cells_joins_their_variant():
    """runner.warm_start warm-starts the full maps only: the run's diagonal cell, at the
    same total budget, is what they are compared with."""
    warm = '{"share": 0.3, "n_evals": 180}'
    out = add_variant(_warm_frame(["diagonal", "diagonal", "givens", "geagsp"],
                                  [None, None, warm, warm]))
    assert out["variant"].tolist() == ["warm_start=0.3"] * 4
    assert out["problem_variant"].tolist() == [""] * 4


def test_a_diagonal_cell_stays_without_a_warm_start_where_the_full_cells_disagree():
    """Full cells with and without a warm start, or with two shares: the diagonal cell
    keeps the variant without one (the first case is the test above this one too)."""
    two_shares = add_variant(_warm_frame(
        ["diagonal", "givens", "geagsp"],
        [None, '{"share": 0.3}', '{"share": 0.5}']))["variant"].tolist()
    assert two_shares == ["", "warm_start=0.3", "warm_start=0.5"]
    other_optimizer = add_variant(_warm_frame(
        ["diagonal", "givens", "givens"], [None, None, '{"share": 0.3}'],
        ["pso", "pso", "cmaes"]))["variant"].tolist()
    assert other_optimizer == ["", "", "warm_start=0.3"]


def test_warm_started_full_cells_are_tested_against_the_diagonal_cell_of_their_run():
    from penaltyrun.report.compare import pairwise

    rng = np.random.default_rng(0)
    n = 12
    frame = _warm_frame(["diagonal"] * n + ["givens"] * n, [None] * n + ['{"share": 0.3}'] * n)
    frame = frame.assign(status="ok", best_converged=True, n_evals=600, max_evals=600,
                         best_cost=np.r_[1.0 + rng.random(n), 0.5 + rng.random(n)])
    rows = pairwise(add_variant(frame))
    assert len(rows) == 1
    row = rows.iloc[0]
    assert (row["variant"], row["map_a"], row["map_b"]) == ("warm_start=0.3", "diagonal",
                                                             "givens")
    assert bool(row["equal_budget"]) and np.isfinite(row["p_mwu"])


def test_bca_of_a_large_sample_runs_in_batches_of_bounded_memory(monkeypatch):
    import tracemalloc

    from penaltyrun.report import stats as report_stats

    x = np.random.default_rng(3).gamma(2.0, 1.0, 2001)  # odd: batches must stay even
    whole = bca_ci(x, "median", n_resamples=999, seed=5)
    monkeypatch.setattr(report_stats, "BOOTSTRAP_BATCH_VALUES", 199_000)
    tracemalloc.start()
    try:
        batched = bca_ci(x, "median", n_resamples=999, seed=5)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # one call would hold 999 × 2000 resampled values and a 2000 × 1999 jackknife (48 MB);
    # a batch is 200 000 values (1.6 MB), a few copies of it alive at once
    assert peak < 16e6
    assert batched[2] == whole[2] == ""
    assert batched[:2] == whole[:2]  # batches of even size: the same draws, same interval


@settings(max_examples=40, deadline=None)
@given(st.lists(st.sampled_from([-3.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0]),
                min_size=1, max_size=EXACT_FLIP_MAX + 2))
def test_signed_rank_p_is_scipys_wilcoxon(values):
    """Small samples with ties and zeros (scipy's enumerated permutation test) and every
    other sample (scipy itself): the same two-sided p-value."""
    d = np.array(values)
    if not np.any(d != 0.0):
        assert math.isnan(signed_rank_p(d))
        return
    want = sps.wilcoxon(d, zero_method="wilcox", alternative="two-sided").pvalue
    assert signed_rank_p(d) == pytest.approx(want, rel=1e-12, abs=1e-15)


def test_signed_rank_p_of_continuous_samples_is_scipys():
    rng = np.random.default_rng(3)
    for n in (5, 12, 40):
        d = rng.normal(0.3, 1.0, n)
        assert signed_rank_p(d) == sps.wilcoxon(d, zero_method="wilcox").pvalue
