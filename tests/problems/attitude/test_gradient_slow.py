"""Exact gradients of the attitude problems (slow part): both laws, both well-posed criteria
at their default horizons and tolerances, every map (GEAGSP where it is differentiable),
points near the event (an earlier dip of the distance just above and just below the
tolerance), and the gradient optimizers on attitude."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from gradient_reference import central, random_z, time_energy_value

import penaltyrun
from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.optim.gradient import z_gradient
from penaltyrun.problems.attitude import lqr, lyapunov
from penaltyrun.runner.setup import build_layout

pytestmark = pytest.mark.slow

#: Reasons a point next to a dip may legitimately have no gradient.
NEAR_DIP_REASONS = ("earlier local minimum", "arrival time of the kernel", "transversally")


def _directional(prob, layout, z, v, value):
    """(exact g·v, central difference along v of value(gain)) at z."""
    out = z_gradient(prob, layout, z)

    def along(s):
        G, ok = prob.gains(layout.split((z + s * v)[None])[0])
        assert ok[0]
        return value(prob, G[0])

    return out, central(along, 1e-4)


@pytest.mark.parametrize("module", [lyapunov, lqr], ids=["pd", "lqr"])
@pytest.mark.parametrize("param", ["diagonal", "givens", "cayley", "full"])
def test_time_energy_matches_central_differences_of_the_reference(module, param):
    prob = module.make_problem("detumble", {"criterion": "time_energy"})
    layout = build_layout(prob, param, {})
    rng = np.random.default_rng(21)
    z = random_z(layout, rng, 0.3, 0.6)
    lb, ub = layout.bounds()
    v = (ub - lb) * rng.normal(size=z.size)
    out, fd = _directional(prob, layout, z, v, time_energy_value)
    if param == "full" and not out.exists:  # GEAGSP next to a skipped vector: no derivative
        assert "map" in out.reason
        return
    assert out.exists, out.reason
    assert abs(out.grad @ v - fd) <= 1e-6 * abs(fd)


@pytest.mark.parametrize("module", [lyapunov, lqr], ids=["pd", "lqr"])
@pytest.mark.parametrize("param", ["givens", "full"])
def test_terminal_default_horizon_matches_central_differences(module, param):
    prob = module.make_problem("rest_to_rest", {"criterion": "terminal"})
    layout = build_layout(prob, param, {})
    z = random_z(layout, np.random.default_rng(8), 0.3, 0.6)
    out = z_gradient(prob, layout, z)
    if param == "full" and not out.exists:
        assert "map" in out.reason
        return
    assert out.exists, out.reason

    def cost(w):
        return prob.evaluate_batch(layout.split(w[None])[0]).cost[0]

    lb, ub = layout.bounds()
    fd = np.array([central(lambda s, i=i: cost(z + s * np.eye(z.size)[i]),
                           1e-4 * (ub[i] - lb[i])) for i in range(z.size)])
    assert np.linalg.norm(out.grad - fd) <= 1e-6 * np.linalg.norm(fd)


def _dips():
    """An underdamped PD loop (rest to rest) whose distance has local minima above the
    default tolerance before it arrives: the minima, from a run that never arrives."""
    prob = lyapunov.make_problem("rest_to_rest", {})
    G = np.concatenate([0.5 * np.eye(3), 2.0 * np.eye(3)], axis=1)
    run = sens.sensitivity_run(G, prob.y0, prob.inertia, 400.0, prob.params.event_weights(),
                               1e-12)
    return run.dips


@pytest.mark.parametrize("offset", [-1e-2, 1e-2])
def test_near_an_earlier_dip_the_gradient_exists_and_is_exact(offset):
    """tol 1 % under a local minimum of the distance (the run passes just above it and
    arrives at the next dip), or 1 % over it (the run arrives in that dip, near its
    bottom, with a small slope)."""
    dip = _dips()[3]
    mats = {"Kp": 0.5 * np.eye(3), "Kd": 2.0 * np.eye(3)}
    prob = lyapunov.make_problem("rest_to_rest", {"criterion": "time_energy",
                                                  "tol": dip * (1.0 + offset)})
    g = prob.gradient(mats)
    assert g.exists, g.reason
    rng = np.random.default_rng(4)
    for name in mats:
        D = rng.normal(size=(3, 3))
        D = D + D.T

        def value(s, name=name, D=D):
            m = {**mats, name: mats[name] + s * D}
            return time_energy_value(prob, np.concatenate([m["Kp"], m["Kd"]], axis=1))

        ref = central(value, 1e-5)
        assert abs(np.sum(g.matrices[name] * D) - ref) <= 1e-5 * abs(ref)


def test_a_dip_touching_the_tolerance_gives_no_gradient():
    dip = _dips()[3]
    prob = lyapunov.make_problem("rest_to_rest", {"criterion": "time_energy",
                                                  "tol": dip * (1.0 - 1e-9)})
    g = prob.gradient({"Kp": 0.5 * np.eye(3), "Kd": 2.0 * np.eye(3)})
    assert g.matrices is None
    assert any(words in g.reason for words in NEAR_DIP_REASONS), g.reason


def test_lbfgs_and_gradient_polish_run_on_attitude(tmp_path):
    params = {"criterion": "terminal", "t_max": 8.0}
    rec = penaltyrun.tune("attitude_lyapunov", param="diagonal", optimizer="lbfgs",
                          optimizer_options={"starts": 1, "max_evals": 300}, n_starts=1,
                          seed=3, workers=1, params=params, run_dir=tmp_path / "lbfgs").records
    row = rec.iloc[0]
    assert row["gradient_note"] == "" and np.isfinite(row["grad_norm"])
    pol = penaltyrun.tune("attitude_lqr", param="givens", optimizer="cmaes",
                          optimizer_options={"max_evals": 300, "polish": "gradient"},
                          n_starts=1, seed=3, workers=1, params=params,
                          run_dir=tmp_path / "polish").records.iloc[0]
    assert "+polish" in pol["stop_reason"] and pol["gradient_note"] == ""


def test_cli_evaluate_gives_the_library_gradient(tmp_path):
    z = [1.0, 1.5, 2.0, 6.0, 8.0, 9.0]
    proc = subprocess.run(
        [sys.executable, "-m", "penaltyrun.cli", "mode=evaluate", "problem=attitude_lyapunov",
         "problem.params.criterion=terminal", "problem.params.t_max=8.0", "param=diagonal",
         f"z={z}".replace(" ", ""), "+gradient=true"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    lib = penaltyrun.evaluate("attitude_lyapunov", z=z, param="diagonal", gradient=True,
                              params={"criterion": "terminal", "t_max": 8.0})
    assert out["grad"] == lib["grad"] and out["gradient_note"] == ""


def test_stiff_lqr_gain_goes_through_the_implicit_method_and_stays_exact():
    """R at the eigenvalue bound: the loop is stiff (the kernel's RODAS4 path, the
    sensitivity run's BDF); the gradient against differences of the production cost."""
    prob = lqr.make_problem("detumble", {"criterion": "terminal", "t_max": 20.0})
    mats = {"Q": np.diag([10.0, 10.0, 10.0, 5.0, 5.0, 5.0]), "R": 1e-8 * np.eye(3)}
    assert sens.stiffness(prob.gain(mats), prob.inertia_inv) > sens.STIFF_RATE
    g = prob.gradient(mats)
    assert g.exists, g.reason
    D = np.random.default_rng(2).normal(size=(6, 6))
    D = D + D.T

    def cost(s):
        return prob.evaluate_batch({"Q": (mats["Q"] + s * D)[None],
                                    "R": mats["R"][None]}).cost[0]

    ref = central(cost, 1e-3)
    assert abs(np.sum(g.matrices["Q"] * D) - ref) <= 1e-6 * abs(ref)


def test_companion_set_up_weighted_event_matches_the_reference():
    """The companion study's set-up: event ‖(10·q_v, ω)‖ ≤ 1e-3 (w_q0 = 0), other inertia
    and initial state."""
    prob = lyapunov.make_problem("schaub_detumble", {"criterion": "time_energy"})
    Kp = np.diag([0.8, 1.0, 0.6])
    Kd = np.diag([4.4, 6.6, 5.4])
    g = prob.gradient({"Kp": Kp, "Kd": Kd})
    assert g.exists, g.reason
    D = np.random.default_rng(0).normal(size=(3, 3))
    D = D + D.T
    ref = central(lambda s: time_energy_value(prob, np.concatenate([Kp + s * D, Kd], 1)), 1e-4)
    assert abs(np.sum(g.matrices["Kp"] * D) - ref) <= 1e-6 * abs(ref)
