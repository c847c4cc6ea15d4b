"""The Keplerian model-mismatch plant (compiled RK4 of the nonlinear relative motion) against
solve_ivp, the CW model and the conservation laws of the target orbit."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from penaltyrun.problems.mpc import controller as ctl
from penaltyrun.problems.mpc.model import cw_continuous, mean_motion, zoh

MU = 398600.4418e9
A_M = 6778.137e3


def naive_rhs(t, y, acc):
    """Relative motion as the difference of two inertial accelerations in the rotating frame
    (written independently of the kernel, with the plain cancelling form)."""
    x, yy, z, vx, vy, vz, r, rdot, thdot = y
    thddot = -2.0 * rdot * thdot / r
    rc = math.sqrt((r + x) ** 2 + yy ** 2 + z ** 2)
    return [vx, vy, vz,
            2 * thdot * vy + thddot * yy + thdot ** 2 * x + MU / r ** 2
            - MU * (r + x) / rc ** 3 + acc[0],
            -2 * thdot * vx - thddot * x + thdot ** 2 * yy - MU * yy / rc ** 3 + acc[1],
            -MU * z / rc ** 3 + acc[2],
            rdot, r * thdot ** 2 - MU / r ** 2, thddot]


@pytest.mark.parametrize("ecc", [0.0, 0.01, 0.1])
def test_rk4_plant_matches_solve_ivp(ecc):
    plant = ctl.KeplerianPlant(A_M, ecc, 0.3, MU, 20.0, 20)
    s0 = np.array([100.0, -1000.0, 50.0, 0.1, -0.2, 0.05])
    y0 = np.concatenate([s0, plant.target])
    acc = np.array([0.01, -0.004, 0.007])
    plant.thrust_scale = 1.0
    plant.reset(s0)
    for _ in range(10):
        s = plant.step(acc)
    sol = solve_ivp(naive_rhs, (0.0, 200.0), y0, args=(acc,), method="DOP853",
                    rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(s, sol.y[:6, -1], rtol=0, atol=1e-6)


def test_target_orbit_keeps_angular_momentum_and_energy():
    plant = ctl.KeplerianPlant(A_M, 0.05, 0.0, MU, 20.0, 20)
    plant.reset(np.zeros(6))
    def invariants(y):
        r, rdot, thdot = y[6:]
        return r * r * thdot, 0.5 * (rdot ** 2 + (r * thdot) ** 2) - MU / r
    h0, en0 = invariants(plant.y)
    for _ in range(300):   # 6000 s, more than one orbit
        plant.step(np.zeros(3))
    h1, en1 = invariants(plant.y)
    assert h1 == pytest.approx(h0, rel=1e-12)
    assert en1 == pytest.approx(en0, rel=1e-12)


def test_circular_keplerian_plant_is_cw_to_first_order():
    """Near the target (ρ ≪ a) the nonlinear plant differs from CW by O(ρ/a) relative."""
    n = mean_motion(A_M, MU)
    Ad, Bd = zoh(*cw_continuous(n), 20.0)
    lin = ctl.LinearPlant(Ad, Bd)
    kep = ctl.KeplerianPlant(A_M, 0.0, 0.0, MU, 20.0, 20)
    for rho in (1000.0, 100.0):
        s0 = np.array([0.1, -1.0, 0.05, 1e-4, 1e-4, 0.0]) * rho
        lin.reset(s0)
        kep.reset(s0)
        for _ in range(50):
            a = np.array([1e-4, -2e-4, 5e-5]) * rho / 1000.0
            sl, sk = lin.step(a), kep.step(a)
        rel = np.linalg.norm(sl[:3] - sk[:3]) / np.linalg.norm(sl[:3])
        assert rel < 20.0 * rho / A_M


def test_thrust_scale_scales_the_applied_input():
    n = mean_motion(A_M, MU)
    Ad, Bd = zoh(*cw_continuous(n), 20.0)
    plant = ctl.LinearPlant(Ad, Bd, 0.95)
    plant.reset(np.zeros(6))
    u = np.array([0.01, 0.0, -0.01])
    np.testing.assert_allclose(plant.step(u), Bd @ (0.95 * u), rtol=1e-15)
