"""Kernel tests for penaltyrun.dynamics.lowthrust: conversions, max rates, gradients,
thrust-off invariance and agreement with an independent scipy integration."""

from __future__ import annotations

import numpy as np
import pytest
from lowthrust_reference import mee_rhs
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.problems.lowthrust import lyapunov_transfer, qlaw

DEG = np.pi / 180.0


def _qlaw_prm(sides: int = 2, a_cap: float = 0.0) -> np.ndarray:
    prm = qlaw.kernel_params(qlaw.make_problem("E", {}).params)
    prm[lt.I_SIDES] = sides
    prm[lt.I_ACAP] = a_cap
    return prm


def _random_spd(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(5, 5)))
    return q @ np.diag(rng.uniform(0.1, 10.0, 5)) @ q.T


def test_kep_mee_round_trip() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        oe = (rng.uniform(7000, 50000), rng.uniform(0.001, 0.9), rng.uniform(0.01, 3.0),
              rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0))
        back = lt.mee2kep(*lt.kep2mee(*oe))
        assert back[0] == pytest.approx(oe[0], rel=1e-12)
        assert back[1] == pytest.approx(oe[1], rel=1e-10)
        for j in range(2, 6):
            assert lt.wrap_angle(back[j] - oe[j]) == pytest.approx(0.0, abs=1e-9)


def test_zero_inclination_guard_keeps_longitude_of_periapsis() -> None:
    a, e, inc, raan, argp, nu = lt.mee2kep(*lt.kep2mee(8000.0, 0.1, 0.0, 0.7, 0.5, 0.3))
    assert inc == 0.0 and raan == 0.0
    assert argp == pytest.approx(1.2)
    assert nu == pytest.approx(0.3)


def test_max_rates_match_dense_search_over_true_anomaly() -> None:
    """ȧ_xx, ė_xx, i̇_xx, Ω̇_xx are maxima of F‖row of B(ν)‖ over ν."""
    prm = _qlaw_prm()
    a, e, inc, argp, F = 20000.0, 0.3, 0.5, 0.8, 1e-6
    rates = lt.max_rates(a + 0j, e + 0j, inc + 0j, argp + 0j, F, prm)
    B = np.empty((5, 3))
    best = np.zeros(4)
    for nu in np.linspace(0.0, 2.0 * np.pi, 20001):
        lt.gauss_matrix(a, e, inc, argp, nu, B)
        best = np.maximum(best, F * np.linalg.norm(B[:4], axis=1))
    for j in range(4):
        assert best[j] == pytest.approx(rates[j].real, rel=1e-6)


def test_omega_rate_cube_root_is_the_in_plane_maximum() -> None:
    """The ω̇_xxi cube-root formula locates the ν that maximises ‖B_ω,in-plane(ν)‖."""
    prm = _qlaw_prm()
    prm[lt.I_B] = 0.0
    a, e, F = 15000.0, 0.2, 1e-6
    rate = lt.max_rates(a + 0j, e + 0j, 0.4 + 0j, 0.3 + 0j, F, prm)[4].real
    B = np.empty((5, 3))
    best = max(F * np.linalg.norm(B[4, :2]) for nu in np.linspace(0, 2 * np.pi, 20001)
               if lt.gauss_matrix(a, e, 0.4, 0.3, nu, B) is None)
    assert best == pytest.approx(rate, rel=1e-6)
    small = lt.max_rates(a + 0j, 1e-4 + 0j, 0.4 + 0j, 0.3 + 0j, F, prm)[4]
    assert np.isfinite(small.real)


@pytest.mark.parametrize("sides", [2, 1])
def test_qlaw_gradient_matches_finite_differences(sides: int) -> None:
    rng = np.random.default_rng(7)
    prm = _qlaw_prm(sides=sides, a_cap=60000.0)
    oeT = np.array([26500.0, 0.7, 116 * DEG, 270 * DEG, 180 * DEG])
    sel = np.array([1.0, 1.0, 1.0, 1.0, 1.0 if sides == 2 else 0.0])
    for _ in range(10):
        K = _random_spd(rng)
        oe = np.array([rng.uniform(7000, 40000), rng.uniform(0.05, 0.8), rng.uniform(0.1, 2.5),
                       rng.uniform(-3, 3), rng.uniform(-3, 3), 0.0])
        grad = np.empty(5)
        q = lt.qlaw_gradient(oe[:5], 1e-6, oeT, sel, K, prm, grad)
        assert q == pytest.approx(lt.qlaw_value(oe[:5] + 0j, 1e-6, oeT, sel, K, prm).real)
        steps = np.array([1e-3, 1e-7, 1e-7, 1e-7, 1e-7])
        scale = np.array([oe[0], 1.0, 1.0, 1.0, 1.0])
        ref = np.max(np.abs(grad * scale))
        for j in range(5):
            zp = oe[:5].astype(complex)
            zm = oe[:5].astype(complex)
            zp[j] += steps[j]
            zm[j] -= steps[j]
            fd = (lt.qlaw_value(zp, 1e-6, oeT, sel, K, prm).real
                  - lt.qlaw_value(zm, 1e-6, oeT, sel, K, prm).real) / (2 * steps[j])
            assert abs(fd - grad[j]) * scale[j] <= 1e-6 * ref


