"""A cell of many starts is reported in bounded memory: its bootstrap intervals are computed
in batches (measured as the peak resident memory of a fresh process)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from large_results import CELLS, write_large_results  # noqa: E402

CHILD = """
import json, resource, sys
from penaltyrun.io import read_results
from penaltyrun.report.build import REPORT_COLUMNS
from penaltyrun.report.stats import add_variant, cell_summary
df = add_variant(read_results(sys.argv[1], REPORT_COLUMNS))
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
summary = cell_summary(df)
print(json.dumps({"rows": len(df), "cells": len(summary),
                  "ci": int(summary["median_ci95_lo"].notna().sum()),
                  "read_kb": base, "peak_kb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
"""


def _summary_in_child(path: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(path)], capture_output=True,
                         text=True, check=True, timeout=1800)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_large_results_writer_writes_the_schema_in_row_groups(tmp_path):
    import pyarrow.parquet as pq

    from penaltyrun.io import read_results

    path = write_large_results(tmp_path, 2 * len(CELLS) + 1)
    df = read_results(path)
    assert len(df) == 2 * len(CELLS) + 1 and df["job_id"].is_unique
    assert pq.ParquetFile(path).metadata.num_rows == len(df)
    assert (df.loc[df["status"] == "ok", "best_cost"] < 1e3).all()


@pytest.mark.slow
def test_cells_of_10000_starts_get_intervals_in_bounded_memory(tmp_path):
    """12 cells × 10 000 starts: one bootstrap call per interval would hold 9999 × 10 000
    values (0.8 GB) and a 10 000 × 9 999 jackknife (0.8 GB); in batches the summary adds
    well under 500 MB to what reading the rows takes."""
    got = _summary_in_child(write_large_results(tmp_path, 10_000 * len(CELLS)))
    assert got["rows"] == 10_000 * len(CELLS) and got["ci"] == got["cells"] == len(CELLS)
    assert (got["peak_kb"] - got["read_kb"]) < 500_000
