"""Problem-level tests of the Q-law transfers (penaltyrun.problems.lowthrust.qlaw)."""

from __future__ import annotations

import json

import matplotlib
import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.base import Problem
from penaltyrun.problems.lowthrust import qlaw

matplotlib.use("Agg")

EYE = {"K": np.eye(5)}


def test_contract_and_registry() -> None:
    assert qlaw.CASES == ("A", "B", "C", "D", "E", "Estar")
    prob = make("qlaw", None, {})
    assert isinstance(prob, Problem)
    assert prob.case == qlaw.DEFAULT_CASE == "A"
    assert prob.matrices[0].name == "K" and prob.matrices[0].size == 5
    assert prob.matrices[0].eig_bounds == (1e-8, 100.0)
    assert prob.scalars == ()
    fuel = qlaw.make_problem("A", {"objective": "min_fuel"})
    assert [s.name for s in fuel.scalars] == ["eta_cut"]
    assert fuel.scalars[0].bounds == (0.0, 1.0)


def test_precedence_defaults_case_overrides() -> None:
    prob = qlaw.make_problem("B", {"tof_cap_days": 123.0})
    assert prob.params.a0_km == 24505.9
    assert prob.params.targeted == ("a", "e", "i")
    assert prob.params.tof_cap_days == 123.0
    assert prob.params.control_step_s == 80.7
    variant = qlaw.make_problem("E", {"Omega_target_deg": 180.0, "omega_target_deg": 270.0})
    assert variant.params.Omega_target_deg == 180.0 and variant.params.omega_target_deg == 270.0
    assert qlaw.make_problem("E", {}).params.Omega_target_deg == 270.0


def test_config_errors() -> None:
    with pytest.raises(ConfigError) as exc:
        qlaw.make_problem("F", {})
    assert "A" in str(exc.value)
    with pytest.raises(ConfigError) as exc:
        qlaw.make_problem("A", {"not_a_param": 1})
    assert exc.value.key == "problem.params.not_a_param"
    with pytest.raises(ConfigError):
        qlaw.make_problem("A", {"objective": "fastest"})
    with pytest.raises(ConfigError):
        qlaw.make_problem("A", {"targeted": ["a", "x"]})
    prob = qlaw.make_problem("C", {})
    with pytest.raises(ConfigError):
        prob.evaluate({"K": np.eye(4)})
    with pytest.raises(ConfigError):
        prob.evaluate_batch({"K": np.eye(5)})
    with pytest.raises(ConfigError):
        prob.evaluate_batch({"K": np.ones((2, 6, 6))})
    with pytest.raises(ConfigError):
        prob.simulate({"K": -np.eye(5)})


@pytest.mark.parametrize(("case", "tof", "prop", "revs"), [
    ("A", 17.6, 50.0, 95.0),
    ("B", 144.0, 222.0, 220.0),
    ("C", 1.41, 37.0, 6.5),
])
def test_identity_min_time_converges_in_sanity_range(case, tof, prop, revs) -> None:
    res = qlaw.make_problem(case, {}).evaluate(EYE)
    assert res["status"] == "converged" and res["converged"]
    assert res["tof_days"] == pytest.approx(tof, rel=0.03)
    assert res["propellant_kg"] == pytest.approx(prop, rel=0.03)
    assert res["revolutions"] == pytest.approx(revs, rel=0.03)
    assert res["cost"] == pytest.approx(res["tof_days"])
    assert abs(res["final_errors"]["a_km"]) <= 10.0 and abs(res["final_errors"]["e"]) <= 1e-3
    assert 0.0 <= res["final_elements"]["nu_deg"] < 360.0
    json.dumps(res)


def test_original_case_e_fails_and_estar_needs_a_cap() -> None:
    e_res = qlaw.make_problem("E", {}).evaluate(EYE)
    assert not e_res["converged"]
    star = qlaw.make_problem("Estar", {}).evaluate(EYE)
    assert not star["converged"]
    capped = qlaw.make_problem("Estar", {"a_cap_km": 40000.0}).evaluate(EYE)
    assert capped["converged"]
    for err in ("i_deg", "Omega_deg", "omega_deg"):
        assert abs(capped["final_errors"][err]) <= 0.01


@pytest.mark.parametrize(("case", "overrides", "status"), [
    ("C", {}, "converged"),
    ("A", {"tof_cap_days": 1.0}, "tof_cap"),
    ("A", {"max_revs": 5.0}, "rev_cap"),
    ("C", {"impact_radius_km": 7500.0}, "impact"),
    ("A", {"mass_floor_kg": 299.0}, "propellant"),
    ("A", {"max_steps": 10}, "stall"),
    ("A", {"stall_window_revs": 1.0, "stall_rel_decrease": 0.99}, "stall"),
    ("Estar", {"tof_cap_days": 100.0}, "escape"),
])
def test_each_status(case, overrides, status) -> None:
    prob = qlaw.make_problem(case, overrides)
    batch = prob.evaluate_batch({"K": np.eye(5)[None]})
    assert batch.status[0] == status
    assert bool(batch.converged[0]) == (status == "converged")
    assert np.isfinite(batch.cost[0])
    if status != "converged":
        assert batch.cost[0] > prob.params.tof_cap_days
    assert prob.evaluate(EYE)["status"] == status


