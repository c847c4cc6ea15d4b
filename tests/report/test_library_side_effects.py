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
