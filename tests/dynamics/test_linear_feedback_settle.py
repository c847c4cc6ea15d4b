"""The settling event of the vectorized loop integrator against scipy ``solve_ivp``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import linear_feedback as loop

A = np.array([[0.0, 1.0], [-1.0, -0.3]])
B = np.array([[0.0], [1.0]])


def _plant(X, U):
    return X @ A.T + U @ B.T


@pytest.mark.parametrize("u_max", [None, 0.5], ids=["linear", "saturated"])
def test_settle_time_and_cost_match_solve_ivp(u_max):
    rng = np.random.default_rng(0)
    K = np.array([[[1.5, 0.8]], [[0.4, 0.2]], [[3.0, 2.0]]])
    X0 = rng.normal(size=(3, 2))
    level = 0.03 * np.linalg.norm(X0, axis=1)
    limits = None if u_max is None else np.array([u_max])
    run = loop.simulate(_plant, K, X0, np.eye(2), np.eye(1), limits, 200.0,
                        settle=level)
    assert np.all(run["status"] == loop.SETTLED)
    for r in range(3):
        def rhs(t, y, r=r):
            u = -K[r] @ y[:2]
            if u_max is not None:
                u = np.clip(u, -u_max, u_max)
            return np.append(A @ y[:2] + B @ u, y[:2] @ y[:2] + u @ u)

        def hit(t, y, r=r):
            return np.linalg.norm(y[:2]) - level[r]

        hit.terminal, hit.direction = True, -1.0
        sol = solve_ivp(rhs, (0.0, 200.0), np.append(X0[r], 0.0), method="DOP853",
                        rtol=1e-11, atol=1e-13, events=hit, max_step=0.05)
        assert run["t_end"][r] == pytest.approx(sol.t_events[0][0], abs=1e-7)
        assert run["cost"][r] == pytest.approx(sol.y_events[0][0][2], rel=1e-8)
        assert np.linalg.norm(run["x_final"][r]) == pytest.approx(level[r], rel=1e-8)


def test_no_settle_keeps_the_horizon_run():
    X0 = np.array([[1.0, 0.0]])
    K = np.array([[[1.5, 0.8]]])
    plain = loop.simulate(_plant, K, X0, np.eye(2), np.eye(1), None, 5.0)
    settled = loop.simulate(_plant, K, X0, np.eye(2), np.eye(1), None, 5.0,
                            settle=np.array([1e-9]))
    assert plain["status"][0] == settled["status"][0] == loop.HORIZON
    assert plain["cost"][0] == settled["cost"][0] and plain["t_end"][0] == 5.0
    at_start = loop.simulate(_plant, K, X0, np.eye(2), np.eye(1), None, 5.0,
                             settle=np.array([2.0]))
    assert at_start["status"][0] == loop.SETTLED and at_start["t_end"][0] == 0.0
