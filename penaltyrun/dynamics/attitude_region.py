"""Compiled search of the first sampled state where a quadratic Lyapunov function of an
attitude feedback law stops decreasing.

With x = (q_v, ω) ∈ R⁶, q0 = +√(1 − |q_v|²), the closed loop u = −G x of the rigid body
(inertia I) is

    q̇_v = ½ (q0 ω + q_v × ω),   ω̇ = I⁻¹ (−ω × I ω + u),

and V(x) = xᵀ P x has V̇ = 2 xᵀ P ẋ. :func:`first_turn` evaluates V̇ at x = s_k d_j over
radii s_k (outer loop, increasing) and directions d_j (inner loop) and stops at the first
radius where some direction has V̇ ≥ 0: its index is the smallest radius at which any ray
turns, without evaluating the radii beyond it. The numpy implementation of the same V̇
(:func:`penaltyrun.problems.attitude.sublevel.vdot`) is its reference in the tests.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def first_turn(P, G, inertia, inertia_inv, directions, radii):
    """Index of the first radius at which some direction has V̇ ≥ 0, or −1 when none does.

    Parameters
    ----------
    P : ndarray, shape (6, 6)
        V(x) = xᵀ P x (symmetric).
    G : ndarray, shape (3, 6)
        Gain of u = −G x (N·m per unit of x).
    inertia, inertia_inv : ndarray, shape (3, 3)
        Inertia (kg·m²) and its inverse.
    directions : ndarray, shape (n, 6)
        Ray directions d.
    radii : ndarray, shape (k,)
        Increasing radii s; the states are x = s d with |q_v| ≤ 1.

    Returns
    -------
    int
        The smallest k with V̇(s_k d_j) ≥ 0 for some j, −1 when there is none.
    """
    x = np.empty(6)
    dx = np.empty(6)
    rhs = np.empty(3)
    for k in range(radii.size):
        s = radii[k]
        for j in range(directions.shape[0]):
            for i in range(6):
                x[i] = s * directions[j, i]
            q0 = np.sqrt(max(1.0 - (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), 0.0))
            w0, w1, w2 = x[3], x[4], x[5]
            dx[0] = 0.5 * (q0 * w0 + x[1] * w2 - x[2] * w1)
            dx[1] = 0.5 * (q0 * w1 + x[2] * w0 - x[0] * w2)
            dx[2] = 0.5 * (q0 * w2 + x[0] * w1 - x[1] * w0)
            iw0 = inertia[0, 0] * w0 + inertia[0, 1] * w1 + inertia[0, 2] * w2
            iw1 = inertia[1, 0] * w0 + inertia[1, 1] * w1 + inertia[1, 2] * w2
            iw2 = inertia[2, 0] * w0 + inertia[2, 1] * w1 + inertia[2, 2] * w2
            rhs[0] = -(w1 * iw2 - w2 * iw1)
            rhs[1] = -(w2 * iw0 - w0 * iw2)
            rhs[2] = -(w0 * iw1 - w1 * iw0)
            for a in range(3):
                u = 0.0
                for b in range(6):
                    u += G[a, b] * x[b]
                rhs[a] -= u
            for a in range(3):
                dx[3 + a] = (inertia_inv[a, 0] * rhs[0] + inertia_inv[a, 1] * rhs[1]
                             + inertia_inv[a, 2] * rhs[2])
            vdot = 0.0
            for a in range(6):
                px = 0.0
                for b in range(6):
                    px += P[a, b] * x[b]
                vdot += px * dx[a]
            if 2.0 * vdot >= 0.0:
                return k
    return -1
