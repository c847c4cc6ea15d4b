"""Companion-study section: our statistics over converged starts beside the authors'."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from penaltyrun.report import attitude, companion


def _df():
    rows = []
    for cost, conv in ((90.0, True), (100.0, True), (130.0, True), (900.0, False)):
        rows.append({"problem": "attitude_lyapunov", "case": "schaub_detumble", "variant": "",
                     "optimizer": "pso", "param": "diagonal", "status": "ok" if conv else
                     "diverged", "best_cost": cost, "best_converged": conv, "n_evals": 100})
    rows.append({**rows[0], "param": "geagsp", "best_cost": 60.0})
    return pd.DataFrame(rows)


def test_companion_table_hand_computation(tmp_path):
    table = companion.companion_table(_df()).set_index("map")
    diag = table.loc["diagonal"]
    assert (diag["starts"], diag["converged"]) == (4, 3)
    assert diag["ours best / median / mean / worst"] == "90.00 / 100.00 / 106.67 / 130.00"
    assert diag["theirs (PSO, 20 runs)"] == "86.53 / 95.23 / 96.69 / 110.96"
    assert table.loc["geagsp", "theirs (PSO, 20 runs)"] == "—"
    assert diag["evaluations per start, median (min–max)"] == "100 (100–100)"
    # converged 90 < 95.23 < 100, 130: 2 above, 1 below vs their 10 / 10; one finite p-value,
    # so Holm leaves it as it is
    assert diag["p (Holm)"] == pytest.approx(stats.fisher_exact([[2, 1], [10, 10]]).pvalue)
    assert np.isnan(table.loc["geagsp", "p (Holm)"])
    lines = companion.study_sections(_df(), tmp_path, paper=True)
    assert lines[0].startswith("## Attitude: the authors' companion study")
    assert (tmp_path / "companion_attitude.csv").exists()


def test_main_setup_tables_leave_out_the_companion_cases(tmp_path):
    assert attitude.study_sections(_df(), tmp_path, paper=True) == []


def test_median_test_by_hand():
    # 20 of ours above their median against their 10 / 10: a hypergeometric tail by hand
    p = companion.median_test(np.full(20, 2.0), their_median=1.0)
    from math import comb
    one_tail = sum(comb(20, k) * comb(20, 30 - k) for k in range(20, 21)) / comb(40, 30)
    assert p == pytest.approx(2 * one_tail)
    assert companion.median_test(np.array([0.5, 2.0]), 1.0) == pytest.approx(1.0)
    assert np.isnan(companion.median_test(np.array([1.0]), 1.0))


def test_their_cayley_tan_row_beside_our_cayley_tan_cell():
    rows = _df()
    rows = pd.concat([rows, rows.iloc[[0]].assign(param="cayley_tan", best_cost=61.0)])
    table = companion.companion_table(rows).set_index("map")
    assert table.loc["cayley_tan", "theirs (PSO, 20 runs)"] == "60.89 / 71.51 / 80.05 / 116.38"
