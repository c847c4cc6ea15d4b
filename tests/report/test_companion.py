"""Companion-study section: our statistics over converged starts beside the authors'."""

from __future__ import annotations

import pandas as pd

from penaltyrun.report import attitude, companion


def _df():
    rows = []
    for cost, conv in ((90.0, True), (100.0, True), (130.0, True), (900.0, False)):
        rows.append({"problem": "attitude_lyapunov", "case": "schaub_detumble", "variant": "",
                     "optimizer": "pso", "param": "diagonal", "status": "ok" if conv else
                     "diverged", "best_cost": cost, "best_converged": conv})
    rows.append({**rows[0], "param": "geagsp", "best_cost": 60.0})
    return pd.DataFrame(rows)


def test_companion_table_hand_computation(tmp_path):
    table = companion.companion_table(_df()).set_index("map")
    diag = table.loc["diagonal"]
    assert (diag["starts"], diag["converged"]) == (4, 3)
    assert diag["ours best / median / mean / worst"] == "90.00 / 100.00 / 106.67 / 130.00"
    assert diag["theirs (PSO, 20 runs)"] == "86.53 / 95.23 / 96.69 / 110.96"
    assert table.loc["geagsp", "theirs (PSO, 20 runs)"] == "—"
    lines = companion.study_sections(_df(), tmp_path, paper=True)
    assert lines[0].startswith("## Attitude: the authors' companion study")
    assert (tmp_path / "companion_attitude.csv").exists()


def test_main_setup_tables_leave_out_the_companion_cases(tmp_path):
    assert attitude.study_sections(_df(), tmp_path, paper=True) == []
