"""Independent low-thrust reference shared by the kernel and min-fuel reference tests: the
Gauss variational equations in modified equinoctial elements written independently in plain
numpy (no production code), for scipy ``solve_ivp``."""

from __future__ import annotations

import numpy as np

from penaltyrun.dynamics import lowthrust as lt


def mee_rhs(_t: float, y: np.ndarray, u: np.ndarray, thrust: float, mdot: float) -> np.ndarray:
    """d/dt of (p, f, g, h, k, L, m) under thrust ``thrust`` N along the unit RTN vector
    ``u``; mass falls at ``mdot`` kg/s while thrusting. Units: km, s, kg."""
    p, f, g, h, k, L, m = y
    acc = thrust / (1000.0 * m) * u
    cl, sl = np.cos(L), np.sin(L)
    w = 1.0 + f * cl + g * sl
    s2 = 1.0 + h * h + k * k
    sig = h * sl - k * cl
    psi = np.sqrt(p / lt.MU)
    return np.array([
        2.0 * p * psi / w * acc[1],
        psi * (sl * acc[0] + ((w + 1) * cl + f) / w * acc[1] - g * sig / w * acc[2]),
        psi * (-cl * acc[0] + ((w + 1) * sl + g) / w * acc[1] + f * sig / w * acc[2]),
        psi * s2 * cl / (2 * w) * acc[2],
        psi * s2 * sl / (2 * w) * acc[2],
        np.sqrt(lt.MU * p) * (w / p) ** 2 + psi * sig / w * acc[2],
        -mdot if thrust > 0 else 0.0,
    ])
