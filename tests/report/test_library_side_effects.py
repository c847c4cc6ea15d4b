"""Importing the report leaves the caller's matplotlib backend alone (a library must not
choose it; the command line picks Agg for itself)."""

from __future__ import annotations

import subprocess
import sys


def test_report_modules_keep_the_callers_backend():
    code = ("import matplotlib; matplotlib.use('svg'); "
            "import penaltyrun.report, penaltyrun.report.figures, penaltyrun.report.holdout, "
            "penaltyrun.report.sections; print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "svg"


def test_the_library_report_keeps_arrows_memory_pool_the_command_line_makes_it_lean(tmp_path):
    """Reporting through the library leaves Arrow's memory pool as the caller had it; the
    command line (a process of its own) gives freed memory back to the system
    (:func:`penaltyrun.io.read.lean_process_memory`)."""
    code = ("import sys, pyarrow as pa, penaltyrun.report as r\n"
            "before = pa.default_memory_pool().backend_name\n"
            "try:\n    r.build_report(sys.argv[1], sys.argv[2])\n"
            "except FileNotFoundError:\n    pass\n"
            "print(before, pa.default_memory_pool().backend_name)\n"
            "from penaltyrun.cli import report_main\n"
            "try:\n    report_main([sys.argv[1], '-o', sys.argv[2]])\n"
            "except SystemExit:\n    pass\n"
            "print(pa.default_memory_pool().backend_name)\n")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "none"),
                          str(tmp_path / "out")], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out[0] == out[1] != "system"
    assert out[2] == "system"
