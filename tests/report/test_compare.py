"""Map-vs-map comparisons: two-sided MWU and A12 per optimizer and variant, Holm over all."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from penaltyrun.report.compare import (
    a12_interval,
    a12_intervals,
    map_order,
    pairwise,
)
from penaltyrun.report.stats import a12, holm

PENALTY = 1000.0


def rows(param, costs, optimizer="pso", variant="", statuses=None):
    statuses = statuses or ["ok"] * len(costs)
    return [{"problem": "toy", "case": "c1", "variant": variant, "optimizer": optimizer,
             "param": param, "best_cost": c, "status": s, "best_converged": s == "ok",
             "n_evals": 100}
            for c, s in zip(costs, statuses)]


COSTS = {"diagonal": [4.0, 5.0, 6.0, 9.0], "geagsp": [1.0, 2.0, 3.0, 6.0],
         "givens": [5.0, 7.0, 8.0], "cayley": [2.0, 2.5, 7.0]}


@pytest.fixture
def frame():
    data = [r for m, c in COSTS.items() for r in rows(m, c)]
    # diverged starts with penalty costs: they would change every test if they entered
    data += rows("diagonal", [PENALTY, PENALTY], statuses=["diverged"] * 2)
    data += rows("geagsp", [PENALTY], statuses=["diverged"])
    # a second optimizer and a warm-start variant, never pooled with the pso rows
    data += rows("diagonal", [100.0, 101.0], optimizer="de")
    data += rows("geagsp", [50.0, 51.0, 52.0], optimizer="de")
    data += rows("geagsp", [0.5, 0.6], variant="warm_start=0.3")
    return pd.DataFrame(data)


def test_map_order():
    assert map_order(["cayley", "zeta", "diagonal", "givens", "geagsp"]) == \
        ["diagonal", "geagsp", "givens", "cayley", "zeta"]


def test_every_pair_of_maps_within_one_optimizer_and_variant(frame):
    c = pairwise(frame)
    pso = c[(c["optimizer"] == "pso") & (c["variant"] == "")]
    expected = list(itertools.combinations(["diagonal", "geagsp", "givens", "cayley"], 2))
    assert list(zip(pso["map_a"], pso["map_b"])) == expected
    de = c[c["optimizer"] == "de"]
    assert list(zip(de["map_a"], de["map_b"])) == [("diagonal", "geagsp")]
    assert (de["n_a"].iloc[0], de["n_b"].iloc[0]) == (2, 3)
    assert de["median_a"].iloc[0] == 100.5  # de costs only
    # the warm-start variant has one map only: nothing to compare, and it is not pooled
    assert not (c["variant"] == "warm_start=0.3").any()
    assert len(c) == 7


def test_statistics_of_one_pair_use_converged_costs_only(frame):
    c = pairwise(frame)
    r = c[(c["optimizer"] == "pso") & (c["map_a"] == "diagonal")
          & (c["map_b"] == "geagsp")].iloc[0]
    d, g = COSTS["diagonal"], COSTS["geagsp"]
    assert (r["n_a"], r["n_b"]) == (4, 4)
    assert r["success_a"] == pytest.approx(4 / 6) and r["success_b"] == pytest.approx(0.8)
    assert (r["median_a"], r["median_b"]) == (5.5, 2.5)
    assert r["median_change_pct"] == pytest.approx(100 * 3 / 5.5)
    assert r["p_mwu"] == pytest.approx(sps.mannwhitneyu(d, g, alternative="two-sided").pvalue)
    # A12 = P(a geagsp start beats a diagonal start) + ½ ties: geagsp 1, 2, 3 beat all four
    # diagonal starts (12 pairs), 6 beats 9 and ties 6 → (13 + ½)/16
    assert r["a12_b_beats_a"] == pytest.approx(13.5 / 16) == pytest.approx(a12(d, g))
    assert r["a12_magnitude"] == "large"
    assert r["note"] == "underpowered (n < 10)"


def test_holm_over_every_comparison_of_the_report(frame):
    c = pairwise(frame)
    assert c["p_holm"].to_numpy() == pytest.approx(holm(c["p_mwu"].to_numpy()), nan_ok=True)
    assert (c["p_holm"] >= c["p_mwu"]).all()


def test_enough_starts_are_not_underpowered_and_one_start_is_no_test():
    rng = np.random.default_rng(0)
    data = rows("diagonal", list(rng.normal(10, 1, 12))) + rows("geagsp", list(rng.normal(
        9, 1, 10))) + rows("diagonal", [3.0], optimizer="grid") + rows("geagsp", [2.0],
                                                                      optimizer="grid")
    c = pairwise(pd.DataFrame(data))
    pso = c[c["optimizer"] == "pso"].iloc[0]
    assert pso["note"] == "" and np.isfinite(pso["p_holm"])
    grid = c[c["optimizer"] == "grid"].iloc[0]
    assert math.isnan(grid["p_mwu"]) and math.isnan(grid["p_holm"])
    assert "no test" in grid["note"]
    assert pso["p_holm"] == pytest.approx(pso["p_mwu"])  # a family of one test


def _brunner_munzel_direct(x, y, level):
    """The Brunner–Munzel interval of P(X < Y) + ½ P(X = Y) written out from its
    placements: each x against every y and back (no ranks), for :func:`a12_interval`."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    place = (x[:, None] < y[None, :]) + 0.5 * (x[:, None] == y[None, :])
    p_hat = place.mean()
    vx = np.var(place.mean(axis=1), ddof=1)  # placements of x (Brunner & Munzel, eq. 3)
    vy = np.var(place.mean(axis=0), ddof=1)
    se = math.sqrt(vx / x.size + vy / y.size)
    df = (vx / x.size + vy / y.size) ** 2 / ((vx / x.size) ** 2 / (x.size - 1)
                                             + (vy / y.size) ** 2 / (y.size - 1))
    half = sps.t.ppf(0.5 + level / 2, df) * se
    return p_hat, se, df, max(0.0, p_hat - half), min(1.0, p_hat + half)


