"""The authors' companion attitude set-up: configurable
terminal event, the ``schaub_detumble`` / ``schaub_detumble_sat`` presets, their best
published runs, and the held-out perturbations of their initial state."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from penaltyrun.dynamics import attitude as at
from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.attitude import common as ac
from penaltyrun.problems.attitude import lyapunov as lyap

#: Best published unconstrained runs (PSO): gains, J, event time (s).
DIAGONAL_RUN = ({"Kp": np.diag([0.26617752, 0.34685239, 0.20612607]),
                 "Kd": np.diag([4.43098254, 6.56962029, 5.39346573])}, 86.529217, 349.8142)
CAYLEY_RUN = ({"Kp": np.array([[1.57829253, 1.07740877, -1.09866686],
                               [1.07740877, 1.30878875, -0.90675407],
                               [-1.09866686, -0.90675407, 1.31689833]]),
               "Kd": np.array([[1.74150880, -0.30138814, 0.16624500],
                               [-0.30138814, 11.03831055, -3.04021733],
                               [0.16624500, -3.04021733, 11.24695355]])}, 55.145268, 348.9489)


def test_preset_is_the_companion_setup():
    p = make("attitude_lyapunov", "schaub_detumble").params
    sat = make("attitude_lyapunov", "schaub_detumble_sat").params
    s = np.array([0.6, -0.4, 0.2])
    s2 = s @ s
    q = np.concatenate([[(1 - s2) / (1 + s2)], 2 * s / (1 + s2)])
    np.testing.assert_allclose(p.initial_quaternion(), q, atol=1e-15)
    np.testing.assert_array_equal(p.inertia_matrix(), np.diag([140.0, 100.0, 80.0]))
    assert p.omega0 == (0.70, 0.20, -0.15) and p.t_max == 350.0 and p.tol == 1e-3
    assert p.event_weights() == (0.0, 10.0, 1.0) and p.eig_bounds == (1e-8, 20.0)
    assert p.u_max is None and sat.u_max == 1.0
    assert (p.rtol, p.atol) == (1e-10, 1e-10)


@pytest.mark.parametrize("run", [DIAGONAL_RUN, CAYLEY_RUN], ids=["diagonal", "cayley"])
def test_preset_reproduces_published_runs(run):
    mats, cost, t_event = run
    res = make("attitude_lyapunov", "schaub_detumble").evaluate(mats)
    assert res["converged"] and res["status"] == "converged"
    assert res["cost"] == pytest.approx(cost, rel=1e-5)
    assert abs(res["t_final"] - t_event) <= 0.05
    assert res["final_distance"] == pytest.approx(1e-3, rel=1e-9)


def test_preset_agrees_with_scipy_reference():
    mats, _, _ = CAYLEY_RUN
    for case in ("schaub_detumble", "schaub_detumble_sat"):
        prob = make("attitude_lyapunov", case)
        res = prob.evaluate(mats)
        ref = lyap.reference_cost(mats, prob.params)
        assert res["converged"] == ref["converged"]
        assert res["cost"] == pytest.approx(ref["cost"], rel=1e-6)
        assert res["t_final"] == pytest.approx(ref["t_final"], rel=1e-6)


def test_default_event_is_unchanged():
    """Weights (1, 1, 1) are today's ‖(q0 − 1, q_v, ω)‖: kernel default == explicit."""
    y = np.array([0.9, 0.1, -0.2, 0.3, 0.01, 0.02, -0.03, 0.0])
    p = np.empty(at.N_PRM)
    at.pack_params(np.eye(3), np.eye(3), np.zeros((3, 6)), np.inf, 1e-4, p)
    assert at.weighted_distance(y, p) == pytest.approx(at.distance(y), rel=1e-15)
    at.pack_params(np.eye(3), np.eye(3), np.zeros((3, 6)), np.inf, 1e-4, p, 0.0, 10.0, 1.0)
    want = np.sqrt(100 * np.sum(y[1:4] ** 2) + np.sum(y[4:7] ** 2))
    assert at.weighted_distance(y, p) == pytest.approx(want, rel=1e-15)
    assert ac.Params(event_weight_q0=0.0, event_weight_qv=10.0).event_distance(y) == \
        pytest.approx(want, rel=1e-15)


