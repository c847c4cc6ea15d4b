"""``penaltyrun mode=plan``, run as a user would: one screen, consistent numbers, nothing
written; bad input is one line; a real run logs the same forecast first."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

SMALL = ["problem=zermelo", "optimizer.n_particles=6", "optimizer.iters=4", "optimizer.ftol=0",
         "runner.forecast_samples=3", "runner.holdout=false"]


def cli(*args, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def rows(stdout: str) -> dict[str, list[str]]:
    """Table rows of the plan screen by cell label."""
    return {line.split()[0]: line.split() for line in stdout.splitlines()
            if re.match(r"^(zermelo|qlaw)\S+\s|^total\s+\d", line)}


def to_seconds(value: str, unit: str) -> float:
    return float(value) * {"s": 1.0, "min": 60.0, "h": 3600.0}[unit]


def test_plan_of_one_cell_is_consistent_and_writes_nothing(tmp_path):
    proc = cli("mode=plan", *SMALL, "param=full", "runner.n_starts=3",
               f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert out.startswith("penaltyrun plan: 1 cell, 3 jobs")
    row = rows(out)["zermelo/default/full/pso"]
    jobs, evals, extra = int(row[1]), int(row[2].replace(",", "")), int(row[3])
    assert (jobs, evals, extra) == (3, 6 * 4, 1)  # starts, particles × iterations, detail
    total = rows(out)["total"]
    assert int(total[2].replace(",", "")) == jobs * (evals + extra)
    mean = float(row[4])
    cpu = to_seconds(row[6], row[7])
    assert mean > 0 and cpu > 0
    assert cpu == pytest.approx(jobs * (evals + extra) * mean, rel=0.06)  # 2-3 digits shown
    for cores in ("64", "512"):
        assert re.search(rf"^\s+{cores}\s+\S+ (s|min|h)", out, re.M), out
    assert "3 random batches" in out
    assert not (tmp_path / "run").exists() and not (tmp_path / "outputs").exists()


def test_multirun_plan_is_one_screen_over_the_sweep(tmp_path):
    proc = cli("-m", "mode=plan", *SMALL, "param=diagonal,full", "runner.n_starts=2",
               "runner.workers=1", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    table = rows(proc.stdout)
    assert set(table) == {"zermelo/default/diagonal/pso", "zermelo/default/full/pso", "total"}
    assert proc.stdout.startswith("penaltyrun plan: 2 cells, 4 jobs (multirun")
    assert "cells in turn" in proc.stdout and "all cells at once" in proc.stdout
    assert "1 workers on" in proc.stdout
    assert len(proc.stdout.splitlines()) <= 40
    assert not (tmp_path / "multirun").exists() and not (tmp_path / "outputs").exists()


def test_plan_expands_an_experiments_sweep(tmp_path):
    proc = cli("-m", "mode=plan", "+experiment=lowthrust_paper_50x50", "case=C",
               "problem=qlaw", "runner.forecast_samples=0", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    table = rows(proc.stdout)
    assert set(table) == {"qlaw/C/diagonal/pso", "qlaw/C/full/pso", "total"}
    assert table["qlaw/C/full/pso"][1:3] == ["10", "2,500"]  # 10 starts × ≤ 50 × 50


@pytest.mark.parametrize(("mode", "args", "fragment"), [
    ("plan", ["runner.workers=0"], "runner.workers: must be a positive integer or auto"),
    ("plan", ["runner.forecast_samples=-1"], "runner.forecast_samples"),
    ("optimize", ["runner.workers=many"], "runner.workers: must be a positive integer or auto"),
])
def test_bad_input_is_one_line_exit_2(tmp_path, mode, args, fragment):
    proc = cli(f"mode={mode}", "problem=zermelo", *args, f"hydra.run.dir={tmp_path / 'r'}",
               cwd=tmp_path)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("penaltyrun: error: "), proc.stderr
    assert fragment in lines[0]


def test_a_run_logs_the_forecast_in_its_first_lines(tmp_path):
    run = tmp_path / "run"
    proc = cli(*SMALL, "param=diagonal", "runner.n_starts=2", "runner.report=false",
               f"hydra.run.dir={run}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    log = [line for line in (run / "penaltyrun.log").read_text().splitlines() if line]
    assert "2 jobs" in log[0]
    assert "forecast: 2 jobs × ≤ 24 evaluations" in log[1]
    assert "3 batches of 6" in log[2]
    assert "CPU" in log[3] and "64 cores" in log[3] and "512 cores" in log[3]


def test_a_glob_sweep_is_planned_and_run_over_its_group(tmp_path):
    """``param=glob(...)`` lists the group's configs through Hydra's config loader, which
    the checks before Hydra and the plan give it as Hydra's own sweeper does."""
    from penaltyrun.cli.planmode import expand_cells
    from penaltyrun.cli.preflight import preflight

    argv = ["-m", "param=glob(*,exclude=cayley*)", *SMALL, "runner.n_starts=1"]
    assert preflight([*argv, "mode=plan"]) == "plan"
    cells, multirun = expand_cells(argv)
    assert multirun and len(cells) >= 4
    proc = cli("mode=plan", *argv, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"penaltyrun plan: {len(cells)} cells, {len(cells)} jobs")
    labels = set(rows(proc.stdout))
    assert {"zermelo/default/diagonal/pso", "zermelo/default/givens/pso"} <= labels
    assert not any("cayley" in label for label in labels)
    run = cli(*argv, "runner.report=false", f"hydra.sweep.dir={tmp_path / 'sweep'}",
              cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    assert len(list((tmp_path / "sweep").glob("*/results.parquet"))) == len(cells)
