"""Compiled plant of the rendezvous MPC's model-mismatch scenarios: nonlinear relative motion
of a chaser about a target on a Keplerian (possibly eccentric) orbit, in the target's LVLH
frame (x radial outward, y along-track, z orbit normal), SI units (m, s).

State ``y = (x, y, z, ẋ, ẏ, ż, r, ṙ, θ̇)`` (relative position m, velocity m/s, target radius
m, radial rate m/s, argument-of-latitude rate rad/s); input a = commanded acceleration in
LVLH (m/s²), held constant over one sample (zero-order hold):

    r̈ = r θ̇² − μ / r²,   θ̈ = −2 ṙ θ̇ / r,   r_c = ‖(r + x, y, z)‖,
    ẍ = 2θ̇ẏ + θ̈y + θ̇²x + μ/r² − μ(r + x)/r_c³ + a_x,
    ÿ = −2θ̇ẋ − θ̈x + θ̇²y − μy/r_c³ + a_y,
    z̈ = −μz/r_c³ + a_z.

The difference μ/r² − μ(r + x)/r_c³ of two nearly equal accelerations is evaluated without
cancellation through q = (r_c² − r²)/r² and expm1 / log1p. Linearized about a circular
orbit these are the Clohessy–Wiltshire equations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def rhs(y, acc, mu, out):
    """Right-hand side dy/dt of the relative motion (see the module docstring)."""
    x, yy, z, vx, vy, vz, r, rdot, thdot = y[0], y[1], y[2], y[3], y[4], y[5], y[6], y[7], y[8]
    thddot = -2.0 * rdot * thdot / r
    q = (2.0 * r * x + x * x + yy * yy + z * z) / (r * r)
    e = math.expm1(1.5 * math.log1p(q))        # (r_c / r)³ − 1
    g = 1.0 + e
    mu_r2 = mu / (r * r)
    # μ/r² − μ(r + x)/r_c³ = μ/r² · ((r_c/r)³ − 1 − x/r) / (r_c/r)³
    radial = mu_r2 * (e - x / r) / g
    mu_rc3 = mu_r2 / (r * g)                   # μ / r_c³
    out[0] = vx
    out[1] = vy
    out[2] = vz
    out[3] = 2.0 * thdot * vy + thddot * yy + thdot * thdot * x + radial + acc[0]
    out[4] = -2.0 * thdot * vx - thddot * x + thdot * thdot * yy - mu_rc3 * yy + acc[1]
    out[5] = -mu_rc3 * z + acc[2]
    out[6] = rdot
    out[7] = r * thdot * thdot - mu_r2
    out[8] = thddot


@njit(cache=True)
def propagate(y, acc, dt, n_sub, mu):
    """State after ``dt`` seconds of constant LVLH acceleration ``acc`` (classical RK4).

    Parameters
    ----------
    y : ndarray, shape (9,)
        State (see the module docstring).
    acc : ndarray, shape (3,)
        Acceleration (m/s²), constant over the interval.
    dt : float
        Interval (s).
    n_sub : int
        RK4 steps in the interval (step dt / n_sub).
    mu : float
        Gravitational parameter (m³/s²).

    Returns
    -------
    ndarray, shape (9,)
    """
    h = dt / n_sub
    cur = y.copy()
    k1 = np.empty(9)
    k2 = np.empty(9)
    k3 = np.empty(9)
    k4 = np.empty(9)
    tmp = np.empty(9)
    for _ in range(n_sub):
        rhs(cur, acc, mu, k1)
        for i in range(9):
            tmp[i] = cur[i] + 0.5 * h * k1[i]
        rhs(tmp, acc, mu, k2)
        for i in range(9):
            tmp[i] = cur[i] + 0.5 * h * k2[i]
        rhs(tmp, acc, mu, k3)
        for i in range(9):
            tmp[i] = cur[i] + h * k3[i]
        rhs(tmp, acc, mu, k4)
        for i in range(9):
            cur[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    return cur
