"""The command line, run as a user would (subprocesses): outputs, errors, resume."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from cli_subprocess import bad_command_lines, popen

from penaltyrun.io import RESULTS_FILE

K2 = "[[1.7421,0.9560],[0.9560,1.1414]]"


def cli(*args, cwd: Path, check: bool = True) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)
    if check and proc.returncode != 0:
        raise AssertionError(f"exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}")
    return proc


def test_evaluate_prints_json_last_line(tmp_path):
    proc = cli("mode=evaluate", "problem=zermelo", f"matrices.K={K2}",
               f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert result["converged"] is True
    assert result["cost"] == pytest.approx(24.8264582, rel=1e-6)
    assert result["t_final"] == pytest.approx(20.848056, rel=1e-6)


def test_evaluate_accepts_plus_form(tmp_path):
    proc = cli("mode=evaluate", f"+matrices.K={K2}", f"hydra.run.dir={tmp_path / 'run'}",
               cwd=tmp_path, check=False)
    # `matrices.K` is pre-declared, so Hydra refuses `+` for it; the error must be readable.
    if proc.returncode != 0:
        assert "matrices.K" in proc.stderr and "Traceback" not in proc.stderr
    else:
        assert json.loads(proc.stdout.strip().splitlines()[-1])["converged"]


#: Bad command lines and the fragments their one error must name.
BAD_INPUTS = [
    (["problem=nope"], ["problem", "zermelo"]),
    (["param=spiral"], ["param", "diagonal", "givens"]),
    (["optimizer=adam"], ["optimizer", "pso"]),
    (["case=Z"], ["case", "allowed: default"]),
    (["optimizer.n_particles=0"], ["optimizer.n_particles", "positive"]),
    (["optimizer.iters=-5"], ["optimizer.iters", "positive"]),
    (["runner.n_starts=0"], ["runner.n_starts", "positive"]),
    (["runner.workers=0"], ["runner.workers", "positive"]),
    (["runner.backend=slurm"], ["runner.backend", "local, dask"]),
    (["mode=train"], ["mode", "optimize, evaluate, report"]),
    (["mode=evaluate"], ["matrices.K", "missing"]),
    (["mode=evaluate", "matrices.K=[[1,2],[3,4]]"], ["matrices.K", "not symmetric"]),
    (["mode=evaluate", "matrices.K=[[1,2],[2,1]]"], ["matrices.K", "positive definite"]),
    (["mode=evaluate", "matrices.K=[[1,0,0],[0,1,0],[0,0,1]]"], ["matrices.K", "2x2"]),
    (["mode=evaluate", "matrices.K=[[1,0],[0,1]]", "matrices.Kp=[[1]]"],
     ["matrices.Kp", "not a matrix"]),
    (["mode=evaluate", "matrices.K=[[1,0],[0"], ["matrices.K"]),
    (["mode=report"], ["report.input", "missing"]),
    (["param.eig_bounds=[0,10]"], ["param.eig_bounds"]),
    (["problem.params.speed=2"], ["problem.params.speed"]),
]


@pytest.fixture(scope="module")
def bad_input_runs(tmp_path_factory):
    """Every bad command line run at once (each in a process of its own, forked from one
    interpreter that imported the command line), with its own working directory."""
    return bad_command_lines(BAD_INPUTS, tmp_path_factory)


@pytest.mark.parametrize("case", range(len(BAD_INPUTS)),
                         ids=[" ".join(args) for args, _ in BAD_INPUTS])
def test_bad_input_is_one_readable_error(bad_input_runs, case):
    proc, cwd = bad_input_runs[case]
    fragments = BAD_INPUTS[case][1]
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr + proc.stdout
    for fragment in fragments:
        assert fragment in proc.stderr, proc.stderr
    assert len(proc.stderr.strip().splitlines()) <= 6, proc.stderr
    assert not (cwd / "run" / "jobs").exists()


@pytest.mark.slow  # about 20 s: two whole runs with reports
def test_optimize_writes_parquet_report_and_resumes(tmp_path):
    run = tmp_path / "run"
    args = ["problem=zermelo", "param=diagonal", "runner.n_starts=3", "runner.workers=2",
            "optimizer.iters=30", f"hydra.run.dir={run}"]
    cli(*args, cwd=tmp_path)
    df = pd.read_parquet(run / RESULTS_FILE)
    assert len(df) == 3 and set(df["status"]) == {"ok"}
    assert df["seed"].nunique() == 3
    assert (df["git_commit"].str.len() > 0).all() and (df["package_version"] == "0.1.0").all()
    assert df["config"].str.contains("problem:").all()
    assert (run / "report" / "report.md").exists()
    assert list((run / "report").glob("zermelo_default_phase_plane_*.png"))
    assert not (tmp_path / "report.log").exists()

    # A killed run keeps its finished jobs: drop one record and resume.
    jobs = sorted((run / "jobs").glob("*.json"))
    kept = {p.name: p.stat().st_mtime_ns for p in jobs[1:]}
    jobs[0].unlink()
    proc = cli(*args, "runner.resume=true", "runner.n_starts=4", cwd=tmp_path)
    assert "2 of 4 jobs already finished" in proc.stderr + proc.stdout
    after = {p.name: p.stat().st_mtime_ns for p in (run / "jobs").glob("*.json")}
    assert len(after) == 4
    assert all(after[name] == mtime for name, mtime in kept.items())
    df2 = pd.read_parquet(run / RESULTS_FILE)
    assert len(df2) == 4
    # resumed jobs reproduce the seeds of the first run
    assert set(df["seed"]) <= set(df2["seed"])


@pytest.mark.slow  # about 15 s: a sweep of two runs and a report
def test_multirun_sweep_and_report_command(tmp_path):
    sweep = tmp_path / "sweep"
    cli("-m", "param=diagonal,full", "runner.n_starts=2", "optimizer.iters=25",
        "runner.report=false", f"hydra.sweep.dir={sweep}", cwd=tmp_path)
    assert len(list(sweep.rglob(RESULTS_FILE))) == 2
    out = tmp_path / "rep"
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", str(sweep), "-o",
                           str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    comparison = pd.read_csv(out / "comparison.csv")
    assert list(zip(comparison["map_a"], comparison["map_b"])) == [("diagonal", "full")]
    assert {"median_change_pct", "a12_b_beats_a", "p_mwu", "p_holm"} <= set(comparison.columns)
    text = (out / "report.md").read_text()
    assert "### Map vs map" in text and "paper K" in text
    for name in ("anytime_zermelo_default.png", "costs_zermelo_default.png",
                 "zermelo_default_phase_plane_*.png", "summary.md", "comparison.md",
                 "best_known.md"):
        assert list(out.glob(name)), name
    # mode=report is the same report through the Hydra app
    cli("mode=report", f"report.input={sweep}", f"report.output={tmp_path / 'rep2'}",
        f"hydra.run.dir={tmp_path / 'r2'}", cwd=tmp_path)
    assert (tmp_path / "rep2" / "comparison.csv").exists()


def test_report_of_missing_input_is_clear(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli",
                           str(tmp_path / "nothing")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "does not exist" in proc.stderr and "Traceback" not in proc.stderr


def test_report_keeps_its_sections_in_the_cache_folder_it_is_given(tmp_path):
    golden = Path(__file__).parents[1] / "report" / "golden" / "zermelo" / "input"
    both = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", str(golden), "-o",
                           str(tmp_path / "x"), "--no-cache", "--cache-dir", str(tmp_path)],
                          capture_output=True, text=True)
    assert both.returncode == 2 and "--no-cache" in both.stderr
    assert len(both.stderr.strip().splitlines()) == 1
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", str(golden), "-o",
                           str(tmp_path / "rep"), "--cache-dir", str(tmp_path / "cache"),
                           "--no-probe", "--basin-points", "0", "--workers", "1"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert list((tmp_path / "cache").rglob("manifest.json"))


@pytest.mark.slow  # about 25 s; SIGTERM, handled the same way, stays in the default suite
def test_ctrl_c_keeps_finished_jobs_and_resume_completes(tmp_path):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) mid-run.

    Few long jobs (about 3 s of CPU each: 400 particles × 200 iterations), so that the run
    is still going seconds after its first record lands, however loaded the machine."""
    run = tmp_path / "run"
    args = ["problem=zermelo", "param=full", "runner.n_starts=8", "runner.workers=2",
            "optimizer.n_particles=400", "optimizer.iters=200", "optimizer.ftol_iter=200",
            "runner.report=false", f"hydra.run.dir={run}"]
    proc = popen(*args, cwd=tmp_path)
    deadline = time.monotonic() + 120
    while not list((run / "jobs").glob("*.json")) and time.monotonic() < deadline:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert "runner.resume=true" in err.strip().splitlines()[-1]
    records = [json.loads(p.read_text()) for p in (run / "jobs").glob("*.json")]
    assert 1 <= len(records) < 8
    assert {r["status"] for r in records} == {"ok"}  # jobs in flight are not recorded

    resumed = cli(*args, "runner.resume=true", cwd=tmp_path)
    assert f"{len(records)} of 8 jobs already finished" in resumed.stderr + resumed.stdout
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 8
