"""The report's time to a known optimum (``known_optimum``, ``known_optimum_ratios``)."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from penaltyrun.report.knownopt import (
    RTOL,
    first_reach,
    known_optimum,
    ratio_relation,
    ratio_table,
    reach_table,
)

J_STAR = 10.0


def row(optimizer: str, start: int, trace: list[tuple[int, float, float]], *,
        method: str = "closed_form", params: dict | None = None, param: str = "givens",
        max_evals: int = 1000) -> dict:
    """A finished lqr job whose anytime trace is ``trace`` ((evals, best, CPU s) points)."""
    evals, best, cpu = (list(v) for v in zip(*trace))
    return {"problem": "lqr", "case": "default", "variant": "", "problem_variant": "",
            "optimizer": optimizer, "param": param, "start": start, "status": "ok",
            "best_cost": best[-1], "best_z": [0.0] * 11, "n_evals": evals[-1],
            "max_evals": max_evals, "trace_evals": evals, "trace_best": best,
            "trace_cpu_s": cpu, "problem_params": json.dumps(params or {}),
            "matrices": json.dumps({"Q": np.eye(4).tolist(), "R": [[1.0]]}),
            "metrics": json.dumps({"optimum": J_STAR, "method": method})}


def near(gap: float) -> float:
    return J_STAR * (1.0 + gap)


FAST = [row("lbfgs", k, [(1, near(1.0), 0.01), (40 + k, near(1e-7), 0.2 + 0.1 * k),
                         (90, near(1e-9), 0.9)]) for k in range(3)]
SLOW = [row("cmaes", k, [(1, near(2.0), 0.0), (900, near(1e-3), 50.0 + k),
                         (1000, near(1e-4), 60.0 + k)]) for k in range(3)]


def test_first_reach_is_the_first_trace_point_within_the_tolerance():
    r = pd.Series(FAST[1])
    assert first_reach(r, J_STAR * (1 + RTOL)) == (41.0, pytest.approx(0.3))
    assert first_reach(r, J_STAR * (1 - 1e-3)) == (float("inf"), float("inf"))
    old = pd.Series({**FAST[1], "trace_cpu_s": None})  # schema version 7: no CPU trace
    evals, cpu = first_reach(old, J_STAR * (1 + RTOL))
    assert evals == 41.0 and np.isnan(cpu)


def test_the_optimum_counts_only_where_it_is_the_optimum_of_the_evaluation():
    assert known_optimum(pd.Series(FAST[0])) == J_STAR
    assert np.isnan(known_optimum(pd.Series(row("lbfgs", 0, [(1, 11.0, 0.1)],
                                                method="integrated"))))
    assert np.isnan(known_optimum(pd.Series(row("lbfgs", 0, [(1, 11.0, 0.1)],
                                                params={"u_max": 2.0}))))
    assert np.isnan(known_optimum(pd.Series({**FAST[0], "metrics": json.dumps({})})))


def test_reach_table_per_cell():
    table = reach_table(pd.DataFrame(FAST + SLOW)).set_index("optimizer")
    fast, slow = table.loc["lbfgs"], table.loc["cmaes"]
    assert fast["n_reached"] == 3 and slow["n_reached"] == 0
    assert fast["evals_to_reach_median"] == 41 and fast["cpu_s_to_reach_median"] == \
        pytest.approx(0.3)
    assert fast["cpu_s_to_reach_min"] == pytest.approx(0.2)
    assert fast["cpu_s_all_median"] == pytest.approx(0.3) and not fast["cpu_s_all_bound"]
    # never reached: the CPU the starts spent is a lower bound
    assert np.isnan(slow["cpu_s_to_reach_median"]) and slow["cpu_s_all_bound"]
    assert slow["cpu_s_all_median"] == 61.0 and slow["cpu_s_spent_min"] == 60.0
    assert slow["gap_median"] == pytest.approx(1e-4)
    assert fast["size"] == 4 and fast["dim"] == 11 and fast["optimum"] == J_STAR


def test_a_cell_without_a_known_optimum_is_left_out():
    rows = [row("pso", 0, [(1, 11.0, 0.1)], method="integrated")]
    assert reach_table(pd.DataFrame(rows)).empty
    assert reach_table(pd.DataFrame(FAST + rows))["optimizer"].tolist() == ["lbfgs"]


def test_median_over_all_starts_is_exact_when_most_starts_reached():
    partial = SLOW[:1] + [row("cmaes", k, [(1, near(1.0), 0.0), (500, near(1e-8), 5.0 * k)])
                          for k in (1, 2)]
    cell = reach_table(pd.DataFrame(partial)).iloc[0]
    assert cell["n_reached"] == 2 and not cell["cpu_s_all_bound"]
    assert cell["cpu_s_all_median"] == 10.0  # of (5, 10, inf)


def test_ratio_table_gives_a_bound_when_the_slow_optimizer_never_reached():
    ratios = ratio_table(reach_table(pd.DataFrame(FAST + SLOW)))
    slow_fast = ratios[ratios["optimizer_a"] == "cmaes"].iloc[0]
    assert slow_fast["relation"] == ">" and slow_fast["cpu_ratio"] == pytest.approx(61 / 0.3)
    # the other way round the same numbers bound the ratio from above
    fast_slow = ratios[ratios["optimizer_a"] == "lbfgs"].iloc[0]
    assert fast_slow["relation"] == "<" and fast_slow["cpu_ratio"] == pytest.approx(0.3 / 61)
    exact = ratio_table(reach_table(pd.DataFrame(FAST + [
        row("cmaes", k, [(1, near(1.0), 0.0), (500, near(1e-8), 3.0)]) for k in range(3)])))
    first = exact[exact["optimizer_a"] == "cmaes"].iloc[0]
    assert first["relation"] == "=" and first["cpu_ratio"] == pytest.approx(10.0)


def test_maps_are_never_pooled():
    rows = FAST + [row("cmaes", k, [(1, near(0.5), 1.0)], param="diagonal") for k in range(2)]
    table = reach_table(pd.DataFrame(rows))
    assert sorted(zip(table["optimizer"], table["param"])) == [("cmaes", "diagonal"),
                                                              ("lbfgs", "givens")]
    assert ratio_table(table).empty


def test_optimizers_with_their_own_budget_variants_are_still_compared():
    slow = [{**r, "variant": "max_evals=1000"} for r in SLOW]
    ratios = ratio_table(reach_table(pd.DataFrame(FAST + slow)))
    first = ratios[ratios["optimizer_a"] == "cmaes"].iloc[0]
    assert first["variant_a"] == "max_evals=1000" and first["variant_b"] == ""
    assert first["relation"] == ">"


def test_no_ratio_when_neither_optimizer_reached_in_most_starts():
    never = [row("lbfgs", k, [(1, near(1.0), 0.0), (50, near(1e-3), 2.0)]) for k in range(3)]
    ratios = ratio_table(reach_table(pd.DataFrame(never + SLOW)))
    assert (ratios["relation"] == "").all() and ratios["cpu_ratio"].isna().all()


@pytest.mark.parametrize(("bound_a", "bound_b", "cpu_b", "expected"), [
    (False, False, 2.0, "="), (True, False, 2.0, ">"), (False, True, 2.0, "<"),
    (True, True, 2.0, ""), (False, False, 0.0, ""), (False, True, float("nan"), "")])
def test_ratio_relation(bound_a, bound_b, cpu_b, expected):
    a = pd.Series({"cpu_s_all_median": 1.0, "cpu_s_all_bound": bound_a})
    b = pd.Series({"cpu_s_all_median": cpu_b, "cpu_s_all_bound": bound_b})
    assert ratio_relation(a, b) == expected


def test_a_lazily_read_study_gives_the_same_time_to_the_known_optimum():
    """A large results set is read lazily (metrics and traces left in the file): the
    table is the one of the same file read whole, not left out."""
    from pathlib import Path

    from penaltyrun.io.read import LAZY_COLUMNS, read_results
    from penaltyrun.report.rows import FRAME_COLUMNS, REPORT_COLUMNS
    from penaltyrun.report.stats import add_variant

    src = Path(__file__).resolve().parents[2] / "studies" / "lqr_scaling" / "results.parquet"
    whole = reach_table(add_variant(read_results(src, REPORT_COLUMNS)))
    lazy_df = add_variant(read_results(src, FRAME_COLUMNS, lazy=True))
    assert "trace_cpu_s" in LAZY_COLUMNS and "trace_cpu_s" not in lazy_df
    lazy = reach_table(lazy_df)
    assert len(whole) == 16
    pd.testing.assert_frame_equal(lazy.astype(whole.dtypes.to_dict()), whole)