def test_event_weights_change_the_event_time():
    """A larger weight on ω makes the same gain stop later (hand-checked direction), and the
    kernel agrees with scipy for non-default weights on the main set-up."""
    gains = {"Kp": 3.0 * np.eye(3), "Kd": 6.0 * np.eye(3)}
    base = make("attitude_lyapunov", "detumble").evaluate(gains)
    heavy = make("attitude_lyapunov", "detumble", {"event_weight_w": 100.0})
    res = heavy.evaluate(gains)
    assert res["t_final"] > base["t_final"]
    ref = lyap.reference_cost(gains, heavy.params)
    assert res["t_final"] == pytest.approx(ref["t_final"], rel=1e-6)
    assert res["cost"] == pytest.approx(ref["cost"], rel=1e-6)


@pytest.mark.parametrize("key,value", [("event_weight_q0", -1.0), ("event_weight_qv", 0.0),
                                       ("event_weight_w", float("nan")),
                                       ("holdout_n_perturbed", -2)])
def test_bad_event_settings(key, value):
    with pytest.raises(ConfigError, match=key):
        make("attitude_lyapunov", "schaub_detumble", {key: value})


@pytest.mark.slow  # about 11 s: held-out runs of the companion case
def test_holdout_perturbs_the_companion_state():
    mats, _, _ = CAYLEY_RUN
    prob = make("attitude_lyapunov", "schaub_detumble", {"holdout_n_perturbed": 6})
    sc = prob.holdout_scenarios()
    assert list(sc["scenario"]) == [f"perturbed:{k}" for k in range(6)]
    q = sc["y0"][:, :4]
    q_nom = prob.y0[:4]
    angle = np.degrees(2 * np.arccos(np.clip(np.abs(q @ q_nom), 0, 1)))
    assert np.all(angle <= 10.0 + 1e-9) and np.all(angle > 0)
    ratio = sc["y0"][:, 4:7] / prob.y0[4:7]
    assert np.all(np.abs(ratio - 1) <= 0.1)
    again = make("attitude_lyapunov", "schaub_detumble", {"holdout_n_perturbed": 6})
    np.testing.assert_array_equal(again.holdout_scenarios()["y0"], sc["y0"])
    held = prob.holdout(mats)
    assert held["cost"].shape == (6,) and list(held["scenario"]) == list(sc["scenario"])
    long = replace(prob.params, t_max=float(held["horizon"]))
    for k in range(6):
        G = np.hstack([mats["Kp"], mats["Kd"]])
        single = ac.reference_run(G, prob.params, sc["y0"][k])
        assert held["cost_at_deadline"][k] == pytest.approx(single["cost"], rel=1e-6)
        assert held["converged_by_deadline"][k] == single["converged"]
        if held["converged"][k]:
            single = ac.reference_run(G, long, sc["y0"][k])
            assert held["cost"][k] == pytest.approx(single["cost"], rel=1e-6)


def test_holdout_grid_plus_perturbed():
    prob = make("attitude_lyapunov", "detumble", {"holdout_n": 2, "holdout_n_perturbed": 3})
    held = prob.holdout({"Kp": 3.0 * np.eye(3), "Kd": 6.0 * np.eye(3)})
    assert held["cost"].shape == (11,)
    assert held["scenario"][0].startswith("grid:") and held["scenario"][-1] == "perturbed:2"
    assert np.all(np.isnan(held["attitudes_deg"][8:]))
    assert np.all(held["omega_init"][:8] == 0.0)


@pytest.mark.slow  # about 40 s: a fresh process compiles the attitude kernels
def test_evaluate_mode_on_presets(tmp_path):
    mats, cost, _ = DIAGONAL_RUN
    args = [sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
            "problem=attitude_lyapunov", "case=schaub_detumble",
            f"matrices.Kp={json.dumps(mats['Kp'].tolist())}",
            f"matrices.Kd={json.dumps(mats['Kd'].tolist())}"]
    proc = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    assert res["case"] == "schaub_detumble" and res["event_weights"] == [0.0, 10.0, 1.0]
    assert res["cost"] == pytest.approx(cost, rel=1e-5)


def test_saturated_preset_limits_the_torque():
    """The unconstrained optimum is too slow under |u_i| <= 1 N·m; the torque stays bounded."""
    mats, _, _ = DIAGONAL_RUN
    prob = make("attitude_lyapunov", "schaub_detumble_sat")
    assert prob.evaluate(mats)["status"] == "horizon"
    sim = prob.simulate(mats, n_points=200)
    assert np.max(np.abs(sim["u"])) <= 1.0 + 1e-12
    assert np.max(np.abs(sim["u"])) == pytest.approx(1.0)
