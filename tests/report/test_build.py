"""The report end to end on small real runs of every problem family (Parquet → files)."""

import numpy as np
import pandas as pd
import pytest

from penaltyrun import io, runner
from penaltyrun.report import build_report

TINY = {"n_particles": 4, "iters": 2, "ftol_iter": 2}


def run_cells(run_dir, cells):
    jobs = []
    for problem, case, param, optimizer, n, params in cells:
        options = TINY if optimizer == "pso" else {}
        jobs += runner.plan_jobs(problem, case, param, optimizer, n, 7, params, {}, options,
                                 {"git_commit": "test"})
    runner.execute(jobs, run_dir)
    return io.collect(run_dir)


@pytest.fixture(scope="module")
def attitude_report(tmp_path_factory):
    root = tmp_path_factory.mktemp("attitude")
    small_grid = {"holdout_n": 2}
    cells = [(law, case, param, "pso", 2, small_grid)
             for law in ("attitude_lyapunov", "attitude_lqr")
             for case in ("detumble", "rest_to_rest") for param in ("diagonal", "full")]
    cells.append(("attitude_lyapunov", "rest_to_rest", "diagonal", "pso", 1,
                  {**small_grid, "t_max": 80.0}))
    run_cells(root / "run", cells)
    return build_report(root / "run", root / "report")


def test_attitude_tables_figures_and_studies(attitude_report):
    text = (attitude_report / "report.md").read_text()
    for heading in ("Table 1 — attitude LQR", "Table 2 — attitude Lyapunov PD",
                    "horizon study", "robustness on held-out initial attitudes"):
        assert heading in text
    assert "section failed" not in text and "sections failed" not in text
    table = pd.read_csv(attitude_report / "table_attitude_lqr_pso.csv")
    assert list(table["start"][:2]) == ["1", "2"]
    paper = table.set_index("start").loc["paper mean"]
    assert paper["detumble diagonal"] == pytest.approx(0.423)
    assert paper["rest_to_rest full"] == pytest.approx(0.152)
    assert "## Held-out scenarios: attitude" in text
    held = pd.read_csv(attitude_report / "holdout_attitude.csv")
    assert set(held["scenarios"]) == {8} and held["diag_conv"].between(0, 1).all()
    robust = pd.read_csv(attitude_report / "attitude_robustness.csv")
    assert set(robust["held-out starts"]) == {8}
    horizon = pd.read_csv(attitude_report / "attitude_horizon.csv")
    assert {80.0, 100.0} <= set(horizon["t_f"])
    for name in ("attitude_lqr_detumble_histories.png", "attitude_robustness.png",
                 "attitude_horizon.png"):
        assert (attitude_report / name).stat().st_size > 0


def test_lowthrust_tables_and_case_e(tmp_path):
    cells = [("qlaw", "C", "diagonal", "pso", 2, {}), ("qlaw", "C", "full", "pso", 2, {}),
             ("qlaw", "C", "diagonal", "baseline", 1, {}),
             ("qlaw", "E", "diagonal", "baseline", 1, {"tof_cap_days": 20.0}),
             ("lyapunov_transfer", "C", "diagonal", "baseline", 1, {})]
    run_cells(tmp_path / "run", cells)
    out = build_report(tmp_path / "run", tmp_path / "report")
    text = (out / "report.md").read_text()
    for heading in ("Table 3 (case definitions used)", "Table 5 — Q-law",
                    "Table 4 — generic Lyapunov law", "original Case E"):
        assert heading in text
    assert "section failed" not in text and "sections failed" not in text
    table5 = pd.read_csv(out / "table_qlaw.csv")
    row_c = table5[(table5["case"] == "C") & table5["variant"].isna()].iloc[0]
    assert row_c["K=I"] == "1.412 d"
    assert row_c["diag conv."] == "2/2"
    assert np.isfinite(row_c["full mean ToF d"])
    # discretization column from the jobs' held-out control steps / substeps
    assert row_c["discr. K (diag/full)"] == "2/2"
    assert np.isfinite(row_c["discr. spread"]) and row_c["discr. spread"] > 0
    assert row_c["discr. verdict"] in ("within discretization noise",
                                       "beyond discretization spread")
    row_e = table5[table5["case"] == "E"].iloc[0]
    assert row_e["K=I"] == "tof_cap"
    table4 = pd.read_csv(out / "table_lyapunov_transfer.csv")
    assert table4.iloc[0]["K=I"] == "impact"
    assert "## Held-out scenarios: low thrust" in text
    assert "### Low thrust: discretization check" in text
    held = pd.read_csv(out / "holdout_low_thrust.csv")
    assert list(held["scenarios"]) == [12]
    disc = pd.read_csv(out / "holdout_discretization.csv")
    assert disc.iloc[0]["verdict"] in ("within discretization noise", "beyond the spread")
    for name in ("qlaw_C_trajectory.png", "qlaw_C_elements.png", "qlaw_C_thrust.png"):
        assert (out / name).stat().st_size > 0


def test_lowthrust_report_without_case_e(tmp_path):
    """A plain `penaltyrun problem=qlaw case=A` has no E/E* rows: the report must still build."""
    run_cells(tmp_path / "run", [("qlaw", "C", "diagonal", "baseline", 1, {})])
    text = (build_report(tmp_path / "run", tmp_path / "report") / "report.md").read_text()
    assert "Table 5 — Q-law" in text
    assert "original Case E" not in text
    assert "failed" not in text


