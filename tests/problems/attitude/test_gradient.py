"""Exact gradients of the attitude problems (fast part): the sensitivity equations'
derivatives against the reference right-hand side, d cost / d z against complex step
(terminal criterion) and central differences (free final time, full maps), and the points
without a gradient (deadline, saturation, no arrival) reported as None with the reason.
Longer horizons, every map and the points near the event are in test_gradient_slow.py."""

from __future__ import annotations

import numpy as np
import pytest
from gradient_reference import (
    central,
    random_z,
    terminal_complex_step,
    time_energy_value,
)

import penaltyrun
from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.optim.gradient import z_gradient
from penaltyrun.problems.attitude import lqr, lyapunov
from penaltyrun.problems.attitude.gradient import DEADLINE_REASON
from penaltyrun.problems.attitude.reference import _rhs_numpy
from penaltyrun.runner.setup import build_layout

I_FULL = np.array([[10.0, 1.0, 0.5], [1.0, 15.0, -0.7], [0.5, -0.7, 20.0]])
KP = np.array([[1.0, 0.1, 0.0], [0.1, 1.5, 0.05], [0.0, 0.05, 2.0]])
KD = np.array([[6.0, 0.3, 0.0], [0.3, 8.0, 0.0], [0.0, 0.0, 9.0]])


def _rel(a, b):
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b))


def test_rhs_and_its_jacobians_match_the_reference_right_hand_side():
    rng = np.random.default_rng(0)
    inertia_inv = np.linalg.inv(I_FULL)
    G = rng.normal(size=(3, 6))
    y = np.concatenate([rng.normal(size=4), 0.1 * rng.normal(size=3), [0.0]])
    ref = _rhs_numpy(G, I_FULL, inertia_inv, np.inf)
    f, F_y, F_g = sens.rhs_parts(y, G, I_FULL, inertia_inv)
    np.testing.assert_allclose(f, ref(0.0, y), rtol=1e-13, atol=1e-15)
    h = 1e-6
    for j in range(7):
        e = np.zeros(8)
        e[j] = h
        fd = (ref(0.0, y + e) - ref(0.0, y - e)) / (2 * h)
        np.testing.assert_allclose(F_y[:, j], fd, rtol=1e-7, atol=1e-9)
    for k in range(18):
        D = np.zeros(18)
        D[k] = h
        D = D.reshape(3, 6)
        fd = (_rhs_numpy(G + D, I_FULL, inertia_inv, np.inf)(0.0, y)
              - _rhs_numpy(G - D, I_FULL, inertia_inv, np.inf)(0.0, y)) / (2 * h)
        np.testing.assert_allclose(F_g[:, k], fd, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("seed", [1, 2])
def test_terminal_pd_diagonal_matches_complex_step(seed):
    prob = lyapunov.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0})
    layout = build_layout(prob, "diagonal", {})
    z = random_z(layout, np.random.default_rng(seed))
    out = z_gradient(prob, layout, z)
    assert out.exists, out.reason
    G = np.concatenate([np.diag(z[:3]), np.diag(z[3:])], axis=1)
    ref = []
    for i in range(6):  # d G / d z_i: one diagonal entry of K_p or K_d
        D = np.zeros((3, 6))
        D[i % 3, 3 * (i // 3) + i % 3] = 1.0
        ref.append(terminal_complex_step(prob, G, D))
    assert _rel(out.grad, ref) < 1e-6


@pytest.mark.parametrize("param", ["givens", "cayley"])
def test_terminal_lqr_full_map_matches_central_differences(param):
    prob = lqr.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0})
    layout = build_layout(prob, param, {})
    z = random_z(layout, np.random.default_rng(5))
    out = z_gradient(prob, layout, z)
    assert out.exists, out.reason

    def cost(v):
        return prob.evaluate_batch(layout.split(v[None])[0]).cost[0]

    lb, ub = layout.bounds()
    fd = []
    for i in range(z.size):
        e = np.zeros_like(z)
        e[i] = 1.0
        fd.append(central(lambda s, e=e: cost(z + s * e), 1e-4 * (ub[i] - lb[i])))
    assert _rel(out.grad, fd) < 1e-6


def test_terminal_lqr_gain_part_matches_complex_step():
    """The cost → gain stage alone (the Riccati stage is the one of problem=lqr)."""
    from penaltyrun.problems.attitude.gradient import gain_sensitivity

    prob = lqr.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0})
    G = prob.gain({"Q": np.diag([1.0, 2.0, 3.0, 0.5, 1.0, 4.0]), "R": np.diag([1.0, 2.0, 0.5])})
    grad, reason, _ = gain_sensitivity(prob, G, 8.0)
    assert reason == ""
    D = np.random.default_rng(7).normal(size=(3, 6))
    ref = terminal_complex_step(prob, G, D)
    assert abs(np.sum(grad * D) - ref) <= 1e-6 * abs(ref)