def test_generic_gradient_matches_finite_differences() -> None:
    rng = np.random.default_rng(3)
    prm = lyapunov_transfer.kernel_params(lyapunov_transfer.make_problem("E", {}).params)
    oeT = np.array([26500.0, 0.7, 116 * DEG, 270 * DEG, 180 * DEG])
    sel = np.ones(5)
    for sides in (1, 2):
        prm[lt.I_SIDES] = sides
        K = _random_spd(rng)
        oe = np.array([12000.0, 0.3, 0.6, 1.0, -2.0])
        grad = np.empty(5)
        lt.generic_gradient(oe, oeT, sel, K, prm, grad)
        for j in range(5):
            h = 1e-3 if j == 0 else 1e-6
            op = oe.copy()
            om = oe.copy()
            op[j] += h
            om[j] -= h
            g = np.empty(5)
            fd = (lt.generic_gradient(op, oeT, sel, K, prm, g)
                  - lt.generic_gradient(om, oeT, sel, K, prm, g)) / (2 * h)
            assert fd == pytest.approx(grad[j], rel=1e-6, abs=1e-12)


def test_thrust_direction_minimises_qdot() -> None:
    rng = np.random.default_rng(5)
    prm = _qlaw_prm()
    oeT = np.array([26500.0, 0.7, 116 * DEG, 270 * DEG, 180 * DEG])
    oe6 = np.array([20000.0, 0.4, 0.7, 0.3, 1.1, 2.0])
    K = _random_spd(rng)
    grad = np.empty(5)
    B = np.empty((5, 3))
    ur, ut, un, on, _, _ = lt.law_eval(oe6, 1e-6, oeT, np.ones(5), K, prm, grad, B)
    assert on
    lt.gauss_matrix(oe6[0], oe6[1], oe6[2], oe6[4], oe6[5], B)
    g = B.T @ grad
    best = g @ np.array([ur, ut, un])
    assert best == pytest.approx(-np.linalg.norm(g))
    for _ in range(200):
        u = rng.normal(size=3)
        assert g @ (u / np.linalg.norm(u)) >= best - 1e-12 * abs(best)


def test_effectivity_extremes_match_dense_grid() -> None:
    grad = np.array([1e-3, 2.0, -0.5, 0.3, 0.8])
    B = np.empty((5, 3))
    gmax, gmin = lt.effectivity_extremes(20000.0, 0.4, 0.7, 1.1, grad, 36, B)
    dense = [np.linalg.norm(B.T @ grad) for nu in np.linspace(0, 2 * np.pi, 100001)
             if lt.gauss_matrix(20000.0, 0.4, 0.7, 1.1, nu, B) is None]
    assert gmax == pytest.approx(max(dense), rel=1e-7)
    assert gmin == pytest.approx(min(dense), rel=1e-5)


def test_thrust_off_elements_constant_over_100_revolutions() -> None:
    prob = qlaw.make_problem("B", {"thrust_newton": 0.0, "max_revs": 100.0,
                                   "stall_window_revs": 0.0, "Omega0_deg": 40.0,
                                   "omega0_deg": 70.0, "tof_cap_days": 1000.0})
    sim = prob.simulate({"K": np.eye(5)})
    assert prob.evaluate({"K": np.eye(5)})["status"] == "rev_cap"
    assert (sim["t"][-1] - sim["t"][0]) > 99 * 2 * np.pi * np.sqrt(24505.9**3 / lt.MU)
    for key in ("a", "e", "i", "Omega", "omega", "mass"):
        v = sim[key]
        assert np.max(np.abs(v - v[0])) <= 1e-10 * abs(v[0]), key


# -- independent reference: scipy solve_ivp (DOP853, rtol 1e-11) within each held step ----
def _reference_transfer(prob) -> tuple[float, float]:
    """ToF (s) and final mass (kg) with scipy integrating each zero-order-hold step."""
    pr = prob.params
    prm = prob._prm
    y = np.array(list(lt.kep2mee(*prob._oe0)) + [pr.m0_kg])
    mdot = pr.thrust_newton / (lt.G0 * pr.isp_s)
    grad = np.empty(5)
    B = np.empty((5, 3))
    err = np.empty(5)
    t = 0.0
    while t < pr.tof_cap_days * 86400.0:
        oe6 = np.array(lt.mee2kep(*y[:6]))
        lt.element_errors(oe6, prob._oeT, err)
        if np.all((np.abs(err) <= prob._tol) | (prob._sel == 0)):
            return t, y[6]
        F = pr.thrust_newton / (1000.0 * y[6])
        ur, ut, un, on, _, _ = lt.law_eval(oe6, F, prob._oeT, prob._sel, np.eye(5), prm,
                                           grad, B)
        sol = solve_ivp(mee_rhs, (0.0, pr.control_step_s), y, method="DOP853",
                        rtol=1e-11, atol=1e-12,
                        args=(np.array([ur, ut, un]), pr.thrust_newton if on else 0.0, mdot))
        y = sol.y[:, -1]
        t += pr.control_step_s
    raise AssertionError("reference transfer did not converge")


def _check_against_reference(prob) -> None:
    res = prob.evaluate({"K": np.eye(5)})
    assert res["converged"]
    tof, mass = _reference_transfer(prob)
    assert res["t_final"] == pytest.approx(tof, rel=1e-3)
    assert abs(res["final_mass_kg"] - mass) <= 0.1


def test_qlaw_matches_solve_ivp_case_c() -> None:
    _check_against_reference(qlaw.make_problem("C", {}))


def test_generic_law_matches_solve_ivp_short_transfer() -> None:
    prob = lyapunov_transfer.make_problem("C", {"a_target_km": 14000.0, "e_target": 0.2})
    _check_against_reference(prob)


@pytest.mark.slow
@pytest.mark.parametrize("module", [qlaw, lyapunov_transfer])
def test_full_case_a_matches_solve_ivp(module) -> None:
    _check_against_reference(module.make_problem("A", {}))
