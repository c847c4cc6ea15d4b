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


def _long(costs, converged, by_deadline, arrival, labels):
    return {"scenario": labels, "cost": costs, "converged": converged,
            "converged_by_deadline": by_deadline, "arrival_time": arrival,
            "horizon": 5000.0, "training_horizon": 100.0}


def test_ratio_statistics_match_a_direct_scipy_computation():
    rng = np.random.default_rng(3)
    n = 40
    labels = [f"g{k}" for k in range(n)]
    jd = rng.uniform(0.5, 2.0, n)
    jf = jd * np.exp(rng.normal(0.3, 0.5, n))
    jf[:3] = 1000.0 + jf[:3]            # not converged by the horizon: graded cost
    conv_f = np.ones(n, bool)
    conv_f[:3] = False
    arr_d, arr_f = rng.uniform(100, 300, n), rng.uniform(200, 900, n)
    diag = _long(jd.tolist(), [True] * n, [False] * n, arr_d.tolist(), labels)
    full = _long(jf.tolist(), conv_f.tolist(), [False] * n,
                 [None if not c else a for c, a in zip(conv_f, arr_f)], labels)
    res = rh.paired(rh.scenario_table(diag), rh.scenario_table(full))
    ratio = jf / jd
    assert res["scenarios"] == res["n_ratio"] == n
    assert res["ratio_median"] == pytest.approx(np.median(ratio), rel=1e-12)
    assert res["ratio_q05"] == pytest.approx(np.quantile(ratio, 0.05), rel=1e-12)
    assert res["ratio_q95"] == pytest.approx(np.quantile(ratio, 0.95), rel=1e-12)
    assert res["full_cheaper"] == int(np.sum(jf < jd))
    assert res["full_cheaper_share"] == pytest.approx(np.mean(jf < jd))
    assert res["ratio_p"] == pytest.approx(
        stats.wilcoxon(np.log(jf) - np.log(jd), alternative="two-sided").pvalue, rel=1e-12)
    assert res["arrival_shift_median"] == pytest.approx(np.median((arr_f - arr_d)[3:]))
    assert res["diag_conv"] == 1.0 and res["full_conv"] == pytest.approx((n - 3) / n)
    assert res["diag_conv_deadline"] == res["full_conv_deadline"] == 0.0
    assert (res["judged_at"], res["horizon"], res["training_horizon"]) == ("5000", 5000.0,
                                                                           100.0)


def test_old_records_are_judged_at_the_deadline_with_a_note():
    res = rh.paired(rh.scenario_table(DIAG), rh.scenario_table(FULL))
    assert res["judged_at"] == rh.AT_DEADLINE and np.isnan(res["horizon"])
    # the ratio statistics still cover every scenario, the deadline column = converged
    assert res["n_ratio"] == 4 and res["full_cheaper"] == 2  # s1, s4
    assert res["diag_conv_deadline"] == res["diag_conv"] == 0.75
    assert np.isnan(res["arrival_shift_median"])


def test_holm_over_the_ratio_family():
    labels = [f"g{k}" for k in range(12)]
    d = _long([1.0] * 12, [True] * 12, [True] * 12, [1.0] * 12, labels)
    rows = [_job("diagonal", 1.0, True, d)]
    for k, param in enumerate(("full", "geagsp")):
        f = _long([2.0 + 0.1 * i + k for i in range(12)], [True] * 12, [True] * 12,
                  [1.0] * 12, labels)
        rows.append(_job(param, 0.9, True, f))
    table, ratios = rh.holdout_rows(pd.DataFrame(rows))
    from penaltyrun.report.stats import holm
    assert np.allclose(table["ratio_p_holm"], holm(table["ratio_p"].to_numpy(float)),
                       equal_nan=True)
    assert all(np.all(r > 1.0) for r in ratios.values())


def test_convergence_shares_are_shown_as_counts():
    assert rh.counts([1.0, 0.5, np.nan, 0.25], [24, 216, 10, 0]) == ["24/24", "108/216", "—",
                                                                    "—"]
