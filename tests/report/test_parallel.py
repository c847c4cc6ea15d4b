"""Case sections written by worker processes: the same report for any number of workers,
in order, nothing imported from the data in a worker, a dead worker costs only time."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io.schema import RESULTS_FILE, to_table
from penaltyrun.problems import trust
from penaltyrun.report import build_report, parallel
from penaltyrun.report.cases import write_sections

GOLDEN_INPUT = Path(__file__).parent / "golden" / "zermelo" / "input" / RESULTS_FILE


def _two_cases(folder: Path) -> Path:
    """The PSO diagonal and full starts of the golden Zermelo results, and the same jobs as
    a second case (unknown to this version: its section comes from the stored columns), in
    two files."""
    table = pq.read_table(GOLDEN_INPUT)
    keep = [o == "pso" and p in ("diagonal", "full")
            for o, p in zip(table["optimizer"].to_pylist(), table["param"].to_pylist())]
    table = table.filter(pa.array(keep))
    (folder / "a").mkdir(parents=True)
    (folder / "b").mkdir()
    pq.write_table(table, folder / "a" / RESULTS_FILE)
    other = table.set_column(table.schema.get_field_index("case"), "case",
                             pa.array(["other_case"] * len(table),
                                      table.schema.field("case").type))
    job_ids = pa.array([f"other-{j}" for j in other["job_id"].to_pylist()],
                       other.schema.field("job_id").type)
    other = other.set_column(other.schema.get_field_index("job_id"), "job_id", job_ids)
    pq.write_table(other, folder / "b" / RESULTS_FILE)
    return folder


@pytest.mark.slow  # two whole reports (~8 s); section order and progress stay in the default suite
def test_the_report_is_the_same_file_for_file_for_one_or_two_workers(tmp_path):
    """Figures, tables and text byte for byte (the probe and the basin maps, which are
    computed in the sections too, in the slow golden test of two studies)."""
    src = _two_cases(tmp_path / "in")
    one = build_report(src, tmp_path / "one", source_label="fixture", workers=1,
                       probe=False, basin_points=0)
    two = build_report(src, tmp_path / "two", source_label="fixture", workers=2,
                       probe=False, basin_points=0)
    names = sorted(p.name for p in one.iterdir())
    assert names == sorted(p.name for p in two.iterdir())
    for name in names:
        assert (one / name).read_bytes() == (two / name).read_bytes(), name
    text = (two / "report.md").read_text(encoding="utf-8")
    assert text.index("## zermelo / default") < text.index("## zermelo / other_case")


def test_sections_come_back_in_order_with_one_progress_call_each(tmp_path):
    src = _two_cases(tmp_path / "in")
    from penaltyrun.io.read import read_results
    from penaltyrun.report import holdout
    from penaltyrun.report.bestknown import best_known
    from penaltyrun.report.compare import pairwise
    from penaltyrun.report.stats import add_variant, cell_summary

    df = add_variant(read_results(src))
    held, imps = holdout.holdout_rows(df)
    ctx = {"summary": cell_summary(df), "comp": pairwise(df), "bk": best_known(df),
           "held": held, "imps": imps, "paper": pd.DataFrame(), "paper_matrices": {},
           "basin_points": 0,
           "probe": False, "probes": pd.DataFrame()}
    done: list[str] = []
    with trust.reading_results():
        lines = list(write_sections(df, ctx, tmp_path, False, 2, done.append))
    assert [section[0] for section in lines] == ["## zermelo / default",
                                                 "## zermelo / other_case"]
    assert sorted(done) == ["zermelo / default", "zermelo / other_case"]  # as they finish


def test_ordered_map_gives_results_in_the_order_of_the_bundles():
    labels: list[str] = []
    bundles = [(f"b{k}", -k) for k in range(7)]
    out = list(parallel.ordered_map(abs, bundles, 2, os.getpid, (), local=abs,
                                    done=labels.append))
    assert out == list(range(7))
    assert sorted(labels) == sorted(label for label, _ in bundles)


def test_a_dead_worker_costs_only_time(caplog):
    """``os._exit`` in the worker: the pool breaks, every bundle is written here."""
    with caplog.at_level(logging.WARNING, logger="penaltyrun.report.parallel"):
        out = list(parallel.ordered_map(os._exit, [("first", 3), ("second", 4)], 2,
                                        os.getpid, (), local=lambda code: f"here {code}"))
    assert out == ["here 3", "here 4"]
    assert "a report worker died" in caplog.text


def test_a_stopped_report_stops_its_workers_at_once():
    """The consumer stops (an error, Ctrl-C, SIGTERM): workers in the middle of a long
    bundle are terminated, not waited for."""
    import time

    results = parallel.ordered_map(time.sleep, [("quick", 0), ("long", 60), ("longer", 60)],
                                   2, os.getpid, (), local=time.sleep)
    assert next(results) is None
    started = time.monotonic()
    results.close()
    assert time.monotonic() - started < 20


def test_workers_never_start_by_a_plain_fork():
    assert parallel.pool_context().get_start_method() in ("forkserver", "spawn")


PLANTED = """
from pathlib import Path
Path({marker!r}).write_text("imported")
def f(X, U):
    Path({marker!r} + ".called").write_text("called")
    return X * 0.0
