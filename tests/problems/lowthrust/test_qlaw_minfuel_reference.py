"""Independent reference for minimum-fuel Q-law coasting.

The reference re-implements, in plain numpy/scipy, everything the coasting decision depends
on except ∇Q: the Keplerian Gauss matrix (written from Gauss' equations), the extremes
Q̇_nn, Q̇_nx of Q̇_n = −F‖Bᵀ∇Q‖ over true anomaly by brute force on a dense grid of
``N_NU`` points (no golden-section refinement, unlike the production code), the
effectivity η_a or η_r, and the flight between control steps (scipy ``solve_ivp`` DOP853 at
rtol 1e-11 with the control held over each step). ∇Q and the thrust direction come from the
production law with coasting switched off (they are tested against finite differences in
tests/dynamics/test_lowthrust.py). Acceptance: propellant within 0.1 kg and time of flight
within 0.1 % on Cases A and C with η_cut 0.3 and 0.6.
"""

from __future__ import annotations

import numpy as np
import pytest
from lowthrust_reference import mee_rhs
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.problems.lowthrust import qlaw

#: True-anomaly grid of the brute-force effectivity search.
N_NU = 7200
NU = np.linspace(0.0, 2.0 * np.pi, N_NU, endpoint=False)


def gauss_rows(a: float, e: float, inc: float, argp: float, nu: np.ndarray) -> np.ndarray:
    """Keplerian Gauss matrices (rows a, e, i, Ω, ω; columns R, T, N), shape (n, 5, 3)."""
    p = a * (1.0 - e * e)
    h = np.sqrt(lt.MU * p)
    r = p / (1.0 + e * np.cos(nu))
    u = argp + nu
    B = np.zeros((nu.size, 5, 3))
    B[:, 0, 0] = 2.0 * a * a / h * e * np.sin(nu)
    B[:, 0, 1] = 2.0 * a * a / h * p / r
    B[:, 1, 0] = p * np.sin(nu) / h
    B[:, 1, 1] = ((p + r) * np.cos(nu) + r * e) / h
    B[:, 2, 2] = r * np.cos(u) / h
    B[:, 3, 2] = r * np.sin(u) / (h * np.sin(inc))
    B[:, 4, 0] = -p * np.cos(nu) / (e * h)
    B[:, 4, 1] = (p + r) * np.sin(nu) / (e * h)
    B[:, 4, 2] = -r * np.sin(u) * np.cos(inc) / (h * np.sin(inc))
    return B


def effectivity(oe6: np.ndarray, grad: np.ndarray, prm: np.ndarray, mode: str) -> float:
    """η_a = Q̇_n/Q̇_nn or η_r = (Q̇_n − Q̇_nx)/(Q̇_nn − Q̇_nx) by brute force over ν."""
    e = max(oe6[1], prm[lt.I_EFLOOR])
    inc = min(max(oe6[2], prm[lt.I_IFLOOR]), np.pi - prm[lt.I_IFLOOR])
    nus = np.append(NU, oe6[5])
    g = np.linalg.norm(np.einsum("nij,i->nj", gauss_rows(oe6[0], e, inc, oe6[4], nus), grad),
                       axis=1)
    now, gmax, gmin = g[-1], g.max(), g.min()
    if mode == "eta_a":
        return now / gmax
    return (now - gmin) / (gmax - gmin) if gmax > gmin else 1.0


def reference_min_fuel(prob, K: np.ndarray, eta_cut: float) -> tuple[float, float]:
    """Time of flight (s) and propellant (kg) of the reference transfer."""
    pr = prob.params
    prm = prob._prm.copy()
    prm[lt.I_COAST] = lt.COAST_NONE  # direction and ∇Q only; coasting decided here
    mdot = pr.thrust_newton / (lt.G0 * pr.isp_s)
    y = np.array(list(lt.kep2mee(*prob._oe0)) + [pr.m0_kg])
    grad, B, err = np.empty(5), np.empty((5, 3)), np.empty(5)
    t = 0.0
    while t < pr.tof_cap_days * 86400.0:
        oe6 = np.array(lt.mee2kep(*y[:6]))
        lt.element_errors(oe6, prob._oeT, err)
        if np.all((np.abs(err) <= prob._tol) | (prob._sel == 0)):
            return t, pr.m0_kg - y[6]
        F = pr.thrust_newton / (1000.0 * y[6])
        ur, ut, un, on, _, _ = lt.law_eval(oe6, F, prob._oeT, prob._sel, K, prm, grad, B)
        on = on and effectivity(oe6, grad, prm, pr.coast_mode) >= eta_cut
        sol = solve_ivp(mee_rhs, (0.0, pr.control_step_s), y, method="DOP853", rtol=1e-11,
                        atol=1e-12, args=(np.array([ur, ut, un]),
                                          pr.thrust_newton if on else 0.0, mdot))
        y = sol.y[:, -1]
        t += pr.control_step_s
    raise AssertionError("reference transfer did not converge")


def check(case: str, eta_cut: float, mode: str = "eta_a") -> None:
    prob = qlaw.make_problem(case, {"objective": "min_fuel", "coast_mode": mode})
    K = np.eye(5)
    res = prob.evaluate({"K": K}, {"eta_cut": eta_cut})
    always = qlaw.make_problem(case, {}).evaluate({"K": K})
    assert res["converged"]
    tof, prop = reference_min_fuel(prob, K, eta_cut)
    print(f"{case} eta_cut={eta_cut} {mode}: propellant {res['propellant_kg']:.4f} vs "
          f"{prop:.4f} kg, ToF {res['t_final']:.1f} vs {tof:.1f} s")
    assert abs(res["propellant_kg"] - prop) <= 0.1
    assert res["t_final"] == pytest.approx(tof, rel=1e-3)
    assert res["propellant_kg"] < always["propellant_kg"]  # coasting did happen


@pytest.mark.parametrize("eta_cut", [0.3, pytest.param(0.6, marks=pytest.mark.slow)])
def test_case_c_min_fuel_matches_reference(eta_cut):
    check("C", eta_cut)


@pytest.mark.slow
def test_case_c_relative_effectivity_matches_reference():
    check("C", 0.3, "eta_r")


@pytest.mark.reference
@pytest.mark.parametrize("eta_cut", [0.3, pytest.param(0.6, marks=pytest.mark.slow)])
def test_case_a_min_fuel_matches_reference(eta_cut):
    check("A", eta_cut)
