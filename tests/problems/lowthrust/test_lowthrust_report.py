"""The low-thrust transfer table: statistics of the converged starts' metrics, NaN (and no
warning) where the records carry none."""

import math
import warnings

from penaltyrun.problems.lowthrust.report import transfer_table


def _job(tof, mass=None, converged=True):
    metrics = {"tof_days": tof, "status": "converged"}
    if mass is not None:
        metrics["final_mass_kg"] = mass
    return {"status": "ok", "case": "E", "variant": "", "optimizer": "pso", "param": "full",
            "converged": converged, "metrics": metrics}


def test_statistics_of_the_converged_starts():
    jobs = [_job(10.0, 90.0), _job(12.0, 88.0), _job(5.0, 99.0, converged=False)]
    (row,) = transfer_table("qlaw", jobs).tables[0][1]
    assert row["best ToF d"] == 10.0 and row["mean ToF d"] == 11.0
    assert row["best m_f kg"] == 90.0 and row["mean m_f kg"] == 89.0
    assert row["converged"] == "2/3"


def test_a_metric_no_record_carries_is_nan_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (row,) = transfer_table("qlaw", [_job(10.0), _job(11.0)]).tables[0][1]
    assert math.isnan(row["best m_f kg"]) and math.isnan(row["mean m_f kg"])
    assert row["best ToF d"] == 10.0
