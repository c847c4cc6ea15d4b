"""Complex-step reference of the Q-law: the test and benchmark reference of the production law.

This is the original kernel's law, kept verbatim: Q evaluated in complex arithmetic
(:func:`qlaw_value`), its gradient by five complex-step evaluations (:func:`qlaw_gradient_cs`,
exact to round-off, including the dependence of the maximum rates, of S_a and of the penalty on
the elements), and the min-fuel effectivity extremes by a true-anomaly grid plus golden-section
refinement (:func:`effectivity_extremes_golden`). It allocates and is several times slower than
:mod:`penaltyrun.dynamics.lowthrust.qlaw`; ``prm[I_GRAD] = GRAD_COMPLEX`` selects it in
:func:`penaltyrun.dynamics.lowthrust.propagate`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.lowthrust.elements import gauss_matrix
from penaltyrun.dynamics.lowthrust.settings import (
    I_ACAP,
    I_B,
    I_EFLOOR,
    I_IFLOOR,
    I_KP,
    I_MS,
    I_N,
    I_R,
    I_RPMIN,
    I_SIDES,
    I_WP,
    MU,
    TWO_PI,
)

CS_STEP = 1e-30
"""Complex-step size (relative to 1 in each element's unit)."""


@njit(cache=True)
def _cabs(z):
    """|z| continued analytically from the real axis (sign of the real part)."""
    return z if z.real >= 0.0 else -z


@njit(cache=True)
def _cwrap(z):
    """Angle wrap to (−π, π] keeping the (unit) derivative: shift by a real multiple of 2π."""
    return z - TWO_PI * np.floor((z.real + np.pi) / TWO_PI)


@njit(cache=True)
def _cfloor(z, lo):
    """max(z, lo) on the real part (derivative 0 below the floor)."""
    return z if z.real >= lo else lo + 0.0j


@njit(cache=True)
def max_rates(a, e, inc, argp, F, prm):
    """Maximum element rates over thrust direction and true anomaly (Petropoulos).

    Complex-valued (for the complex-step gradient); ``e`` and ``inc`` are floored here.

    Returns
    -------
    (ȧ_xx, ė_xx, i̇_xx, Ω̇_xx, ω̇_xx) : complex
        km/s, 1/s, rad/s, rad/s, rad/s.
    """
    ef = _cfloor(e, prm[I_EFLOOR])
    ifl = _cfloor(inc, prm[I_IFLOOR])
    if ifl.real > np.pi - prm[I_IFLOOR]:
        ifl = np.pi - prm[I_IFLOOR] + 0.0j
    p = a * (1.0 - ef * ef)
    hh = np.sqrt(MU * p)
    adot = 2.0 * F * np.sqrt(a * a * a * (1.0 + ef) / (MU * (1.0 - ef)))
    edot = 2.0 * p * F / hh
    sw = np.sin(argp)
    cw = np.cos(argp)
    idot = p * F / (hh * (np.sqrt(1.0 - ef * ef * sw * sw) - ef * _cabs(cw)))
    odot = p * F / (hh * np.sin(ifl) * (np.sqrt(1.0 - ef * ef * cw * cw) - ef * _cabs(sw)))
    e3 = ef * ef * ef
    uu = (1.0 - ef * ef) / (2.0 * e3)
    q = (1.0 - ef * ef) / e3
    vv = np.sqrt(0.25 * q * q + 1.0 / 27.0)
    vmu = (1.0 / 27.0) / (uu + vv)
    cth = np.exp(np.log(uu + vv) / 3.0) - np.exp(np.log(vmu) / 3.0) - 1.0 / ef
    sth2 = 1.0 - cth * cth
    rr = p / (1.0 + ef * cth)
    wxxi = F / (ef * hh) * np.sqrt(p * p * cth * cth + (p + rr) * (p + rr) * sth2)
    wxxo = odot * _cabs(np.cos(ifl))
    b = prm[I_B]
    wdot = (wxxi + b * wxxo) / (1.0 + b)
    return adot, edot, idot, odot, wdot


@njit(cache=True)
def qlaw_value(oe, F, oeT, sel, K, prm):
    """Q-law proximity quotient Q (paper Eq. 30) at complex slow elements ``oe`` (5,).

    Q = (1 + W_p P) (S N D)ᵀ K (S N D) (``sides = 2``) or (S N D)ᵀ K (N D) (``sides = 1``),
    N = diag(√S_œ / œ̇_xx), S_a = [1 + |(a − a_T)/(m_s a_T)|^n]^(1/r),
    P = exp[k_p (1 − r_p/r_p,min)] (+ exp[k_p (a/a_cap − 1)] when a_cap > 0).
    """
    a = oe[0]
    e = oe[1]
    rates = max_rates(a, e, oe[2], oe[4], F, prm)
    aT = oeT[0]
    x = _cabs((a - aT) / (prm[I_MS] * aT))
    if x.real > 0.0:
        sa = np.exp(np.log(1.0 + np.exp(prm[I_N] * np.log(x))) / prm[I_R])
    else:
        sa = 1.0 + 0.0j
    nd = np.empty(5, dtype=np.complex128)
    nd[0] = np.sqrt(sa) / rates[0] * (a - aT)
    nd[1] = (e - oeT[1]) / rates[1]
    nd[2] = _cwrap(oe[2] - oeT[2]) / rates[2]
    nd[3] = _cwrap(oe[3] - oeT[3]) / rates[3]
    nd[4] = _cwrap(oe[4] - oeT[4]) / rates[4]
    two_sided = prm[I_SIDES] > 1.5
    quad = 0.0j
    for j in range(5):
        if sel[j] == 0.0:
            continue
        acc = 0.0j
        for l in range(5):
            if two_sided and sel[l] == 0.0:
                continue
            acc += K[j, l] * nd[l]
        quad += nd[j] * acc
    rp = a * (1.0 - e)
    pen = np.exp(prm[I_KP] * (1.0 - rp / prm[I_RPMIN]))
    if prm[I_ACAP] > 0.0:
        pen += np.exp(prm[I_KP] * (a / prm[I_ACAP] - 1.0))
    return (1.0 + prm[I_WP] * pen) * quad


@njit(cache=True)
def qlaw_gradient_cs(oe, F, oeT, sel, K, prm, grad):
    """Q and ∇Q w.r.t. (a, e, i, Ω, ω) by complex step; fills ``grad`` (5,), returns Q."""
    z = np.empty(5, dtype=np.complex128)
    q0 = 0.0
    for j in range(5):
        for l in range(5):
            z[l] = oe[l] + 0.0j
        z[j] += 1j * CS_STEP
        qc = qlaw_value(z, F, oeT, sel, K, prm)
        grad[j] = qc.imag / CS_STEP
        q0 = qc.real
    return q0


@njit(cache=True)
def _gnorm(a, e, inc, argp, nu, grad, B):
    """‖Bᵀ∇Q‖ at true anomaly ``nu`` (floored ``e``, ``inc``)."""
    gauss_matrix(a, e, inc, argp, nu, B)
    s = 0.0
    for c in range(3):
        acc = 0.0
        for j in range(5):
            acc += B[j, c] * grad[j]
        s += acc * acc
    return np.sqrt(s)


@njit(cache=True)
def _golden(a, e, inc, argp, grad, B, lo, hi, sign):
    """Golden-section search of ``sign``·‖Bᵀ∇Q‖(ν) on [lo, hi]; returns the extreme value."""
    gr = 0.5 * (np.sqrt(5.0) - 1.0)
    c = hi - gr * (hi - lo)
    d = lo + gr * (hi - lo)
    fc = sign * _gnorm(a, e, inc, argp, c, grad, B)
    fd = sign * _gnorm(a, e, inc, argp, d, grad, B)
    for _ in range(24):
        if fc > fd:
            hi = d
            d = c
            fd = fc
            c = hi - gr * (hi - lo)
            fc = sign * _gnorm(a, e, inc, argp, c, grad, B)
        else:
            lo = c
            c = d
            fc = fd
            d = lo + gr * (hi - lo)
            fd = sign * _gnorm(a, e, inc, argp, d, grad, B)
    return sign * max(fc, fd)


@njit(cache=True)
def effectivity_extremes_golden(a, e, inc, argp, grad, ngrid, B):
    """max and min over true anomaly of ‖Bᵀ∇Q‖ (grid of ``ngrid`` points + golden refinement).

    Q̇_nn = −F·max and Q̇_nx = −F·min.
    """
    dnu = TWO_PI / ngrid
    jmax = 0
    jmin = 0
    gmax = -1.0
    gmin = np.inf
    for j in range(ngrid):
        gval = _gnorm(a, e, inc, argp, j * dnu, grad, B)
        if gval > gmax:
            gmax = gval
            jmax = j
        if gval < gmin:
            gmin = gval
            jmin = j
    gmax = max(gmax, _golden(a, e, inc, argp, grad, B, (jmax - 1) * dnu, (jmax + 1) * dnu, 1.0))
    gmin = min(gmin, _golden(a, e, inc, argp, grad, B, (jmin - 1) * dnu, (jmin + 1) * dnu, -1.0))
    return gmax, gmin