def test_time_energy_pd_matches_central_differences_of_the_reference():
    """A loose event tolerance keeps the runs short (the default one: the slow tests)."""
    prob = lyapunov.make_problem("detumble", {"criterion": "time_energy", "tol": 1e-2})
    g = prob.gradient({"Kp": KP, "Kd": KD})
    assert g.exists and g.status == "converged", g.reason
    rng = np.random.default_rng(11)
    for name, M in (("Kp", KP), ("Kd", KD)):
        D = rng.normal(size=(3, 3))
        D = D + D.T

        def value(s, name=name, M=M, D=D):
            mats = {"Kp": KP, "Kd": KD, name: M + s * D}
            return time_energy_value(prob, np.concatenate([mats["Kp"], mats["Kd"]], axis=1))

        ref = central(value, 1e-4 * np.linalg.norm(M))
        assert abs(np.sum(g.matrices[name] * D) - ref) <= 1e-6 * abs(ref)


def test_deadline_has_no_gradient_and_says_why():
    out = penaltyrun.evaluate("attitude_lyapunov", z=[1.0, 1.5, 2.0, 6.0, 8.0, 9.0],
                              param="diagonal", gradient=True)
    assert out["grad"] is None and out["grad_matrices"] is None
    assert out["gradient_note"] == DEADLINE_REASON
    assert np.isfinite(out["cost"])


def test_evaluate_gives_the_gradient_on_a_well_posed_criterion():
    params = {"criterion": "terminal", "t_max": 8.0}
    z = [1.0, 1.5, 2.0, 6.0, 8.0, 9.0]
    out = penaltyrun.evaluate("attitude_lyapunov", z=z, param="diagonal", params=params,
                              gradient=True)
    prob = lyapunov.make_problem("detumble", params)
    ref = z_gradient(prob, build_layout(prob, "diagonal", {}), np.asarray(z))
    assert out["gradient_note"] == "" and out["grad"] == ref.grad.tolist()
    assert set(out["grad_matrices"]) == {"Kp", "Kd"}


def test_torque_limit_reached_gives_no_gradient_and_an_unreached_one_changes_nothing():
    mats = {"Kp": KP, "Kd": KD}
    free = lyapunov.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0})
    u_peak = float(np.max(np.abs(free.gain(mats) @ free.y0[1:7])))
    hit = lyapunov.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0,
                                             "u_max": 0.5 * u_peak})
    g = hit.gradient(mats)
    assert g.matrices is None and "u_max" in g.reason
    loose = lyapunov.make_problem("detumble", {"criterion": "terminal", "t_max": 8.0,
                                               "u_max": 100.0 * u_peak})
    a, b = loose.gradient(mats), free.gradient(mats)
    assert a.exists and b.exists
    for name in mats:
        np.testing.assert_allclose(a.matrices[name], b.matrices[name], rtol=1e-8)


def test_no_arrival_by_the_cap_gives_no_gradient():
    prob = lyapunov.make_problem("detumble", {"criterion": "time_energy",
                                              "free_time_cap": 5.0})
    g = prob.gradient({"Kp": KP, "Kd": KD})
    assert g.matrices is None and g.status != "converged" and "graded penalty" in g.reason


@pytest.mark.parametrize("crit", ["terminal", "time_energy"])
def test_adjoint_and_forward_sensitivities_agree(crit):
    from penaltyrun.problems.attitude import criteria as attitude_criteria
    from penaltyrun.problems.attitude.gradient import gain_sensitivity

    over = {"criterion": crit, "t_max": 8.0} if crit == "terminal" else \
        {"criterion": crit, "tol": 1e-2}
    prob = lyapunov.make_problem("detumble", over)
    p = prob.params
    G = prob.gain({"Kp": KP, "Kd": KD})
    t_final = float(prob.evaluate({"Kp": KP, "Kd": KD})["t_final"])
    forward, reason, value = gain_sensitivity(prob, G, t_final)
    assert reason == ""
    adj, cost = sens.adjoint_gradient(
        G, prob.y0, prob.inertia, p.t_max if crit == "terminal" else p.free_time_cap,
        p.event_weights(), None if crit == "terminal" else p.tol,
        attitude_criteria.terminal_weight(p), p.rho)
    assert abs(cost - value) <= 1e-8 * abs(value)
    assert _rel(adj, forward.ravel()) < 1e-7