def test_failure_penalty_is_graded() -> None:
    near = qlaw.make_problem("A", {"tof_cap_days": 15.0}).evaluate(EYE)
    far = qlaw.make_problem("A", {"tof_cap_days": 15.0, "thrust_newton": 0.2}).evaluate(EYE)
    assert near["status"] == far["status"] == "tof_cap"
    assert 15.0 < near["cost"] < far["cost"]


def test_batch_matches_single_and_full_matrix_changes_result() -> None:
    prob = qlaw.make_problem("C", {})
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(5, 5)))
    full = q @ np.diag([3.0, 0.5, 1.0, 2.0, 1.5]) @ q.T
    batch = prob.evaluate_batch({"K": np.stack([np.eye(5), full])})
    assert batch.cost[0] == pytest.approx(prob.evaluate(EYE)["cost"])
    assert batch.cost[1] == pytest.approx(prob.evaluate({"K": full})["cost"])
    assert batch.cost[0] != batch.cost[1]


def test_min_fuel_coasting_trades_time_for_propellant() -> None:
    prob = qlaw.make_problem("A", {"objective": "min_fuel", "coast_mode": "eta_a"})
    batch = prob.evaluate_batch({"K": np.stack([np.eye(5)] * 2)},
                                {"eta_cut": np.array([0.0, 0.5])})
    assert batch.converged.all()
    always, coasting = (prob.evaluate(EYE, {"eta_cut": v}) for v in (0.0, 0.5))
    assert batch.cost[0] == pytest.approx(always["propellant_kg"])
    assert coasting["propellant_kg"] < always["propellant_kg"] - 3.0
    assert coasting["tof_days"] > always["tof_days"]
    assert coasting["eta_cut"] == 0.5
    default = prob.evaluate(EYE, {"eta_cut": None})
    assert default["eta_cut"] == prob.params.eta_cut
    sim = prob.simulate(EYE, {"eta_cut": 0.5})
    assert 0.0 < sim["thrust_on"].mean() < 1.0
    relative = qlaw.make_problem("C", {"objective": "min_fuel", "coast_mode": "eta_r",
                                       "eta_cut": 0.3}).evaluate(EYE)
    assert relative["converged"]


def test_simulate_histories_and_plots(tmp_path) -> None:
    prob = qlaw.make_problem("C", {})
    sim = prob.simulate(EYE)
    res = prob.evaluate(EYE)
    for key in ("t", "a", "e", "i", "Omega", "omega", "mass", "thrust_on", "x", "y", "z"):
        assert sim[key].shape == sim["t"].shape
    assert sim["t"][-1] == pytest.approx(res["t_final"])
    assert sim["mass"][-1] == pytest.approx(res["final_mass_kg"])
    r = np.sqrt(sim["x"] ** 2 + sim["y"] ** 2 + sim["z"] ** 2)
    assert r.min() > 6378.0
    small = qlaw.make_problem("C", {"sim_max_points": 100}).simulate(EYE)
    assert len(small["t"]) <= 102
    other = qlaw.make_problem("C", {"control_step_s": 120.0}).simulate(EYE)
    qlaw.plot_trajectory(sim, tmp_path / "traj.png")
    qlaw.plot_elements({"diagonal": sim, "full": other}, tmp_path / "elements.png")
    qlaw.plot_thrust(sim, tmp_path / "thrust.png")
    for name in ("traj.png", "elements.png", "thrust.png"):
        assert (tmp_path / name).stat().st_size > 1000


def test_element_plot_unwraps_angles_settling_at_180_degrees() -> None:
    import matplotlib.pyplot as plt

    n = 50
    omega = np.deg2rad(np.where(np.arange(n) % 2 == 0, 179.9, -179.9))
    sim = {"t": np.linspace(0.0, 86400.0, n), "a": np.full(n, 26500.0), "e": np.full(n, 0.7),
           "i": np.full(n, 1.5), "Omega": omega, "omega": omega, "mass": np.full(n, 1500.0)}
    fig = qlaw.plot_elements({"run": sim})
    for ax in fig.axes[3:5]:
        y = ax.lines[0].get_ydata()
        assert np.max(np.abs(np.diff(y))) < 1.0
        assert abs(y[0] - 179.9) < 1e-9
    plt.close(fig)


def test_one_sided_selector_option() -> None:
    res = qlaw.make_problem("C", {"selector_sides": 1}).evaluate(EYE)
    assert res["status"] in {"converged", "tof_cap", "stall", "impact", "escape", "rev_cap"}
    with pytest.raises(ConfigError):
        qlaw.make_problem("C", {"selector_sides": 3})

