"""The report end to end on small real runs of every problem family (Parquet → files)."""

import pandas as pd
import pytest

from penaltyrun import io, runner
from penaltyrun.report import build_report

TINY = {"n_particles": 4, "iters": 2, "ftol_iter": 2}


def run_cells(run_dir, cells):
    jobs = []
    for problem, case, param, optimizer, n, params in cells:
        options = TINY if optimizer == "pso" else {}
        jobs += runner.plan_jobs(problem, case, param, optimizer, n_starts=n, root_seed=7,
                                 problem_params=params, optimizer_options=options,
                                 meta={"git_commit": "test"})
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


@pytest.mark.slow
def test_attitude_tables_figures_and_studies(attitude_report):
    text = (attitude_report / "report.md").read_text(encoding="utf-8")
    assert text.index("## Verdict") < text.index("## attitude_lqr / detumble")
    for heading in ("Table 1 — attitude LQR layout (pso)", "Table 2 — attitude Lyapunov PD",
                    "horizon study", "### Held-out scenarios", "N²·m²·s"):
        assert heading in text
    assert "failed" not in text
    held = pd.read_csv(attitude_report / "holdout.csv")
    assert set(held["scenarios"]) == {8} and held["diag_conv"].between(0, 1).all()
    assert "8 rest-to-rest starts from the attitudes of a grid" in text
    paper = pd.read_csv(attitude_report / "summary.csv")
    lqr = paper[(paper["problem"] == "attitude_lqr") & (paper["case"] == "detumble")]
    assert lqr.set_index("param").loc["diagonal", "paper_mean"] == pytest.approx(0.423)
    published = pd.read_csv(attitude_report / "paper.csv")  # the Paper values tables as CSV
    assert {"attitude_lqr", "attitude_lyapunov"} <= set(published["problem"])
    assert published["Holm p"].dropna().between(0, 1).all()
    for name in ("attitude_lqr_detumble_histories.png",):
        assert (attitude_report / name).stat().st_size > 0
    assert list(attitude_report.glob("attitude_lyapunov_section*_horizon_study_*.png"))


def test_lowthrust_tables_and_case_e(tmp_path):
    cells = [("qlaw", "C", "diagonal", "pso", 2, {}), ("qlaw", "C", "full", "pso", 2, {}),
             ("qlaw", "C", "diagonal", "baseline", 1, {}),
             ("qlaw", "E", "diagonal", "baseline", 1, {"tof_cap_days": 20.0}),
             ("lyapunov_transfer", "C", "diagonal", "baseline", 1, {})]
    run_cells(tmp_path / "run", cells)
    out = build_report(tmp_path / "run", tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    for heading in ("Table 3 layout (case definitions used)", "Table 5 — Q-law layout",
                    "Table 4 — generic Lyapunov law layout", "original Case E",
                    "time of flight (days)", "### Discretization check",
                    "re-run at control steps"):
        assert heading in text
    assert "failed" not in text
    verdict = pd.read_csv(out / "verdict.csv", keep_default_na=False)
    row = verdict[verdict["case"] == "C"].iloc[0]
    assert row["discretization"] in ("within discretization noise", "beyond the spread")
    check = pd.read_csv(out / "discretization.csv", keep_default_na=False)
    assert row["discretization"] in set(check["verdict"])
    for name in ("qlaw_C_trajectory.png", "qlaw_C_elements.png", "qlaw_C_thrust.png"):
        assert (out / name).stat().st_size > 0


def test_lowthrust_report_without_case_e(tmp_path):
    """A plain `penaltyrun problem=qlaw case=A` has no E/E* rows: the report must still build."""
    run_cells(tmp_path / "run", [("qlaw", "C", "diagonal", "baseline", 1, {})])
    text = (build_report(tmp_path / "run", tmp_path / "report") / "report.md").read_text(
        encoding="utf-8")
    assert "Table 5 — Q-law" in text
    assert "original Case E" not in text
    assert "failed" not in text


@pytest.fixture(scope="module")
def zermelo_run(tmp_path_factory):
    """Small real Zermelo study at one budget: pso, cmaes, grid, and a warm-started pso."""
    root = tmp_path_factory.mktemp("zermelo")
    budget = {"max_evals": 90}
    jobs = []
    for param in ("diagonal", "full"):
        jobs += runner.plan_jobs("zermelo", "default", param, "pso", n_starts=3, root_seed=7,
                                 optimizer_options={**budget, "n_particles": 6, "iters": 100})
        jobs += runner.plan_jobs("zermelo", "default", param, "cmaes", n_starts=3, root_seed=7,
                                 optimizer_options=budget)
        jobs += runner.plan_jobs("zermelo", "default", param, "grid", n_starts=1, root_seed=7,
                                 optimizer_options={"points_per_dim": 9, "n_local": 1,
                                                    "local_max_evals": 40})
    jobs += runner.plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=7,
                             optimizer_options={**budget, "n_particles": 6, "iters": 100},
                             warm_start_share=0.3)
    runner.execute(jobs, root / "run")
    return io.collect(root / "run")


def test_zermelo_report_statistics_best_known_and_anytime(zermelo_run, tmp_path):
    out = build_report(zermelo_run, tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    for heading in ("## Verdict", "## Best-known optima", "Optimizer shortfall",
                    "### Map vs map", "Fixed targets: ERT",
                    "Holm families: (1) every equal-budget map-vs-map"):
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
    matrices = pd.read_csv(out / "paper_matrices.csv")  # ours against the published K
    assert set(matrices["map"]) == {"diagonal", "full"}
    assert (comp["note"] != "").all()  # 3 starts: underpowered, or budgets differ
    grid = comp[comp["optimizer"] == "grid"].iloc[0]
    assert grid["note"].startswith("budgets differ")  # grid spends what its grid needs
    assert "certified (grid + local search)" in text
    bk = pd.read_csv(out / "best_known.csv")
    assert sorted(bk["family"]) == ["diagonal", "full"]
    jobs = pd.read_parquet(zermelo_run)
    ok = jobs[jobs["status"] == "ok"]
    assert bk.set_index("family").loc["diagonal", "best_known"] == pytest.approx(
        ok.loc[ok["param"] == "diagonal", "best_cost"].min())
    targets = pd.read_csv(out / "targets.csv", keep_default_na=False)
    assert set(targets["epsilon"]) == {0.01, 0.001}
    for name in ("anytime_zermelo_default.png", "ecdf_zermelo_default.png",
                 "costs_zermelo_default.png", "anytime_zermelo_default_warm_start_0_3_*.png"):
        assert [p.stat().st_size > 0 for p in out.glob(name)] == [True]


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
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "## Best-known optima" in text and "### Map vs map" in text
    assert "anytime and ECDF figures skipped" in text
    assert "Fixed targets" not in text
    assert not list(out.glob("anytime_*.png")) and (out / "costs_zermelo_default.png").exists()


def test_zermelo_held_out_section(tmp_path):
    cells = [("zermelo", "default", param, "pso", 2, {"holdout_radii": [2.0, 5.0]})
             for param in ("diagonal", "full")]
    run_cells(tmp_path / "run", cells)
    out = build_report(tmp_path / "run", tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "### Held-out scenarios" in text and "16 starts on circles of radius 2, 5" in text
    head = "\n".join(text.splitlines()[:12])  # the answer is on the first screen
    assert "## Verdict" in head and "zermelo / default" in head and "held-out" in head
    held = pd.read_csv(out / "holdout.csv")
    assert list(held["scenarios"]) == [16, 16]  # the pso cell and the best-known pair
    assert (out / "holdout_zermelo_default.png").stat().st_size > 0
