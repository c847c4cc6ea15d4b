"""Compiled attitude kernel: right-hand side, conservation laws, saturation, event."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.dynamics import attitude as at
from penaltyrun.dynamics import integrate
from penaltyrun.problems.attitude.common import Params, _rhs_numpy, reference_run

I_DIAG = np.diag([10.0, 15.0, 20.0])
I_FULL = np.array([[10.0, 1.0, 0.5], [1.0, 15.0, -0.7], [0.5, -0.7, 20.0]])
Q_START = np.array([0.413836, -0.610042, 0.290580, 0.610042])
Q_START = Q_START / np.linalg.norm(Q_START)


def _final(G, y0, inertia, t_max=100.0, tol=1e-4, u_max=np.inf, rtol=1e-10,
           max_step=np.inf):
    return at.final_state(np.asarray(G, float), np.asarray(y0, float), inertia,
                          np.linalg.inv(inertia), t_max, tol, u_max, rtol, rtol, max_step,
                          0.05, 4, 1_000_000)


def _params_vector(G, inertia, u_max=np.inf, tol=1e-4):
    p = np.empty(at.N_PRM)
    at.pack_params(inertia, np.linalg.inv(inertia), np.asarray(G, float), u_max, tol, p)
    return p


@pytest.mark.parametrize("u_max", [np.inf, 0.05])
def test_rhs_matches_numpy_model(u_max):
    rng = np.random.default_rng(3)
    G = rng.normal(size=(3, 6))
    y = np.concatenate([rng.normal(size=4), 0.1 * rng.normal(size=3), [0.0]])
    out = np.empty(8)
    at.rhs(0.0, y, _params_vector(G, I_FULL, u_max), out)
    ref = _rhs_numpy(G, I_FULL, np.linalg.inv(I_FULL), u_max)(0.0, y)
    np.testing.assert_allclose(out, ref, rtol=1e-13, atol=1e-15)


def test_no_control_no_rates_nothing_moves():
    y0 = np.concatenate([Q_START, np.zeros(3)])
    t, y, status = _final(np.zeros((3, 6)), y0, I_FULL, t_max=50.0)
    assert status == integrate.HORIZON
    assert t == pytest.approx(50.0)
    np.testing.assert_array_equal(y[:7], y0)
    assert y[7] == 0.0


def test_torque_free_conserves_energy_momentum_and_norm():
    w0 = np.array([0.3, -0.2, 0.25])
    y0 = np.concatenate([Q_START, w0])
    t, y, status = _final(np.zeros((3, 6)), y0, I_FULL, t_max=100.0)
    assert status == integrate.HORIZON
    w = y[4:7]
    assert 0.5 * w @ I_FULL @ w == pytest.approx(0.5 * w0 @ I_FULL @ w0, rel=1e-9)
    assert np.linalg.norm(I_FULL @ w) == pytest.approx(np.linalg.norm(I_FULL @ w0), rel=1e-9)
    # ~5 revolutions of fast tumbling (30x the manoeuvre rates): drift ~1e-9
    assert abs(np.linalg.norm(y[:4]) - 1.0) < 5e-9
    assert not np.allclose(w, w0)  # the body really tumbled (full inertia)


def test_quaternion_norm_conserved_under_control():
    G = np.hstack([0.5 * np.eye(3), 2.0 * np.eye(3)])
    y0 = np.concatenate([Q_START, [0.05, -0.04, 0.03]])
    for t_max in (10.0, 40.0, 100.0):
        _, y, _ = _final(G, y0, I_FULL, t_max=t_max, tol=1e-12)
        assert abs(np.linalg.norm(y[:4]) - 1.0) < 1e-9


def test_saturation_bounds_torque_and_agrees_with_reference():
    u_max = 0.02
    G = np.hstack([2.0 * np.eye(3), 6.0 * np.eye(3)])
    y0 = np.concatenate([Q_START, np.zeros(3)])
    t, y, status = _final(G, y0, I_DIAG, t_max=100.0, u_max=u_max)
    t_free, y_free, _ = _final(G, y0, I_DIAG, t_max=100.0)
    # energy rate is at most ½·3·u_max², and saturation really bit (unsaturated |u| ≈ 2)
    assert y[7] <= 1.5 * u_max ** 2 * t * (1.0 + 1e-12)
    assert y[7] < 0.5 * y_free[7]
    # the saturated torque along the reference path stays within the limit
    params = Params(omega0=(0.0, 0.0, 0.0), u_max=u_max)
    ref = reference_run(G, params)
    assert ref["energy"] == pytest.approx(y[7], rel=1e-6)
    assert ref["converged"] == (status == integrate.EVENT)
    p = _params_vector(G, I_DIAG, u_max)
    for state in (np.concatenate([y0, [0.0]]), y):
        u = np.array([at._torque(state, p, i) for i in range(3)])
        assert np.all(np.abs(u) <= u_max)


def test_batch_broadcasts_gains_and_starts():
    G = np.stack([np.hstack([k * np.eye(3), 3 * k * np.eye(3)]) for k in (0.5, 1.0, 2.0)])
    y0 = np.concatenate([Q_START, [0.01, -0.01, 0.01]])[None]
    Iinv = np.linalg.inv(I_DIAG)
    args = (100.0, 1e-4, np.inf, 1e-10, 1e-10, np.inf, 0.05, 4, 1_000_000)
    t_b, c_b, d_b, s_b = at.simulate_batch(G, y0, I_DIAG, Iinv, *args)
    assert t_b.shape == (3,)
    for k in range(3):
        t1, c1, d1, s1 = at.simulate_batch(G[k:k + 1], y0, I_DIAG, Iinv, *args)
        assert (t1[0], c1[0], d1[0], s1[0]) == (t_b[k], c_b[k], d_b[k], s_b[k])
    starts = np.repeat(y0, 4, axis=0)
    starts[1:, 4:7] = 0.0
    out = at.simulate_batch(G[:1], starts, I_DIAG, Iinv, *args)
    assert out[0].shape == (4,)
    assert out[1][0] == c_b[0]


def test_event_at_start_fires_immediately():
    y0 = np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    t, y, status = _final(np.eye(3, 6), y0, I_DIAG)
    assert status == integrate.EVENT and t == 0.0 and y[7] == 0.0
