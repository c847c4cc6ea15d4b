"""``problem=lqr`` criteria against independent references.

Continuous plants: scipy ``solve_ivp`` (DOP853, rtol 1e-10) of ẋ = A x + B sat(−K x) with
the running cost as an extra state, K from scipy's Riccati solver; sampled plants: a plain
loop. ``time_energy``: J = ∫₀^{t_s} (xᵀW_x x + uᵀW_u u + ρ) dt to the first time
‖x‖ ≤ settle_tol ‖x0‖ (J to 1e-6 relative, t_s to 1e-6); ``terminal``: J + x(T)ᵀ S x(T).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import solve_continuous_are, solve_discrete_are

from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr.params import KNOWN_ANSWER

A = np.array(KNOWN_ANSWER["A"])
B = np.array(KNOWN_ANSWER["B"])
WX = np.array(KNOWN_ANSWER["state_weight"])
X0 = np.array(KNOWN_ANSWER["x0"])


def _spd(rng, n, lo, hi):
    basis, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return basis @ np.diag(rng.uniform(lo, hi, n)) @ basis.T


def _reference(K, x0, t_end, u_max=None, level=None, rho=0.0, cubic=False):
    def rhs(t, y):
        u = -K @ y[:3]
        if u_max is not None:
            u = np.clip(u, -u_max, u_max)
        dx = A @ y[:3] + B @ u
        if cubic:
            dx[1] -= 0.1 * y[0] ** 3
        return np.append(dx, y[:3] @ WX @ y[:3] + u @ u + rho)

    kwargs = {}
    if level is not None:
        def hit(t, y):
            return np.linalg.norm(y[:3]) - level * np.linalg.norm(x0)

        hit.terminal, hit.direction = True, -1.0
        kwargs = {"events": hit, "max_step": 0.05}
    sol = solve_ivp(rhs, (0.0, t_end), np.append(x0, 0.0), method="DOP853", rtol=1e-10,
                    atol=1e-13, **kwargs)
    if level is not None:
        assert sol.t_events[0].size
        return float(sol.t_events[0][0]), sol.y_events[0][0]
    return float(sol.t[-1]), sol.y[:, -1]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_time_energy_continuous_matches_solve_ivp(seed):
    rng = np.random.default_rng(seed)
    Q, R = _spd(rng, 3, 0.1, 10.0), _spd(rng, 2, 0.1, 10.0)
    rho = float(rng.uniform(0.01, 1.0))
    level = float(rng.uniform(0.005, 0.05))
    prob = lqr.make_problem("default", {"criterion": "time_energy", "rho": rho,
                                        "settle_tol": level})
    res = prob.evaluate({"Q": Q, "R": R})
    K = np.linalg.solve(R, B.T @ solve_continuous_are(A, B, Q, R))
    assert np.allclose(res["gain"], K, rtol=1e-8, atol=1e-10)
    held = prob.holdout({"Q": Q, "R": R})
    for i, x0 in enumerate(X0):
        t_s, y = _reference(K, x0, 500.0, level=level, rho=rho)
        assert res["start_costs"][i] == pytest.approx(y[3], rel=1e-6)
    assert res["converged"] and res["cost"] == pytest.approx(np.mean(res["start_costs"]))
    x0 = held["x0"][0]
    t_s, y = _reference(K, x0, 500.0, level=level, rho=rho)
    assert held["arrival_time"][0] == pytest.approx(t_s, abs=1e-6)
    assert held["cost"][0] == pytest.approx(y[3], rel=1e-6)
    assert held["horizon"] == held["training_horizon"] == 1000.0


@pytest.mark.parametrize("u_max", [1.0, None], ids=["saturated", "nonlinear"])
def test_time_energy_integrated_matches_solve_ivp(u_max):
    """Saturated loops and a nonlinear ``dynamics`` (here the linear plant plus a cubic
    term) go through the vectorized integrator and its settling event."""
    rng = np.random.default_rng(9)
    Q, R = _spd(rng, 3, 0.1, 10.0), _spd(rng, 2, 0.1, 10.0)
    rho, level = 0.2, 0.02
    overrides = {"criterion": "time_energy", "rho": rho, "settle_tol": level}
    if u_max is None:
        overrides.update({"dynamics": f"{__name__}:cubic", "A": KNOWN_ANSWER["A"],
                          "B": KNOWN_ANSWER["B"], "x0": KNOWN_ANSWER["x0"],
                          "state_weight": KNOWN_ANSWER["state_weight"],
                          "input_weight": KNOWN_ANSWER["input_weight"]})
    else:
        overrides["u_max"] = u_max
    prob = lqr.make_problem("default", overrides)
    res = prob.evaluate({"Q": Q, "R": R})
    K = np.linalg.solve(R, B.T @ solve_continuous_are(A, B, Q, R))
    assert np.allclose(res["gain"], K, rtol=1e-8, atol=1e-10)
    if u_max is not None:
        assert np.abs(K @ X0.T).max() > u_max    # the limit is active
    for i, x0 in enumerate(X0):
        _, y = _reference(K, x0, 500.0, u_max=u_max, level=level, rho=rho,
                          cubic=u_max is None)
        assert res["start_costs"][i] == pytest.approx(y[3], rel=1e-6)
    held = prob.holdout({"Q": Q, "R": R})
    t_s, y = _reference(K, held["x0"][0], 500.0, u_max=u_max, level=level, rho=rho,
                        cubic=u_max is None)
    assert held["arrival_time"][0] == pytest.approx(t_s, abs=1e-6)
    assert held["cost"][0] == pytest.approx(y[3], rel=1e-6)


def test_time_energy_divergence_is_graded_above_the_penalty():
    prob = lqr.make_problem("default", {"criterion": "time_energy", "u_max": 0.05})
    res = prob.evaluate({"Q": np.eye(3), "R": np.eye(2)})
    diverged = [c for c, s in zip(res["start_costs"], res["start_status"]) if s == "diverged"]
    assert diverged and min(diverged) > 2.0 * res["failure_penalty"]


def cubic(X, U):
    """A nonlinear plant for the test: the known-answer plant plus −0.1 x₁³ on ẋ₂."""
    out = X @ A.T + U @ B.T
    out[:, 1] -= 0.1 * X[:, 0] ** 3
    return out


def test_time_energy_sampled_matches_a_plain_loop():
    rng = np.random.default_rng(4)
    Q, R = _spd(rng, 3, 0.1, 10.0), _spd(rng, 2, 0.1, 10.0)
    dt, rho, level = 0.2, 0.3, 0.02
    prob = lqr.make_problem("default", {"criterion": "time_energy", "rho": rho, "dt": dt,
                                        "settle_tol": level, "u_max": 0.5})
    res = prob.evaluate({"Q": Q, "R": R})
    K = np.asarray(res["gain"])
    P = solve_discrete_are(A, B, Q, R)
    assert np.allclose(K, np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A), rtol=1e-8)
    for i, x0 in enumerate(X0):
        x, J, k = x0.copy(), 0.0, 0
        while np.linalg.norm(x) > level * np.linalg.norm(x0):
            u = np.clip(-K @ x, -0.5, 0.5)
            J += x @ WX @ x + u @ u
            x = A @ x + B @ u
            k += 1
        assert res["start_costs"][i] == pytest.approx(J + rho * k * dt, rel=1e-9)


@pytest.mark.parametrize("u_max,given_s", [(None, False), (None, True), (0.3, False)],
                         ids=["closed_form_default_S", "closed_form_random_S",
                              "saturated_default_S"])
def test_terminal_matches_solve_ivp(u_max, given_s):
    rng = np.random.default_rng(7)
    Q, R = _spd(rng, 3, 0.1, 10.0), _spd(rng, 2, 0.1, 10.0)
    overrides = {"criterion": "terminal", "t_max": 2.0}
    S = solve_continuous_are(A, B, WX, np.eye(2))
    if given_s:
        root = rng.normal(size=(3, 2))
        S = root @ root.T
        overrides["terminal_weight"] = S.tolist()
    if u_max is not None:
        overrides["u_max"] = u_max
    prob = lqr.make_problem("default", overrides)
    res = prob.evaluate({"Q": Q, "R": R})
    K = np.linalg.solve(R, B.T @ solve_continuous_are(A, B, Q, R))
    for i, x0 in enumerate(X0):
        _, y = _reference(K, x0, 2.0, u_max=u_max)
        expected = y[3] + y[:3] @ S @ y[:3]
        assert res["start_costs"][i] == pytest.approx(expected, rel=1e-6)


def test_defaults_unchanged_and_settings_checked():
    base = lqr.make_problem("default", {})
    assert base.params.criterion == "deadline" and base.S is None
    assert base.params.setup == ""
    user = lqr.make_problem("default", {"A": [[0, 1], [-1, -1]], "B": [0, 1]})
    assert user.params.setup == "A,B#d67a82e3"   # the label before the criteria existed
    terminal = lqr.make_problem("default", {"criterion": "terminal"})
    assert terminal.params.setup not in ("", "A,B#d67a82e3")
    with pytest.raises(ConfigError, match="^problem.params.terminal_weight: "):
        lqr.make_problem("default", {"criterion": "terminal", "terminal_weight": [1, -1, 1]})
    with pytest.raises(ConfigError, match="^problem.params.rho: "):
        lqr.make_problem("default", {"criterion": "time_energy", "rho": 0})
    with pytest.raises(ConfigError, match="^problem.params.criterion: unknown"):
        lqr.make_problem("default", {"criterion": "fast"})
