"""Low-thrust held-out scenarios: perturbed departures and other discretizations, each
checked against an independently built problem with the same settings; bad settings are
one-line config errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.lowthrust import holdout as lh
from penaltyrun.problems.lowthrust.params import DEG

SMALL = {"holdout_n_perturbed": 2, "holdout_control_steps": (60.0,), "holdout_substeps": (2,)}


def test_scenarios_are_seeded_and_bounded():
    prob = make("qlaw", "A")
    sc = prob.holdout_scenarios()
    assert [s.label for s in sc] == [f"departure:{k}" for k in range(8)] + \
        ["step=40s", "step=60s", "step=100s", "substeps=2"]
    again = make("qlaw", "A").holdout_scenarios()
    assert sc == again
    p = prob.params
    for s in sc[:8]:
        oe = np.asarray(s.oe0)
        assert abs(oe[0] - 7000.0) <= 70.0 and abs(oe[1] - 0.01) <= 0.005
        assert abs(oe[2] - 0.05 * DEG) <= 0.04 * DEG + 1e-15
        assert (s.control_step_s, s.rk4_substeps) == (p.control_step_s, p.rk4_substeps)
    other = make("qlaw", "A", {"holdout_seed": 1}).holdout_scenarios()
    assert other[0].oe0 != sc[0].oe0
    assert prob.training_scenario()["control_step_s"] == 80.7


@pytest.mark.parametrize("law,case", [("qlaw", "A"), ("qlaw", "C"), ("lyapunov_transfer", "A")])
def test_holdout_matches_independent_problems(law, case):
    K = np.diag([1.0, 2.0, 1.0, 1.0, 1.0])
    prob = make(law, case, SMALL)
    held = prob.holdout({"K": K})
    assert held["scenario"] == ["departure:0", "departure:1", "step=60s", "substeps=2"]
    for k, sc in enumerate(prob.holdout_scenarios()):
        a, e, i, raan, argp, nu = sc.oe0
        over = {"a0_km": a, "e0": e, "i0_deg": i / DEG, "Omega0_deg": raan / DEG,
                "omega0_deg": argp / DEG, "nu0_deg": nu / DEG,
                "control_step_s": sc.control_step_s, "rk4_substeps": sc.rk4_substeps,
                "holdout_n_perturbed": 0, "holdout_control_steps": (),
                "holdout_substeps": ()}
        ref = make(law, case, over).evaluate({"K": K})
        assert held["cost"][k] == pytest.approx(ref["cost"], rel=1e-12)
        assert held["status"][k] == ref["status"]
        assert held["tof_days"][k] == pytest.approx(ref["tof_days"], rel=1e-12)
    train = prob.evaluate({"K": K})
    assert held["training"]["cost"] == train["cost"]


def test_min_fuel_holdout_uses_eta_cut():
    prob = make("qlaw", "C", {**SMALL, "objective": "min_fuel"})
    low = prob.holdout({"K": np.eye(5)}, {"eta_cut": 0.1})
    high = prob.holdout({"K": np.eye(5)}, {"eta_cut": 0.5})
    assert low["propellant_kg"] != high["propellant_kg"]
    assert low["cost"] == pytest.approx(low["propellant_kg"], rel=1e-12) or \
        not all(low["converged"])


def test_empty_holdout_is_none():
    off = {"holdout_n_perturbed": 0, "holdout_control_steps": (), "holdout_substeps": ()}
    assert make("qlaw", "C", off).holdout({"K": np.eye(5)}) is None


@pytest.mark.parametrize("over,key", [
    ({"holdout_de": 0.05}, "holdout_de"),
    ({"holdout_di_deg": 1.0}, "holdout_di_deg"),
    ({"holdout_da_rel": 0.3}, "holdout_da_rel"),
    ({"holdout_control_steps": (40.0, 80.7)}, "holdout_control_steps"),
    ({"holdout_control_steps": (40.0, -1.0)}, "holdout_control_steps"),
    ({"holdout_substeps": (1,)}, "holdout_substeps"),
    ({"holdout_n_perturbed": -1}, "holdout_n_perturbed"),
])
def test_bad_scenario_settings(over, key):
    with pytest.raises(ConfigError, match=key):
        make("qlaw", "A", over)


def test_bad_scenario_settings_on_the_command_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "problem=qlaw", "case=A",
                           "problem.params.holdout_de=0.05", "runner.n_starts=1"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("penaltyrun: error: problem.params.holdout_de")
    assert "Traceback" not in proc.stderr


def test_kinds_cover_every_scenario():
    assert {s.kind for s in make("qlaw", "A").holdout_scenarios()} == set(lh.KINDS)


@pytest.mark.parametrize("over", [{"a0_km": 5000.0}, {"e0": 0.75}])
def test_departure_inside_the_earth_names_a0(over):
    """Case A: a0 = 7000 km, e0 = 0.01 (periapsis 6930 km); both overrides put it inside."""
    with pytest.raises(ConfigError) as info:
        make("qlaw", "A", over)
    assert info.value.key == "problem.params.a0_km"
    assert "inside the Earth" in str(info.value)