"""


def _planted_rows(folder: Path, problem: str, case: str, params: dict, config: str) -> None:
    """One diagonal and one full PSO cell of three converged starts each."""
    records = [{"job_id": f"{problem}-{param}-{k}", "problem": problem, "case": case,
                "param": param, "optimizer": "pso", "start": k, "seed": k, "status": "ok",
                "best_cost": 1.0 + k + (param == "full"), "best_converged": True,
                "n_evals": 10, "config_hash": "h",
                "matrices": {"K": [[1.0 + k, 0.0], [0.0, 1.0]]}, "scalars": {},
                "metrics": {}, "problem_params": params, "optimizer_settings": {},
                "config": config, "git_commit": "test"}
               for param in ("diagonal", "full") for k in range(3)]
    folder.mkdir(parents=True)
    pq.write_table(to_table(records, "run"), folder / RESULTS_FILE)


def test_a_worker_imports_nothing_named_in_the_data(tmp_path, monkeypatch):
    """S1 and S3 with the sections in workers: the module beside the results is on the
    workers' path too, and still nothing is imported or called."""
    folder = tmp_path / "received"
    folder.mkdir()
    marker = tmp_path / "MARKER"
    for name in ("planted_mod", "planted_plant"):
        (folder / f"{name}.py").write_text(PLANTED.format(marker=str(marker)),
                                           encoding="utf-8")
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.chdir(folder)
    config = "problem:\n  name: planted_problem\n  module: planted_mod\n"
    _planted_rows(folder / "s1", "planted_problem", "only", {}, config)
    _planted_rows(folder / "s3", "lqr", "default",
                  {"A": [[0.0, 1.0], [0.0, 0.0]], "B": [[0.0], [1.0]],
                   "dynamics": "planted_plant:f"}, "")
    out = build_report(folder, tmp_path / "report", workers=2)
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "## planted_problem / only" in text and "## lqr / default" in text
    assert not marker.exists() and not Path(str(marker) + ".called").exists()


def test_trust_snapshot_restores_what_the_user_named():
    """Other tests of this process may have named modules: they are kept as they were."""
    before = trust.snapshot()
    try:
        trust.name_module("mine", "mylab.problems")
        trust.allow_module("mylab.plants")
        state = trust.snapshot()
        trust.forget_named()
        assert trust.named() == {} and not trust.allowed("mylab.plants")
        trust.restore(state)
        assert trust.named()["mine"] == "mylab.problems" and trust.allowed("mylab.plants")
        assert trust.snapshot() == state
    finally:
        trust.restore(before)


def test_a_bad_workers_option_is_one_line_and_exit_2(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", str(GOLDEN_INPUT),
                           "-o", str(tmp_path / "r"), "--workers", "0"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "--workers" in lines[0] and "positive integer" in lines[0]
    assert not (tmp_path / "r").exists()
