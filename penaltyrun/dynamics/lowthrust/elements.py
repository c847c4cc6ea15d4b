"""Orbital elements and equations of motion of the low-thrust kernels (numba, floats and arrays).

Conversions between Keplerian elements ``(a, e, i, Ω, ω, ν)`` and modified equinoctial
elements (MEE) ``(p, f, g, h, k, L)``, the Gauss variational equations in MEE with mass, a
fixed-step RK4 with the control held, and the Keplerian Gauss matrix used by the steering laws.
Units: km, s, kg, N; angles in rad.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.lowthrust.settings import MU


@njit(cache=True)
def wrap_angle(x):
    """Wrap an angle to (−π, π] via atan2(sin x, cos x) (rad)."""
    return np.arctan2(np.sin(x), np.cos(x))


@njit(cache=True)
def kep2mee(a, e, inc, raan, argp, nu):
    """Keplerian (a km, e, i, Ω, ω, ν rad) → MEE (p km, f, g, h, k, L rad)."""
    p = a * (1.0 - e * e)
    f = e * np.cos(raan + argp)
    g = e * np.sin(raan + argp)
    t2 = np.tan(0.5 * inc)
    h = t2 * np.cos(raan)
    k = t2 * np.sin(raan)
    return p, f, g, h, k, raan + argp + nu


@njit(cache=True)
def mee2kep(p, f, g, h, k, L):
    """MEE → Keplerian (a, e, i, Ω, ω, ν).

    At exactly zero inclination (h = k = 0) Ω is set to 0 and ω to the longitude of
    periapsis atan2(g, f), so that Ω + ω stays correct.
    """
    e2 = f * f + g * g
    a = p / (1.0 - e2)
    e = np.sqrt(e2)
    hk2 = h * h + k * k
    inc = np.arctan2(2.0 * np.sqrt(hk2), 1.0 - hk2)
    if hk2 > 1e-300:
        raan = np.arctan2(k, h)
        argp = np.arctan2(g * h - f * k, f * h + g * k)
    else:
        raan = 0.0
        argp = np.arctan2(g, f)
    nu = L - raan - argp
    return a, e, inc, raan, argp, nu


@njit(cache=True)
def mee2cart(p, f, g, h, k, L):
    """MEE → inertial position (x, y, z), km."""
    w = 1.0 + f * np.cos(L) + g * np.sin(L)
    r = p / w
    s2 = 1.0 + h * h + k * k
    al2 = h * h - k * k
    cl = np.cos(L)
    sl = np.sin(L)
    x = r / s2 * (cl + al2 * cl + 2.0 * h * k * sl)
    y = r / s2 * (sl - al2 * sl + 2.0 * h * k * cl)
    z = 2.0 * r / s2 * (h * sl - k * cl)
    return x, y, z


@njit(cache=True)
def mee_rhs(y, ur, ut, un, thrust, mdot, out):
    """Gauss variational equations in MEE with mass.

    Parameters
    ----------
    y : ndarray, shape (7,)
        (p km, f, g, h, k, L rad, m kg).
    ur, ut, un : float
        Thrust direction (radial, transverse, normal), unit vector or zero.
    thrust : float
        Thrust magnitude, N (0 when coasting).
    mdot : float
        Mass flow while thrusting, kg/s (positive number).
    out : ndarray, shape (7,)
        Receives dy/dt.
    """
    p, f, g, h, k, L, m = y[0], y[1], y[2], y[3], y[4], y[5], y[6]
    F = thrust / (1000.0 * m)
    aR = F * ur
    aT = F * ut
    aN = F * un
    cl = np.cos(L)
    sl = np.sin(L)
    w = 1.0 + f * cl + g * sl
    s2 = 1.0 + h * h + k * k
    sig = h * sl - k * cl
    psi = np.sqrt(p / MU)
    out[0] = 2.0 * p * psi / w * aT
    out[1] = psi * sl * aR + psi * ((w + 1.0) * cl + f) / w * aT - psi * g * sig / w * aN
    out[2] = -psi * cl * aR + psi * ((w + 1.0) * sl + g) / w * aT + psi * f * sig / w * aN
    out[3] = psi * s2 * cl / (2.0 * w) * aN
    out[4] = psi * s2 * sl / (2.0 * w) * aN
    out[5] = np.sqrt(MU * p) * (w / p) ** 2 + psi * sig / w * aN
    out[6] = -mdot if thrust > 0.0 else 0.0


@njit(cache=True)
def rk4_step(y, dt, nsub, ur, ut, un, thrust, mdot, k1, k2, k3, k4, tmp):
    """Advance ``y`` in place over ``dt`` s with ``nsub`` RK4 substeps and the control held."""
    h = dt / nsub
    n = y.shape[0]
    for _ in range(nsub):
        mee_rhs(y, ur, ut, un, thrust, mdot, k1)
        for j in range(n):
            tmp[j] = y[j] + 0.5 * h * k1[j]
        mee_rhs(tmp, ur, ut, un, thrust, mdot, k2)
        for j in range(n):
            tmp[j] = y[j] + 0.5 * h * k2[j]
        mee_rhs(tmp, ur, ut, un, thrust, mdot, k3)
        for j in range(n):
            tmp[j] = y[j] + h * k3[j]
        mee_rhs(tmp, ur, ut, un, thrust, mdot, k4)
        for j in range(n):
            y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])


@njit(cache=True)
def gauss_matrix(a, e, inc, argp, nu, B):
    """Keplerian Gauss matrix per unit acceleration (km/s² → element rates).

    Rows (a, e, i, Ω, ω); columns (radial, transverse, normal). ``e`` and ``inc`` must already
    be floored by the caller (singular at e = 0 and sin i = 0). Fills ``B`` (5, 3).
    """
    p = a * (1.0 - e * e)
    hh = np.sqrt(MU * p)
    cn = np.cos(nu)
    sn = np.sin(nu)
    r = p / (1.0 + e * cn)
    u = argp + nu
    cu = np.cos(u)
    su = np.sin(u)
    si = np.sin(inc)
    ci = np.cos(inc)
    B[0, 0] = 2.0 * a * a / hh * e * sn
    B[0, 1] = 2.0 * a * a / hh * p / r
    B[0, 2] = 0.0
    B[1, 0] = p * sn / hh
    B[1, 1] = ((p + r) * cn + r * e) / hh
    B[1, 2] = 0.0
    B[2, 0] = 0.0
    B[2, 1] = 0.0
    B[2, 2] = r * cu / hh
    B[3, 0] = 0.0
    B[3, 1] = 0.0
    B[3, 2] = r * su / (hh * si)
    B[4, 0] = -p * cn / (e * hh)
    B[4, 1] = (p + r) * sn / (e * hh)
    B[4, 2] = -r * su * ci / (hh * si)


@njit(cache=True)
def element_errors(oe6, oeT, out):
    """Signed errors (a − a_T, e − e_T, wrapped angle errors) into ``out`` (5,)."""
    out[0] = oe6[0] - oeT[0]
    out[1] = oe6[1] - oeT[1]
    for j in range(2, 5):
        out[j] = wrap_angle(oe6[j] - oeT[j])
