"""A report read lazily (the per-row text and list columns read per cell, as for a large
results set) is the same report as one read whole: every table, report.md and report.html
byte for byte, the same figures; a million rows are reported in bounded memory, with a
progress bar."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from penaltyrun.report import build_report
from penaltyrun.report.anytime import anytime_band

sys.path.insert(0, str(Path(__file__).parent))
from large_results import CELLS, write_large_results  # noqa: E402

GOLDEN = Path(__file__).parent / "golden"


def _both(src: Path, tmp_path: Path, **kw) -> tuple[Path, Path]:
    whole = build_report(src, tmp_path / "whole", stream=False, source_label="x", **kw)
    lazy = build_report(src, tmp_path / "lazy", stream=True, source_label="x", **kw)
    return whole, lazy


def _assert_same(whole: Path, lazy: Path) -> None:
    names = sorted(p.name for p in whole.iterdir())
    assert names == sorted(p.name for p in lazy.iterdir())
    assert any(n.endswith(".png") for n in names) and "report.md" in names
    for name in names:
        if name.endswith((".csv", ".md", ".html")):
            assert (whole / name).read_bytes() == (lazy / name).read_bytes(), name


@pytest.mark.slow
def test_a_lazily_read_report_equals_the_report_read_whole(tmp_path, monkeypatch):
    """Every figure is drawn from the same data (its pixels are not compared here, and
    not rendered: a placeholder file stands for each, which keeps the test fast)."""
    import matplotlib.figure

    monkeypatch.setattr(matplotlib.figure.Figure, "tight_layout", lambda self, **kw: None)
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig",
                        lambda self, path, **kw: Path(path).write_bytes(b"\x89PNG"))
    src = write_large_results(tmp_path / "results", 2 * len(CELLS))
    _assert_same(*_both(src, tmp_path, basin_points=0))


@pytest.mark.slow
def test_a_lazily_read_report_of_two_studies_equals_the_report_read_whole(tmp_path,
                                                                        monkeypatch):
    """Held-out data (re-judged files), problem sections, tuning modes, controllers; the
    lazily read rows in batches of 3 (the held-out data of many batches)."""
    from penaltyrun.report import rows

    monkeypatch.setattr(rows, "BATCH_ROWS", 3)
    _assert_same(*_both(GOLDEN / "two_studies" / "input", tmp_path, basin_points=4))


def test_the_anytime_band_is_the_same_in_batches_of_grid_points(monkeypatch):
    from penaltyrun.report import anytime

    rng = np.random.default_rng(3)
    traces = []
    for _ in range(40):
        evals = np.sort(rng.choice(np.arange(1, 500), rng.integers(1, 8), replace=False))
        traces.append((evals.astype(float), np.sort(rng.random(evals.size))[::-1], 500.0))
    grid = np.unique(np.geomspace(1, 500, 60).round())
    whole = anytime_band(traces, grid)
    monkeypatch.setattr(anytime, "BAND_VALUES", 7 * len(traces))  # 7 grid points a batch
    for a, b in zip(whole, anytime_band(traces, grid)):
        np.testing.assert_array_equal(a, b)


#: Peak resident memory allowed for the report of a million rows. Read whole, the report
#: of these rows passed 1.6 GB by its sixth step (of 15); read lazily its peak measured
#: 0.83 GB with the command's process settings (bench/README.md): the imported libraries
#: (about 0.2 GB), the rows' small columns, memory the allocators keep after each step, and
#: one case's rows with its cells' traces.
MILLION_ROWS_KB = 1_100_000

CHILD = """
import json, resource, sys
from penaltyrun.cli import report_main
report_main([sys.argv[1], "-o", sys.argv[2], "--progress", "true", "--basin-points", "0"])
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"peak_kb": usage.ru_maxrss, "cpu_s": usage.ru_utime + usage.ru_stime}))
"""


@pytest.mark.slow
def test_a_million_rows_are_reported_in_bounded_memory_with_progress(tmp_path):
    """1e6 job rows in 12 cells (one problem case): the report completes within
    :data:`MILLION_ROWS_KB` of peak resident memory and draws its progress bar when asked
    to."""
    src = write_large_results(tmp_path / "results", 1_000_000)
    done = subprocess.run([sys.executable, "-c", CHILD, str(src), str(tmp_path / "report")],
                          capture_output=True, text=True, timeout=3600)
    assert done.returncode == 0, done.stderr[-3000:]
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got["peak_kb"] < MILLION_ROWS_KB, got
    assert "report: 100%" in done.stderr and "step" in done.stderr
    summary = (tmp_path / "report" / "summary.csv").read_text(encoding="utf-8")
    assert summary.count("\n") == len(CELLS) + 1
    text = (tmp_path / "report" / "report.md").read_text(encoding="utf-8")
    assert "1000000 jobs" in text


def test_the_progress_bar_counts_the_steps_and_is_off_unless_asked(capsys):
    from penaltyrun.report.progress import Steps

    with Steps(3, enabled=True) as steps:
        for name in ("cell statistics", "case 1/1: zermelo / default", "report.md"):
            steps.step(name)
    err = capsys.readouterr().err
    assert "3/3" in err and "case 1/1: zermelo / default" in err
    with Steps(3) as steps:  # stderr captured: not a terminal, no bar
        steps.step("cell statistics")
    assert capsys.readouterr().err == ""