def test_full_worse_explanation_names_the_cell_and_its_variant():
    from penaltyrun.report.build import _why_full_worse

    df = pd.DataFrame({
        "problem": ["qlaw"] * 2, "case": ["Estar"] * 2,
        "variant": ["objective=min_fuel"] * 2, "optimizer": ["pso"] * 2,
        "param": ["full"] * 2, "stop_reason": ["iters", "ftol"], "n_evals": [120, 96],
        "best_z": [np.zeros(16), np.zeros(16)],
    })
    row = pd.Series({"problem": "qlaw", "case": "Estar", "variant": "objective=min_fuel",
                     "optimizer": "pso", "full_map": "full", "full_best": 514.4,
                     "diag_best": 476.6})
    text = _why_full_worse(df, row)
    assert "qlaw / Estar [objective=min_fuel] / pso / full" in text
    assert "514.4 > best diagonal 476.6" in text
    assert "mean evaluations 108 for 16 variables" in text


@pytest.fixture(scope="module")
def zermelo_run(tmp_path_factory):
    """Small real Zermelo study at one budget: pso, cmaes, grid, and a warm-started pso."""
    root = tmp_path_factory.mktemp("zermelo")
    budget = {"max_evals": 90}
    jobs = []
    for param in ("diagonal", "full"):
        jobs += runner.plan_jobs("zermelo", "default", param, "pso", 3, 7, {}, {},
                                 {**budget, "n_particles": 6, "iters": 100}, {})
        jobs += runner.plan_jobs("zermelo", "default", param, "cmaes", 3, 7, {}, {}, budget, {})
        jobs += runner.plan_jobs("zermelo", "default", param, "grid", 1, 7, {}, {},
                                 {"points_per_dim": 9, "n_local": 1, "local_max_evals": 40},
                                 {})
    jobs += runner.plan_jobs("zermelo", "default", "full", "pso", 2, 7, {}, {},
                             {**budget, "n_particles": 6, "iters": 100}, {},
                             warm_start_share=0.3)
    runner.execute(jobs, root / "run")
    return io.collect(root / "run")


def test_zermelo_report_statistics_best_known_and_anytime(zermelo_run, tmp_path):
    out = build_report(zermelo_run, tmp_path / "report")
    text = (out / "report.md").read_text()
    for heading in ("## Best-known optima", "best-known full vs best-known diagonal",
                    "Optimizer shortfall", "## Map vs map at equal budget",
                    "Fixed targets: ERT", "Holm family: every map-vs-map comparison"):
        assert heading in text
    assert "failed" not in text
    summary = pd.read_csv(out / "summary.csv", keep_default_na=False)
    assert set(summary["optimizer"]) == {"pso", "cmaes", "grid"}
    warm = summary[summary["variant"] == "warm_start=0.3"]
    assert list(warm["param"]) == ["full"] and list(warm["n_jobs"]) == [2]
    assert (pd.to_numeric(summary.loc[summary["optimizer"] != "grid", "max_evals"]) == 90).all()
    comp = pd.read_csv(out / "comparison.csv", keep_default_na=False)
    # one diagonal-vs-full row per optimizer of the main variant, none for the warm variant
    assert sorted(comp["optimizer"]) == ["cmaes", "grid", "pso"]
    assert set(comp["variant"]) == {""}
    assert (comp["note"] != "").all()  # 3 starts: underpowered (grid: no test)
    bk = pd.read_csv(out / "best_known.csv")
    assert sorted(bk["family"]) == ["diagonal", "full"]
    jobs = pd.read_parquet(zermelo_run)
    ok = jobs[jobs["status"] == "ok"]
    assert bk.set_index("family").loc["diagonal", "best_known"] == pytest.approx(
        ok.loc[ok["param"] == "diagonal", "best_cost"].min())
    targets = pd.read_csv(out / "targets.csv", keep_default_na=False)
    assert set(targets["epsilon"]) == {0.01, 0.001}
    for name in ("anytime_zermelo_default.png", "ecdf_zermelo_default.png",
                 "costs_zermelo_default.png", "anytime_zermelo_default_warm_start_0_3.png"):
        assert (out / name).stat().st_size > 0


def test_results_without_traces_still_report(zermelo_run, tmp_path):
    """Schema-2 results (no traces, budgets or warm starts) give every table, no anytime."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    old = pq.read_table(zermelo_run).drop_columns(["trace_evals", "trace_best", "max_evals",
                                                   "warm_start"])
    old = old.set_column(old.schema.get_field_index("schema_version"), "schema_version",
                         pa.array([2] * old.num_rows, pa.int64()))
    (tmp_path / "old").mkdir()
    pq.write_table(old, tmp_path / "old" / "results.parquet")
    out = build_report(tmp_path / "old", tmp_path / "report")
    text = (out / "report.md").read_text()
    assert "## Best-known optima" in text and "## Map vs map" in text
    assert "anytime and ECDF figures skipped" in text
    assert "Fixed targets" not in text
    assert not list(out.glob("anytime_*.png")) and (out / "costs_zermelo_default.png").exists()


def test_zermelo_held_out_section(tmp_path):
    cells = [("zermelo", "default", param, "pso", 2, {"holdout_radii": [2.0, 5.0]})
             for param in ("diagonal", "full")]
    run_cells(tmp_path / "run", cells)
    out = build_report(tmp_path / "run", tmp_path / "report")
    text = (out / "report.md").read_text()
    assert "## Held-out scenarios: Zermelo" in text
    held = pd.read_csv(out / "holdout_zermelo.csv")
    assert list(held["scenarios"]) == [16]
    assert (out / "holdout_zermelo.png").stat().st_size > 0