@pytest.mark.parametrize("cost_a, cost_b", [
    ([4.0, 5.0, 6.0, 9.0, 5.0], [1.0, 2.0, 5.0, 6.0, 7.5, 3.0]),  # with a tie across maps
    ([0.3, 0.1, 0.7, 0.2], [0.5, 0.4, 0.6, 0.05, 0.55]),
])
def test_a12_interval_matches_scipy_brunnermunzel_and_a_direct_computation(cost_a, cost_b):
    effect, lo, hi, note = a12_interval(cost_a, cost_b, level=0.9)
    assert note == ""
    assert effect == pytest.approx(a12(cost_a, cost_b))
    p_hat, se, df, lo_ref, hi_ref = _brunner_munzel_direct(cost_b, cost_a, 0.9)
    assert effect == pytest.approx(p_hat)
    assert (lo, hi) == pytest.approx((lo_ref, hi_ref), rel=1e-12)
    # scipy's statistic is (A12 − ½)/SE with the same Welch–Satterthwaite df
    ref = sps.brunnermunzel(cost_b, cost_a, alternative="two-sided", distribution="t")
    assert (effect - 0.5) / se == pytest.approx(ref.statistic, rel=1e-12)
    assert 2 * sps.t.sf(abs(ref.statistic), df) == pytest.approx(ref.pvalue, rel=1e-10)
    assert lo <= effect <= hi


def test_a12_interval_says_why_there_is_none():
    assert a12_interval([1.0, 2.0], [3.0, 4.0])[3] == "complete separation: no interval"
    effect, lo, hi, note = a12_interval([1.0], [3.0, 4.0])
    assert effect == 0.0 and math.isnan(lo) and math.isnan(hi) and "fewer than 2" in note


def test_a12_intervals_follow_the_equal_budget_pairs(frame):
    ci = a12_intervals(frame)
    comp = pairwise(frame)
    merged = comp.merge(ci, on=["problem", "case", "variant", "optimizer", "map_a", "map_b"],
                        suffixes=("", "_ci"))
    assert len(merged) == len(comp) == len(ci)
    assert np.allclose(merged["a12_b_beats_a"], merged["a12_b_beats_a_ci"])
    row = ci[(ci["optimizer"] == "pso") & (ci["map_a"] == "diagonal")
             & (ci["map_b"] == "geagsp")].iloc[0]
    assert (row["a12_lo"], row["a12_hi"]) == pytest.approx(
        a12_interval(COSTS["diagonal"], COSTS["geagsp"])[1:3])
    unequal = frame.assign(n_evals=np.where(frame["param"] == "geagsp", 50, 100))
    assert not (a12_intervals(unequal)["map_b"] == "geagsp").any()


def test_a_polish_that_ends_early_does_not_make_budgets_unequal():
    """Same cap, same search spend: the polish's spend (which ends when it converges) is
    left out of the equal-budget rule and shown beside it; a search spend that differs
    still refuses the test."""
    data = [{**r, "max_evals": 1000, "n_evals": 800 + p, "polish_evals": p}
            for (m, c), p in zip([("diagonal", COSTS["diagonal"]), ("geagsp", COSTS["geagsp"])],
                                 (200, 37)) for r in rows(m, c)]
    row = pairwise(pd.DataFrame(data)).iloc[0]
    assert row["equal_budget"] and row["evals_a"] == 800 and row["evals_b"] == 800
    assert (row["polish_evals_a"], row["polish_evals_b"]) == (200, 37)
    assert "budgets differ" not in row["note"] and np.isfinite(row["p_mwu"])
    for r in data[len(COSTS["diagonal"]):]:
        r["polish_evals"] = 0  # the same n_evals, all of it search: 837 against 800
    row = pairwise(pd.DataFrame(data)).iloc[0]
    assert not row["equal_budget"] and row["note"] == "budgets differ: no test"


def test_records_without_a_polish_column_count_everything_as_search(frame):
    row = pairwise(frame.assign(max_evals=100)).iloc[0]
    assert row["evals_a"] == 100 and math.isnan(row["polish_evals_a"])
