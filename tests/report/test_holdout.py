"""Held-out report statistics against hand computations."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from penaltyrun.report import holdout as rh


def _job(param, cost, converged, held, best_converged=True, status="ok"):
    return {"problem": "qlaw", "case": "A", "variant": "", "optimizer": "pso",
            "param": param, "status": status, "best_cost": cost,
            "best_converged": best_converged, "holdout": json.dumps(held)}


DIAG = {"scenario": ["s1", "s2", "s3", "s4"], "cost": [10.0, 20.0, 30.0, 40.0],
        "converged": [True, True, True, False]}
#: Full listed in another order (pairing is by label), s2 not converged.
FULL = {"scenario": ["s4", "s3", "s2", "s1"], "cost": [35.0, 33.0, 50.0, 8.0],
        "converged": [True, True, False, True]}


def test_paired_by_label_matches_hand_computation():
    res = rh.paired(rh.scenario_table(DIAG), rh.scenario_table(FULL))
    # both converged: s1 (10 vs 8: +20 %) and s3 (30 vs 33: −10 %)
    assert res["scenarios"] == 4 and res["pairs"] == 2
    assert res["diag_conv"] == 0.75 and res["full_conv"] == 0.75
    assert res["full_better_share"] == 0.5
    np.testing.assert_allclose(np.sort(res["improvements"]), [-10.0, 20.0])
    assert res["median_imp_pct"] == pytest.approx(5.0)
    assert res["wilcoxon_p"] == pytest.approx(
        stats.wilcoxon([10.0, 30.0], [8.0, 33.0]).pvalue)
    assert "underpowered" in res["note"]


def test_rows_pick_best_converged_start_and_pool_all_starts():
    worse = {**DIAG, "converged": [False] * 4}
    df = pd.DataFrame([_job("diagonal", 17.0, True, DIAG),
                       _job("diagonal", 15.0, False, worse, best_converged=False),
                       _job("full", 16.0, True, FULL)])
    table, imps = rh.holdout_rows(df)
    row = table.iloc[0]
    assert row["pairs"] == 2  # the converged diagonal start (17.0) was paired, not 15.0
    assert row["diag_conv_all_starts"] == pytest.approx(3 / 8)
    assert row["full_conv_all_starts"] == pytest.approx(3 / 4)
    assert list(imps) == ["qlaw / A / pso / full", "qlaw / A / best-known (all optimizers) / full"]


def test_discretization_verdict():
    def held(train, steps):
        return {"scenario": ["departure:0", "step=40s", "substeps=2"],
                "kind": ["departure", "control_step", "substeps"],
                "cost": [99.0, *steps], "converged": [True, True, True],
                "training": {"cost": train, "converged": True}}

    df = pd.DataFrame([_job("diagonal", 17.60, True, held(17.60, [19.4, 17.58])),
                       _job("full", 17.50, True, held(17.50, [17.55, 17.52]))])
    row = rh.discretization_rows(df).iloc[0]
    assert row["saving"] == pytest.approx(0.10)
    assert row["diag_spread"] == pytest.approx(19.4 - 17.58)
    assert row["full_spread"] == pytest.approx(0.05)
    assert row["verdict"] == "within discretization noise"
    tight = pd.DataFrame([_job("diagonal", 17.60, True, held(17.60, [17.61, 17.60])),
                          _job("full", 17.00, True, held(17.00, [17.02, 17.01]))])
    assert rh.discretization_rows(tight).iloc[0]["verdict"] == "beyond the spread"


def test_old_results_without_labels_pair_by_position(tmp_path):
    old = {"cost": [1.0, 2.0], "converged": [True, True]}
    new = {"cost": [0.5, 2.5], "converged": [True, True]}
    df = pd.DataFrame([{**_job("diagonal", 1.0, True, old), "problem": "attitude_lqr"},
                       {**_job("full", 0.9, True, new), "problem": "attitude_lqr"}])
    table, imps = rh.holdout_rows(df)
    lines = rh.problem_section(df, table, imps, tmp_path)
    assert lines[0] == "### Held-out scenarios"
    assert "rest-to-rest starts" in lines[2]  # the problem describes its held-out set
    assert list(table["pairs"]) == [2, 2]
    assert (tmp_path / "holdout_attitude_lqr_A.png").exists()


def test_file_stem_keeps_long_labels_within_file_system_limits():
    from penaltyrun.report.tables import file_stem
    label = "attitude_lyapunov_rest_to_rest_train_scenarios=" + repr(
        [{"attitude": [60.0 + k, 80.0, -60.0]} for k in range(8)])
    other = label.replace("67.0", "68.5")
    stem = file_stem(label)
    assert len(stem) == 80 and stem.replace("_", "").isalnum()
    assert file_stem(other) != stem and file_stem("a-b") == "a-b"
    assert file_stem("a b") != file_stem("a_b") and file_stem("a b").startswith("a_b_")
