"""Discretization column of the low-thrust comparison tables, on a synthetic Parquet file."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from penaltyrun import io
from penaltyrun.io.schema import write_table_atomic
from penaltyrun.report import discretization as disc
from penaltyrun.report import lowthrust


def held(train, steps, substep, converged=(True, True, True)):
    """Held-out record: one departure (ignored by the check), two steps, one substep."""
    return {"scenario": ["departure:0", "step=40s", "step=60s", "substeps=2"],
            "kind": ["departure", "control_step", "control_step", "substeps"],
            "cost": [99.0, *steps, substep], "converged": [True, *converged],
            "training": {"cost": train, "converged": True}}


def job(case, param, start, tof, holdout, objective="min_time", converged=True):
    metrics = {"objective": objective, "tof_days": tof, "final_mass_kg": 300.0 - tof,
               "status": "converged" if converged else "tof_cap", "control_step_s": 80.7}
    return {"job_id": f"qlaw-{case}-{param}-pso-x-s{start:03d}", "problem": "qlaw",
            "case": case, "param": param, "optimizer": "pso", "start": start, "status": "ok",
            "best_cost": tof, "best_converged": converged, "metrics": metrics,
            "holdout": holdout, "problem_params": {}, "matrices": {"K": np.eye(5).tolist()}}


def synthetic(tmp_path):
    """Case A: saving 0.10 d, diagonal spreads 0.3 / 0.5 d → within noise.
    Case C: saving 1.0 d, spreads ≤ 0.04 d → beyond. Case D: no held-out data."""
    records = [
        job("A", "diagonal", 0, 17.60, held(17.60, [17.70, 17.90], 17.65)),   # spread 0.30
        job("A", "diagonal", 1, 17.60, held(17.60, [17.10, 17.50], 17.60)),   # spread 0.50
        job("A", "diagonal", 2, 30.00, held(30.0, [1.0, 1.0], 1.0, (False,) * 3),
            converged=False),                                                 # not counted
        job("A", "full", 0, 17.50, held(17.50, [17.51, 17.52], 17.50)),       # spread 0.02
        job("A", "full", 1, 17.50, held(17.50, [17.54, 17.50], 17.50)),       # spread 0.04
        job("C", "diagonal", 0, 3.00, held(3.00, [3.01, 3.02], 3.00)),        # spread 0.02
        job("C", "full", 0, 2.00, held(2.00, [2.04, 2.00], 2.01)),            # spread 0.04
        job("D", "diagonal", 0, 9.0, None),
        job("D", "full", 0, 8.0, None),
    ]
    path = tmp_path / "results.parquet"
    write_table_atomic(io.to_table(records, run_id="synthetic"), path)
    return io.read_results(path)


def test_k_spread_hand_computation():
    assert disc.k_spread(json.dumps(held(17.6, [17.7, 17.9], 17.65))) == pytest.approx(0.30)
    # non-converged re-evaluations are left out; fewer than two runs → NaN
    assert disc.k_spread(held(17.6, [17.7, 99.0], 1.0, (True, False, False))) == \
        pytest.approx(0.1)
    assert np.isnan(disc.k_spread(held(17.6, [1.0, 1.0], 1.0, (False,) * 3)))
    old = {"scenario": ["a"], "cost": [1.0], "converged": [True]}  # no kinds stored
    assert np.isnan(disc.k_spread(old)) and np.isnan(disc.k_spread(None))


def test_comparison_table_has_the_discretization_column(tmp_path):
    df = synthetic(tmp_path)
    table = lowthrust.comparison_table(df, "qlaw", paper=False).set_index("case")
    a = table.loc["A"]
    assert a["ToF saving d"] == pytest.approx(0.10)
    assert a["discr. spread"] == pytest.approx(0.40)  # median of 0.30 and 0.50
    assert a["discr. K (diag/full)"] == "2/2"
    assert a["discr. verdict"] == disc.WITHIN
    c = table.loc["C"]
    assert c["ToF saving d"] == pytest.approx(1.0)
    assert c["discr. spread"] == pytest.approx(0.04)
    assert c["discr. verdict"] == disc.BEYOND
    d = table.loc["D"]
    assert np.isnan(d["discr. spread"]) and d["discr. verdict"] == disc.UNKNOWN


def test_min_fuel_compares_the_final_mass_gain(tmp_path):
    records = [job("A", "diagonal", 0, 10.0, held(12.0, [12.5, 0.0], 12.2, (True, False, True)),
                   objective="min_fuel"),
               job("A", "full", 0, 11.0, held(11.0, [11.1, 0.0], 11.0, (True, False, True)),
                   objective="min_fuel")]
    # final mass 300 − tof: gain = (300 − 11) − (300 − 10) = −1 kg; spread 0.5 kg
    path = tmp_path / "results.parquet"
    write_table_atomic(io.to_table(records), path)
    row = lowthrust.comparison_table(io.read_results(path), "qlaw", paper=False).iloc[0]
    assert row["m_f gain kg"] == pytest.approx(-1.0)
    assert row["discr. spread"] == pytest.approx(0.5)
    assert row["discr. verdict"] == disc.BEYOND


def test_study_section_explains_the_column(tmp_path):
    df = synthetic(tmp_path)
    out = tmp_path / "report"
    out.mkdir()
    text = "\n".join(lowthrust.study_sections(df, out, paper=False))
    assert "within discretization noise" in text and "Discretization check" in text
    saved = pd.read_csv(out / "table_qlaw.csv")
    assert set(saved["discr. verdict"]) == {disc.WITHIN, disc.BEYOND, disc.UNKNOWN}
