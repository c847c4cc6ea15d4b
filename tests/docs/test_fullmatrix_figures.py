"""The full-matrix page's data and figures on a tiny synthetic study (two cells, a few
starts, three held-out scenarios): what the page computes, and that every figure draws."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from penaltyrun.docsgen import fullmatrix
from penaltyrun.docsgen import fullmatrix_plots as plots
from penaltyrun.report.holdout import BEST_KNOWN

PNG = b"\x89PNG\r\n\x1a\n"
SCENARIOS = ["grid:10,10,10", "grid:10,10,350", "grid:350,10,10"]


def spd(diag: list[float], off: float = 0.0) -> list[list[float]]:
    M = np.diag(diag) + off * (np.ones((3, 3)) - np.eye(3))
    assert np.all(np.linalg.eigvalsh(M) > 0)
    return M.tolist()


def record(case: str, param: str, start: int, cost: float, kd: list[float], off: float,
           held: list[float] | None) -> dict:
    holdout = None if held is None else json.dumps({
        "scenario": SCENARIOS, "cost": held, "converged": [True] * 3,
        "converged_by_deadline": [False] * 3,
        "arrival_time": [150.0 + 10 * k for k in range(3)], "horizon": 5000.0,
        "training_horizon": 100.0})
    return {"job_id": f"{case}-{param}-s{start}", "config_hash": f"h-{case}-{param}",
            "problem": "attitude_lyapunov", "case": case, "param": param,
            "optimizer": "cmaes", "start": start, "status": "ok", "best_converged": True,
            "best_cost": cost, "problem_params": "{}", "scalars": None,
            "matrices": json.dumps({"Kp": spd([1.0, 1.5, 2.0]),
                                    "Kd": spd(kd, off)}),
            "holdout": holdout, "closed_loop": None, "cl_slowest_real": None}


@pytest.fixture(scope="module")
def frame() -> pd.DataFrame:
    rows = []
    for case in ("detumble", "rest_to_rest"):
        rows += [record(case, "diagonal", 0, 0.08, [6.0, 8.0, 10.0], 0.0, [0.05, 0.06, 0.07]),
                 record(case, "diagonal", 1, 0.09, [5.0, 8.0, 9.0], 0.0, None),
                 record(case, "cayley", 0, 0.02, [30.0, 40.0, 50.0], 25.0, [5.0, 0.03, 9.0]),
                 record(case, "cayley", 1, 0.03, [9.0, 9.0, 12.0], 2.0, None),
                 record(case, "cayley", 2, 0.05, [7.0, 9.0, 11.0], 1.0, None)]
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def mech(frame) -> fullmatrix.Mechanism:
    return fullmatrix.mechanism(frame)


def test_cells_pair_the_best_starts(mech):
    assert list(mech.cells["case"]) == ["detumble", "rest_to_rest"]
    cell = mech.cells.iloc[0]
    assert cell["diag_job"] == "detumble-diagonal-s0"
    assert cell["full_job"] == "detumble-cayley-s0"
    assert cell["saving_pct"] == pytest.approx(75.0)
    ratios = np.array([5.0 / 0.05, 0.03 / 0.06, 9.0 / 0.07])
    assert cell["ratio_median"] == pytest.approx(np.median(ratios))
    assert cell["full_cheaper"] == 1 and cell["scenarios"] == 3
    assert cell["diag_conv_n"] == 3 and cell["full_conv_deadline_n"] == 0
    assert cell["horizon"] == 5000.0 and cell["training_horizon"] == 100.0
    assert cell["n_full"] == 3 and np.isfinite(cell["rho"])
    assert cell["full_tau"] == pytest.approx(-1.0 / cell["full_slowest"])
    assert set(mech.pairs["optimizer"]) == {"cmaes", BEST_KNOWN}


def test_slowest_mode_equals_numpy_eig_of_the_closed_loop(frame, mech):
    row = frame.iloc[2]
    mats = {k: np.asarray(v) for k, v in json.loads(row["matrices"]).items()}
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(np.diag([10.0, 15.0, 20.0]))])
    s = np.linalg.eigvals(A - B @ np.hstack([mats["Kp"], mats["Kd"]]))
    got = mech.modes[(mech.modes["case"] == "detumble") & (mech.modes["param"] == "cayley")]
    assert got["slowest"].iloc[0] == pytest.approx(s.real.max(), rel=1e-9)
    assert mech.cells.iloc[0]["full_slowest"] == pytest.approx(s.real.max(), rel=1e-9)


def test_spearman_sign_and_degenerate_input():
    assert fullmatrix.spearman([1, 2, 3], [-0.01, -0.02, -0.03]) == pytest.approx(1.0)
    assert np.isnan(fullmatrix.spearman([1, 2], [-0.1, -0.2]))
    assert np.isnan(fullmatrix.spearman([1, 1, 1], [-0.1, -0.2, -0.3]))


def test_example_scenario_is_the_median_one(frame, mech):
    ex = fullmatrix.example_scenario(frame, mech, "attitude_lyapunov", "detumble")
    assert ex["scenario"] == "grid:10,10,10"  # ratios 100, 0.5, 128.6: the median is 100
    assert ex["ratio"] == pytest.approx(100.0)
    assert ex["diag_arrival"] == 150.0 and ex["full_cost"] == 5.0
    assert ex["horizon"] == 5000.0
    with pytest.raises(ValueError, match="no best-known"):
        fullmatrix.example_scenario(frame, mech, "attitude_lqr", "detumble")


def test_ratio_and_mode_figures_draw(mech, tmp_path: Path):
    for path in (plots.ratio_figure(mech.pairs, mech.ratios, tmp_path / "r.png"),
                 plots.mode_figure(mech.modes, tmp_path / "m.png", mech.cells)):
        assert path.read_bytes()[:8] == PNG and path.stat().st_size > 5000


def test_trajectory_figure_draws(tmp_path: Path):
    t = np.linspace(0.0, 200.0, 50)
    sim = {"t": t, "w": np.outer(np.exp(-t / 50), [0.01, -0.01, 0.02]),
           "J": 0.1 * (1 - np.exp(-t / 20)), "dist": np.exp(-t / 20)}
    path = plots.trajectory_figure({"diagonal": sim, "full": sim}, tmp_path / "t.png",
                                   "title", deadline=100.0)
    assert path.read_bytes()[:8] == PNG and path.stat().st_size > 5000
    again = plots.trajectory_figure({"diagonal": sim, "full": sim}, tmp_path / "t2.png",
                                    "title", deadline=100.0)
    assert again.read_bytes() == path.read_bytes()  # no time stamp: same data, same file
