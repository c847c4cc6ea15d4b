"""Problem-level tests of the generic Lyapunov law (problems.lowthrust.lyapunov_transfer)."""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.lowthrust import lyapunov_transfer as lyap

matplotlib.use("Agg")

EYE = {"K": np.eye(5)}


def test_contract() -> None:
    prob = make("lyapunov_transfer", "B", {})
    assert prob.name == "lyapunov_transfer" and prob.case == "B"
    assert prob.scalars == ()
    assert prob.matrices[0].size == 5
    with pytest.raises(ConfigError):
        lyap.make_problem("Z", {})
    with pytest.raises(ConfigError) as exc:
        lyap.make_problem("A", {"eta_cut": 0.3})
    assert exc.value.key == "problem.params.eta_cut"
    with pytest.raises(ConfigError):
        prob.evaluate({"K": np.eye(3)})


@pytest.mark.parametrize(("case", "tof"), [("A", 14.6), ("B", 146.0)])
def test_identity_converges(case, tof) -> None:
    res = lyap.make_problem(case, {}).evaluate(EYE)
    assert res["converged"]
    assert res["tof_days"] == pytest.approx(tof, rel=0.03)
    json.dumps(res)


def test_case_c_impacts_without_periapsis_penalty() -> None:
    prob = lyap.make_problem("C", {})
    batch = prob.evaluate_batch({"K": np.eye(5)[None]})
    assert batch.status[0] == "impact" and not batch.converged[0]
    assert np.isfinite(batch.cost[0]) and batch.cost[0] > prob.params.tof_cap_days
    sim = prob.simulate(EYE)
    rp = sim["a"][-1] * (1.0 - sim["e"][-1])
    assert rp < 6378.137


@pytest.mark.parametrize(("overrides", "status"), [
    ({"tof_cap_days": 2.0}, "tof_cap"),
    ({"max_revs": 3.0}, "rev_cap"),
    ({"mass_floor_kg": 299.5}, "propellant"),
    ({"max_steps": 5}, "stall"),
])
def test_failure_statuses(overrides, status) -> None:
    res = lyap.make_problem("A", overrides).evaluate(EYE)
    assert res["status"] == status and not res["converged"]


def test_full_matrix_and_selector_matter() -> None:
    prob = lyap.make_problem("A", {})
    coupled = np.eye(5)
    coupled[0, 1] = coupled[1, 0] = 0.5
    costs = prob.evaluate_batch({"K": np.stack([np.eye(5), coupled])}).cost
    assert costs[0] != costs[1]
    # Untargeted elements drop out with the two-sided selector: changing K on them is inert.
    inert = np.eye(5)
    inert[2, 2] = inert[3, 3] = 50.0
    assert prob.evaluate({"K": inert})["cost"] == pytest.approx(costs[0])


def test_plots(tmp_path) -> None:
    sim = lyap.make_problem("A", {"sim_max_points": 500}).simulate(EYE)
    lyap.plot_trajectory(sim, tmp_path / "t.png")
    lyap.plot_thrust(sim, tmp_path / "p.png")
    lyap.plot_elements({"K=I": sim}, tmp_path / "e.png")
    assert (tmp_path / "e.png").exists()
