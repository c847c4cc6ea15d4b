"""Anytime traces: best-so-far step function, ECDF, ERT (COCO) and the target table."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.report.anytime import (
    anytime_band,
    best_so_far,
    ecdf,
    ert,
    hitting_evals,
    target_table,
    trace_of,
)
from penaltyrun.report.bestknown import best_known

EVALS = np.array([10.0, 30.0, 50.0])
BEST = np.array([5.0, 3.0, 2.0])


def test_best_so_far_is_the_step_function_through_the_trace():
    got = best_so_far(EVALS, BEST, np.array([5, 10, 29, 30, 49, 50, 1000]))
    assert math.isnan(got[0])  # before the first evaluation
    assert got[1:].tolist() == [5.0, 5.0, 3.0, 3.0, 2.0, 2.0]  # held after the end


def test_hitting_evals():
    assert hitting_evals(EVALS, BEST, 5.0) == 10.0
    assert hitting_evals(EVALS, BEST, 3.5) == 30.0
    assert hitting_evals(EVALS, BEST, 2.0) == 50.0
    assert hitting_evals(EVALS, BEST, 1.9) == math.inf


def test_ecdf_hand_example():
    hits = np.array([30.0, math.inf, 50.0])
    assert ecdf(hits, np.array([10, 30, 49, 50, 1000])) == pytest.approx(
        [0.0, 1 / 3, 1 / 3, 2 / 3, 2 / 3])
    assert np.isnan(ecdf(np.array([]), np.array([1.0]))).all()


def test_ert_hand_example():
    # start 1 reached the target after 30 of 100 evaluations, start 2 never (80 spent),
    # start 3 after 50 of 60: (30 + 80 + 50) / 2 successes
    assert ert(np.array([30.0, math.inf, 50.0]), np.array([100.0, 80.0, 60.0])) == 80.0
    assert ert(np.array([math.inf, math.inf]), np.array([100.0, 100.0])) == math.inf
    assert ert(np.array([7.0]), np.array([9.0])) == 7.0


def test_anytime_band_median_and_quartiles():
    traces = [(np.array([1.0, 3.0]), np.array([10.0, 4.0]), 3.0),
              (np.array([1.0, 2.0]), np.array([8.0, 6.0]), 2.0),
              (np.array([2.0]), np.array([2.0]), 2.0)]
    med, q25, q75 = anytime_band(traces, np.array([1.0, 2.0, 3.0]))
    # n = 1: values 10, 8 (third start not yet evaluated); n = 2: 10, 6, 2; n = 3: 4, 6, 2
    assert med.tolist() == [9.0, 6.0, 4.0]
    assert q25.tolist() == [8.5, 4.0, 3.0] and q75.tolist() == [9.5, 8.0, 5.0]


def job(param, optimizer, evals, best, status="ok", n_evals=None):
    return {"problem": "toy", "case": "c1", "problem_variant": "", "variant": "",
            "param": param, "optimizer": optimizer, "status": status,
            "best_converged": status == "ok", "best_cost": best[-1] if best else np.nan,
            "trace_evals": evals, "trace_best": best, "n_evals": n_evals or
            (evals[-1] if evals else None), "job_id": f"{param}{optimizer}{len(evals or [])}",
            "matrices": "{}"}


def test_target_table_per_cell_and_without_traces():
    df = pd.DataFrame([
        job("diagonal", "pso", [10, 40, 100], [9.0, 2.019, 2.0]),
        job("diagonal", "pso", [10, 100], [9.0, 2.5]),
        job("diagonal", "pso", [10, 50], [1e3, 1e3], status="diverged"),  # counts, never hits
        job("diagonal", "de", [20, 60], [3.0, 2.001]),
        job("diagonal", "de", None, None),  # a result without trace (schema 2)
        job("diagonal", "cmaes", None, [2.1]),  # incomplete trace: skipped
    ])
    df.loc[4, "best_cost"] = 2.2
    bk = best_known(df)
    assert bk.iloc[0]["best_known"] == 2.0
    t = target_table(df, bk).set_index(["optimizer", "epsilon"])
    assert set(t.index.get_level_values(0)) == {"pso", "de"}  # cmaes: no usable trace
    pso = t.loc[("pso", 0.01)]
    assert pso["target"] == pytest.approx(2.02)
    # target 2.02: the first start hits at 40; the others never (100 and 50 spent)
    assert (pso["n_starts"], pso["n_reached"]) == (3, 1)
    assert pso["ert_evals"] == pytest.approx((40 + 100 + 50) / 1)
    assert pso["median_evals_to_target"] == 40.0
    # target 2.002: the first start hits at 100
    assert t.loc[("pso", 0.001), "ert_evals"] == pytest.approx((100 + 100 + 50) / 1)
    assert t.loc[("pso", 0.001), "share_reached"] == pytest.approx(1 / 3)
    de = t.loc[("de", 0.01)]
    assert (de["n_starts"], de["n_reached"], de["ert_evals"]) == (1, 1, 60.0)


def test_trace_of():
    assert trace_of(pd.Series({"trace_evals": None, "trace_best": None})) is None
    assert trace_of(pd.Series({"trace_evals": [], "trace_best": []})) is None
    e, b = trace_of(pd.Series({"trace_evals": [1, 2], "trace_best": [3.0, 1.0]}))
    assert e.tolist() == [1.0, 2.0] and b.tolist() == [3.0, 1.0]


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.integers(1, 60).map(float), st.just(float("inf"))), max_size=40),
       st.lists(st.integers(0, 80).map(float), min_size=1, max_size=20))
def test_ecdf_counts_the_hits_at_or_below_each_grid_point(hits, grid):
    """Against the share computed by comparing every hit with every grid point (ties,
    never-reached starts)."""
    hits, grid = np.array(hits), np.array(grid)
    if hits.size:
        np.testing.assert_array_equal(ecdf(hits, grid),
                                      (hits[None, :] <= grid[:, None]).mean(axis=1))
