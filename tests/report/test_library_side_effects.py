"""Importing the report leaves the caller's matplotlib backend alone (a library must not
choose it; the command line picks Agg for itself)."""

from __future__ import annotations

import subprocess
import sys

import pytest


def test_report_modules_keep_the_callers_backend():
    code = ("import matplotlib; matplotlib.use('svg'); "
            "import penaltyrun.report, penaltyrun.report.figures, penaltyrun.report.holdout, "
            "penaltyrun.report.sections; print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "svg"


@pytest.mark.slow  # two whole reports in a subprocess (~13 s)
def test_the_library_report_keeps_arrows_memory_pool_the_command_line_makes_it_lean(tmp_path):
    """Reporting through the library leaves Arrow's memory pool as the caller had it; the
    command line (a process of its own) gives freed memory back to the system
    (:func:`penaltyrun.io.memory.lean_process_memory`)."""
    from large_results import write_large_results

    src = write_large_results(tmp_path / "results", 24)
    code = ("import sys, pyarrow as pa, penaltyrun.report as r\n"
            "from pathlib import Path\n"
            "before = pa.default_memory_pool().backend_name\n"
            "r.build_report(Path(sys.argv[1]), Path(sys.argv[2]) / 'lib', basin_points=0)\n"
            "print('pool', before, pa.default_memory_pool().backend_name)\n"
            "from penaltyrun.cli import report_main\n"
            "report_main([sys.argv[1], '-o', sys.argv[2] + '/cli', '--basin-points', '0'])\n"
            "print('pool', pa.default_memory_pool().backend_name)\n")
    done = subprocess.run([sys.executable, "-c", code, str(src), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    library, command_line = (line.split()[1:] for line in done.stdout.splitlines()
                             if line.startswith("pool "))
    assert library[0] == library[1] != "system"
    assert command_line == ["system"]
    assert (tmp_path / "lib" / "report.md").is_file()
    assert (tmp_path / "cli" / "report.md").is_file()
