"""The well-posed criteria of the rendezvous MPC against an independent integration.

The controller's inputs (zero-order hold, one per sample) are replayed through the
continuous Clohessy–Wiltshire equations written here and integrated by scipy ``solve_ivp``
(DOP853, rtol 1e-10); the sampled states must match the production loop, and J
(Σ (½‖u_k‖² + ρ) Tₛ to the first converged sample, or Σ ½‖u_k‖² Tₛ + s_Nᵀ S s_N) and the
arrival time are recomputed from the replay: J to 1e-6 relative, arrival to 1e-6 s.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from penaltyrun.errors import ConfigError
from penaltyrun.problems.mpc import rendezvous as rz


def _replay(prob, inputs):
    p = prob.params
    n = math.sqrt(p.mu_km3_s2 * 1e9 / (p.orbit_radius_km * 1e3) ** 3)
    s = np.asarray(p.s0, dtype=float)
    states = [s]
    for u in inputs:
        def cw(t, y, u=u):
            x, y_, z, vx, vy, vz = y
            return [vx, vy, vz, 3 * n * n * x + 2 * n * vy + u[0], -2 * n * vx + u[1],
                    -n * n * z + u[2]]

        sol = solve_ivp(cw, (0.0, p.sample_time_s), s, method="DOP853", rtol=1e-10,
                        atol=1e-12)
        s = sol.y[:, -1]
        states.append(s)
    return np.asarray(states)


def _random_weights(rng):
    def spd(n, lo, hi):
        basis, _ = np.linalg.qr(rng.normal(size=(n, n)))
        return basis @ np.diag(10.0 ** rng.uniform(np.log10(lo), np.log10(hi), n)) @ basis.T

    return {"Q": spd(6, 1e-6, 1e-3), "R": spd(3, 200.0, 5000.0)}


def _converged(states, p):
    return (np.linalg.norm(states[:, :3], axis=1) <= p.pos_tol_m) \
        & (np.linalg.norm(states[:, 3:], axis=1) <= p.vel_tol_m_s)


@pytest.mark.parametrize("seed", [1, 2])
def test_time_energy_matches_a_replay(seed):
    rng = np.random.default_rng(seed)
    mats = _random_weights(rng)
    rho = float(10.0 ** rng.uniform(-6, -4))
    prob = rz.make_problem("default", {"criterion": "time_energy", "rho": rho})
    res = prob.evaluate(mats)
    sim = prob.simulate(mats)
    u = sim["u"][:-1]
    states = _replay(prob, u)
    assert np.allclose(states, np.column_stack([sim["r"], sim["v"]]), rtol=1e-6, atol=1e-6)
    k_f = int(np.flatnonzero(_converged(states, prob.params))[0])
    dt = prob.params.sample_time_s
    arrival = k_f * dt
    J = float(np.sum(0.5 * np.sum(u[:k_f] ** 2, axis=1) + rho) * dt)
    assert res["converged"] and res["arrival_time"] == pytest.approx(arrival, abs=1e-6)
    assert res["cost"] == pytest.approx(J, rel=1e-6)
    assert res["energy"] == pytest.approx(J - rho * arrival, rel=1e-6)
    assert res["horizon"] == 12_000.0


@pytest.mark.parametrize("given_s", [False, True], ids=["default_S", "random_S"])
def test_terminal_matches_a_replay(given_s):
    rng = np.random.default_rng(5)
    mats = _random_weights(rng)
    overrides = {"criterion": "terminal", "t_max": 1200.0}
    p0 = rz.Params()
    S = 0.01 * np.diag([p0.pos_tol_m ** -2] * 3 + [p0.vel_tol_m_s ** -2] * 3)
    if given_s:
        root = rng.normal(size=(6, 6))
        S = 1e-4 * root @ root.T
        overrides["terminal_weight"] = S.tolist()
    prob = rz.make_problem("default", overrides)
    res = prob.evaluate(mats)
    sim = prob.simulate(mats)
    u = sim["u"][:-1]
    assert u.shape[0] == 60     # no event: every run lasts t_max
    states = _replay(prob, u)
    x = states[-1]
    J = float(np.sum(0.5 * np.sum(u ** 2, axis=1)) * prob.params.sample_time_s + x @ S @ x)
    assert res["converged"] and res["status"] == "converged" and res["t_final"] == 1200.0
    assert res["cost"] == pytest.approx(J, rel=1e-6)
    assert res["terminal_cost"] == pytest.approx(x @ S @ x, rel=1e-6, abs=1e-15)
    assert np.allclose(res["terminal_S"], S, rtol=1e-12, atol=0.0)


def test_time_energy_failure_and_holdout():
    mats = {"Q": 1e-6 * np.eye(6), "R": 1e3 * np.eye(3)}
    prob = rz.make_problem("default", {"criterion": "time_energy", "free_time_cap": 400.0})
    res = prob.evaluate(mats)
    assert res["status"] == "horizon" and np.isnan(res["arrival_time"])
    p = prob.params
    e0 = max(np.linalg.norm(p.s0[:3]) / p.pos_tol_m, np.linalg.norm(p.s0[3:]) / p.vel_tol_m_s)
    e_end = max(res["final_distance"] / p.pos_tol_m, res["final_speed"] / p.vel_tol_m_s)
    graded = res["energy"] + 1e-5 * 400.0 + p.failure_penalty * (1.0 + e_end / e0)
    assert res["cost"] == pytest.approx(graded, rel=1e-12)
    held = prob.holdout(mats)
    assert held["horizon"] == held["training_horizon"] == 400.0
    assert np.array_equal(held["cost"], held["cost_at_deadline"])


def test_time_energy_ignores_the_delta_v_cutoff():
    mats = {"Q": 1e-6 * np.eye(6)[None], "R": 1e3 * np.eye(3)[None]}
    prob = rz.make_problem("default", {"criterion": "time_energy"})
    full = prob.evaluate_batch(mats)
    cut = prob.evaluate_batch(mats, thresholds=np.array([1e-9]))
    assert cut.cost[0] == full.cost[0] and cut.status[0] == "converged"


def test_default_is_delta_v():
    prob = rz.make_problem("default", {})
    res = prob.evaluate({"Q": 1e-6 * np.eye(6), "R": 1e3 * np.eye(3)})
    assert res["cost"] == res["delta_v"] and "criterion" not in res
    assert res["cost_unit"] == "m/s"


@pytest.mark.parametrize("overrides,key", [
    ({"criterion": "minimum_time"}, "problem.params.criterion"),
    ({"rho": -1.0}, "problem.params.rho"),
    ({"terminal_weight": [[1.0, 2.0], [2.0, 1.0]]}, "problem.params.terminal_weight"),
    ({"terminal_weight": [1, 1, 1, 1, 1, -0.5]}, "problem.params.terminal_weight"),
    ({"free_time_cap": 0}, "problem.params.free_time_cap"),
])
def test_bad_settings_are_one_config_error(overrides, key):
    with pytest.raises(ConfigError) as err:
        rz.make_problem("default", overrides)
    assert str(err.value).startswith(f"{key}: ") and "\n" not in str(err.value)
