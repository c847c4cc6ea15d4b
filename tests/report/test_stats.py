"""Cell statistics, diagonal-vs-full comparison and table formatting on synthetic data."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from penaltyrun.report.stats import add_variant, bootstrap_ci, cell_summary, comparison
from penaltyrun.report.tables import fmt, markdown, write_table

DIAG = [4.0, 5.0, 6.0, 9.0]
GEAGSP = [1.0, 2.0, 3.0, 6.0]
GIVENS = [5.0, 7.0, 8.0]


def rows(param, costs, problem="toy", case="c1", optimizer="pso", statuses=None):
    statuses = statuses or ["ok"] * len(costs)
    return [{"problem": problem, "case": case, "optimizer": optimizer, "param": param,
             "best_cost": c, "status": s, "n_evals": 100 + i, "wall_time_s": 1.0 + i}
            for i, (c, s) in enumerate(zip(costs, statuses))]


@pytest.fixture
def df():
    data = (rows("diagonal", DIAG + [np.nan], statuses=["ok", "ok", "diverged", "ok", "failed"])
            + rows("geagsp", GEAGSP, statuses=["ok", "ok", "ok", "diverged"])
            + rows("givens", GIVENS)
            + rows("diagonal", [10.0, 20.0], optimizer="de"))
    return pd.DataFrame(data)


def cell(summary, param, optimizer="pso"):
    sel = summary[(summary["param"] == param) & (summary["optimizer"] == optimizer)]
    assert len(sel) == 1
    return sel.iloc[0]


def test_cell_summary_statistics(df):
    s = cell_summary(df)
    assert len(s) == 4
    d = cell(s, "diagonal")
    assert d["n_jobs"] == 5 and d["n_failed"] == 1
    assert d["success_rate"] == pytest.approx(3 / 5)
    assert d["best"] == 4.0 and d["worst"] == 9.0
    assert d["mean"] == pytest.approx(6.0)
    assert d["median"] == pytest.approx(5.5)
    assert d["std"] == pytest.approx(np.std(DIAG, ddof=1))
    assert d["mean_evals"] == pytest.approx(np.mean([100, 101, 102, 103, 104]))
    assert d["mean_wall_s"] == pytest.approx(3.0)
    assert d["mean_ci95_lo"] <= d["mean"] <= d["mean_ci95_hi"]
    g = cell(s, "geagsp")
    assert (g["best"], g["mean"], g["median"], g["worst"]) == (1.0, 3.0, 2.5, 6.0)
    assert g["success_rate"] == pytest.approx(0.75)
    assert g["n_failed"] == 0
    de = cell(s, "diagonal", "de")
    assert de["mean"] == 15.0 and de["n_jobs"] == 2
    assert math.isnan(de["paper_mean"])  # no paper number for the toy problem


def test_cell_summary_single_and_all_failed():
    df = pd.DataFrame(rows("diagonal", [2.0]) + rows("geagsp", [np.nan, np.nan],
                                                      statuses=["failed", "failed"]))
    s = cell_summary(df)
    d = cell(s, "diagonal")
    assert d["best"] == 2.0 and math.isnan(d["std"]) and math.isnan(d["mean_ci95_lo"])
    g = cell(s, "geagsp")
    assert g["n_jobs"] == 2 and g["n_failed"] == 2 and g["success_rate"] == 0.0
    assert math.isnan(g["mean"]) and math.isnan(g["best"])


def test_cell_summary_separates_variants(df):
    df = df.assign(variant="")
    df.loc[df.index[:2], "variant"] = "objective=min_fuel"
    s = cell_summary(df)
    diag_pso = s[(s["param"] == "diagonal") & (s["optimizer"] == "pso")]
    assert sorted(diag_pso["n_jobs"]) == [2, 3]


def test_cell_summary_paper_mean_uses_the_parameterization():
    df = pd.DataFrame(rows("diagonal", [0.5, 0.4], problem="attitude_lqr", case="detumble")
                      + rows("geagsp", [0.2, 0.1], problem="attitude_lqr", case="detumble"))
    s = cell_summary(df)
    assert cell(s, "diagonal")["paper_mean"] == pytest.approx(0.423)
    assert cell(s, "geagsp")["paper_mean"] == pytest.approx(0.146)
    c = comparison(df).iloc[0]
    assert c["paper_improvement_mean_pct"] == pytest.approx(100 * (0.423 - 0.146) / 0.423)


def test_comparison(df):
    c = comparison(df)
    # one row per full map with a diagonal cell of the same (problem, case, optimizer)
    assert sorted(c["full_map"]) == ["geagsp", "givens"]
    assert set(c["optimizer"]) == {"pso"}
    g = c[c["full_map"] == "geagsp"].iloc[0]
    assert g["n_diagonal"] == 5 and g["n_full"] == 4
    assert g["diag_mean"] == pytest.approx(6.0) and g["full_mean"] == pytest.approx(3.0)
    assert g["improvement_mean_pct"] == pytest.approx(50.0)
    assert g["improvement_best_pct"] == pytest.approx(75.0)
    assert g["diag_success"] == pytest.approx(0.6) and g["full_success"] == pytest.approx(0.75)
    expected_p = sps.mannwhitneyu(GEAGSP, DIAG, alternative="less").pvalue
    assert g["p_value_mwu"] == pytest.approx(expected_p)
    assert not g["full_worse_on_best"]
    v = c[c["full_map"] == "givens"].iloc[0]
    assert v["improvement_mean_pct"] == pytest.approx(100 * (6.0 - 20 / 3) / 6.0)
    assert v["improvement_best_pct"] == pytest.approx(-25.0)
    assert v["full_worse_on_best"]
    assert v["p_value_mwu"] == pytest.approx(
        sps.mannwhitneyu(GIVENS, DIAG, alternative="less").pvalue)
    assert v["p_value_mwu"] > 0.5


def test_comparison_treats_full_as_a_full_map_and_needs_diagonal():
    df = pd.DataFrame(rows("diagonal", [2.0, 3.0]) + rows("full", [1.0, 1.5]))
    c = comparison(df)
    assert list(c["full_map"]) == ["full"]
    assert c.iloc[0]["improvement_mean_pct"] == pytest.approx(100 * (2.5 - 1.25) / 2.5)
    assert comparison(pd.DataFrame(rows("geagsp", [1.0, 2.0]))).empty


def test_bootstrap_ci():
    rng = np.random.default_rng(0)
    x = rng.normal(10.0, 2.0, 40)
    lo, hi = bootstrap_ci(x)
    assert lo < x.mean() < hi
    assert x.min() <= lo and hi <= x.max()
    assert bootstrap_ci(x) == (lo, hi)  # deterministic for a fixed seed
    lo90, hi90 = bootstrap_ci(x, level=0.90)
    assert lo <= lo90 and hi90 <= hi
    assert all(math.isnan(v) for v in bootstrap_ci(np.array([1.0])))
    assert bootstrap_ci(np.array([3.0, 3.0])) == (3.0, 3.0)


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
