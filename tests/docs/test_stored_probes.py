"""The cliff probes committed beside each study's results (``probe.parquet``): every point
the report probes has one, each one's cost at its point is what the problem computes now,
and (slow) one whole probe per study is what probing again gives. A stored probe that the
code no longer reproduces fails here, not silently in a report."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from penaltyrun.docsgen.probe import report_points
from penaltyrun.docsgen.studies import list_studies
from penaltyrun.io import storedprobe
from penaltyrun.io.schema import read_results
from penaltyrun.optim.probe import STEPS
from penaltyrun.report import cliffs

ROOT = Path(__file__).resolve().parents[2]
STUDIES = list_studies(ROOT)


def _points(name: str) -> tuple[list[dict], object]:
    folder = ROOT / "studies" / name
    return (report_points(read_results(folder / "results.parquet")),
            storedprobe.read_one(folder / storedprobe.PROBE_FILE))


@pytest.mark.parametrize("name", STUDIES)
def test_every_point_the_report_probes_is_stored_and_its_cost_is_current(name):
    points, stored = _points(name)
    assert points and len(stored) == len(points)
    for row in points:
        kept = storedprobe.lookup(stored, row["job_id"], row.get("config_hash"),
                                  row["best_z"], STEPS)
        assert kept is not None, row["job_id"]
        prob, layout = cliffs.rebuilt_layout(row)
        mats, scalars = layout.split(np.asarray(row["best_z"], float)[None])
        out = prob.evaluate_batch(mats, scalars or None)
        assert kept.cost == pytest.approx(float(out.cost[0]), rel=1e-9, abs=0.0)
        assert kept.converged == bool(out.converged[0])


@pytest.mark.slow
@pytest.mark.parametrize("name", STUDIES)
def test_one_stored_probe_per_study_is_what_probing_again_gives(name):
    points, stored = _points(name)
    row = min(points, key=lambda r: len(r["best_z"]))
    again, _ = cliffs.probe_row(row)
    kept = storedprobe.lookup(stored, row["job_id"], row.get("config_hash"), row["best_z"],
                              STEPS)
    np.testing.assert_array_equal(np.isnan(kept.change), np.isnan(again.change))
    np.testing.assert_allclose(kept.change, again.change, rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(kept.status_change, again.status_change)
