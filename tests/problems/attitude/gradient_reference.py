"""Independent references for the attitude gradient tests: a complex-analytic closed loop
for complex-step derivatives (terminal criterion), the scipy reference run of the problem
module for differences of the free-final-time criterion, and a fourth-order central
difference."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from penaltyrun.problems.attitude import criteria as attitude_criteria
from penaltyrun.problems.attitude.reference import reference_run

#: Tolerances of the reference integrations (tighter than the problem's 1e-10).
REF_TOL = 1e-12


def complex_rhs(G: np.ndarray, inertia: np.ndarray):
    """Closed loop (q, ω, E) written analytically in G (no abs, no conj): complex G gives
    the complex-step derivative."""
    inertia_inv = np.linalg.inv(inertia)

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        q, w = y[:4], y[4:7]
        u = -G @ y[1:7]
        om = np.array([[0, -w[0], -w[1], -w[2]], [w[0], 0, w[2], -w[1]],
                       [w[1], -w[2], 0, w[0]], [w[2], w[1], -w[0], 0]])
        return np.concatenate([0.5 * om @ q, inertia_inv @ (u - np.cross(w, inertia @ w)),
                               [0.5 * (u @ u)]])

    return rhs


def terminal_value(problem: Any, G: np.ndarray) -> complex:
    """E(T) + x(T)ᵀ S x(T) of a (complex) gain by solve_ivp DOP853 at :data:`REF_TOL`."""
    p = problem.params
    y0 = np.concatenate([problem.y0, [0.0]]).astype(complex)
    sol = solve_ivp(complex_rhs(np.asarray(G, dtype=complex), problem.inertia),
                    (0.0, float(p.t_max)), y0, method="DOP853", rtol=REF_TOL, atol=REF_TOL)
    y = sol.y[:, -1]
    x = y[1:7]
    return y[7] + x @ attitude_criteria.terminal_weight(p) @ x


def terminal_complex_step(problem: Any, G: np.ndarray, D: np.ndarray, h: float = 1e-30
                          ) -> float:
    """Directional derivative of the terminal criterion along D (3 × 6) by complex step."""
    return float(np.imag(terminal_value(problem, G + 1j * h * D)) / h)


def time_energy_value(problem: Any, G: np.ndarray) -> float:
    """E(t_f) + ρ t_f of a gain by the problem module's scipy reference run (first crossing
    located on the dense output) at :data:`REF_TOL`."""
    p = problem.params
    out = reference_run(G, replace(p, t_max=float(p.free_time_cap)), problem.y0,
                        rtol=REF_TOL, atol=REF_TOL)
    assert out["converged"]
    return out["energy"] + float(p.rho) * out["t_final"]


def central(f, h: float) -> float:
    """Fourth-order central difference of the scalar function f(s) at s = 0."""
    return (8.0 * (f(h) - f(-h)) - (f(2 * h) - f(-2 * h))) / (12.0 * h)


def random_z(layout: Any, rng: np.random.Generator, lo: float = 0.2, hi: float = 0.6
             ) -> np.ndarray:
    """A point inside the box of ``layout``: each coordinate at a uniform fraction in
    [lo, hi] of its side."""
    lb, ub = layout.bounds()
    return lb + (ub - lb) * rng.uniform(lo, hi, size=lb.size)
