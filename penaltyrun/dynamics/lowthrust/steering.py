"""Steering laws: thrust direction, generic Lyapunov law and min-fuel effectivity.

Both laws give û = −Bᵀ∇Q/‖Bᵀ∇Q‖ with B the Keplerian Gauss matrix at the floored e and i.
Bᵀ∇Q is formed directly (:func:`bt_grad`) without filling B. The min-fuel effectivity needs
the extremes of ‖Bᵀ∇Q‖ over true anomaly on the osculating orbit (:func:`effectivity_extremes`):
a grid of ``ngrid`` points (sines and cosines by rotation, no trigonometric call) refined by a
safeguarded regula falsi on the analytic derivative of ‖Bᵀ∇Q‖², one sine/cosine pair per
refinement evaluation.

:func:`law_eval_m` is the propagation loop's entry (selector matrix hoisted, no allocation);
:func:`law_eval` is the convenience form taking ``K`` (tests, references).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.lowthrust.elements import wrap_angle
from penaltyrun.dynamics.lowthrust.qlaw import N_WORK, qlaw_grad, selector_matrix
from penaltyrun.dynamics.lowthrust.qlaw_complex import (
    effectivity_extremes_golden,
    qlaw_gradient_cs,
)
from penaltyrun.dynamics.lowthrust.settings import (
    COAST_ETA_A,
    COAST_NONE,
    GRAD_COMPLEX,
    I_COAST,
    I_EFLOOR,
    I_ETACUT,
    I_GRAD,
    I_IFLOOR,
    I_LAW,
    I_NGRID,
    I_SIDES,
    LAW_QLAW,
    MU,
    TWO_PI,
)


@njit(cache=True)
def generic_grad(oe, oeT, M, grad):
    """Generic law V = ½ (W D)ᵀ M (W D) and ∇V with a hoisted selector matrix ``M`` (5, 5).

    W = diag(1/a_T, 1, 1, 1, 1); angle errors wrapped to (−π, π]. Fills ``grad``, returns V.
    """
    w0 = (oe[0] - oeT[0]) / oeT[0]
    w1 = oe[1] - oeT[1]
    w2 = wrap_angle(oe[2] - oeT[2])
    w3 = wrap_angle(oe[3] - oeT[3])
    w4 = wrap_angle(oe[4] - oeT[4])
    v = 0.0
    for j in range(5):
        gj = 0.0
        for m in range(5):
            wm = w0 if m == 0 else w1 if m == 1 else w2 if m == 2 else w3 if m == 3 else w4
            gj += 0.5 * (M[j, m] + M[m, j]) * wm
        wj = w0 if j == 0 else w1 if j == 1 else w2 if j == 2 else w3 if j == 3 else w4
        v += 0.5 * wj * gj
        grad[j] = gj
    grad[0] /= oeT[0]
    return v


@njit(cache=True)
def generic_gradient(oe, oeT, sel, K, prm, grad):
    """Generic law V = ½ (S W D)ᵀ K (S W D) (or one-sided) and ∇V; fills ``grad``, returns V.

    W = diag(1/a_T, 1, 1, 1, 1); angle errors wrapped to (−π, π]. Convenience form of
    :func:`generic_grad` (builds the selector matrix).
    """
    M = np.empty((5, 5))
    selector_matrix(sel, K, prm[I_SIDES] > 1.5, M)
    return generic_grad(oe, oeT, M, grad)


@njit(cache=True)
def bt_grad(a, e, inc, argp, nu, grad):
    """Bᵀ∇Q (radial, transverse, normal) at true anomaly ``nu``; ``e``, ``inc`` floored.

    Rows of B whose gradient component is zero are skipped.
    """
    p = a * (1.0 - e * e)
    hh = np.sqrt(MU * p)
    cn = np.cos(nu)
    sn = np.sin(nu)
    opc = 1.0 + e * cn
    r = p / opc
    d0 = 0.0
    d1 = 0.0
    d2 = 0.0
    if grad[0] != 0.0:
        c = 2.0 * a * a / hh * grad[0]
        d0 += c * e * sn
        d1 += c * opc
    if grad[1] != 0.0:
        d0 += p * sn / hh * grad[1]
        d1 += ((p + r) * cn + r * e) / hh * grad[1]
    if grad[2] != 0.0 or grad[3] != 0.0 or grad[4] != 0.0:
        cu = np.cos(argp + nu)
        su = np.sin(argp + nu)
        si = np.sin(inc)
        ci = np.cos(inc)
        d2 += r * cu / hh * grad[2] + r * su / (hh * si) * (grad[3] - ci * grad[4])
        if grad[4] != 0.0:
            d0 -= p * cn / (e * hh) * grad[4]
            d1 += (p + r) * sn / (e * hh) * grad[4]
    return d0, d1, d2


@njit(cache=True)
def _fnorm2(cn, sn, p, e, c_a, c_e, c_w, n_c, n_s):
    """h²‖Bᵀ∇Q‖²(ν) and its derivative d/dν from cos ν, sin ν (see effectivity_extremes)."""
    opc = 1.0 + e * cn
    r = p / opc
    dr = r * r * e * sn / p
    xr = (c_a * e + p * c_e) * sn - p * c_w * cn
    dxr = (c_a * e + p * c_e) * cn + p * c_w * sn
    xt = c_a * opc + c_e * ((p + r) * cn + r * e) + c_w * (p + r) * sn
    dxt = (-c_a * e * sn + c_e * (dr * cn - (p + r) * sn + dr * e)
           + c_w * (dr * sn + (p + r) * cn))
    nn = n_c * cn + n_s * sn
    xn = r * nn
    dxn = dr * nn + r * (n_s * cn - n_c * sn)
    return xr * xr + xt * xt + xn * xn, 2.0 * (xr * dxr + xt * dxt + xn * dxn)


@njit(cache=True)
def _falsi(lo, glo, hi, ghi, sign, p, e, c_a, c_e, c_w, n_c, n_s):
    """Regula falsi (Illinois) for the zero of sign·f′ in [lo, hi] (+ at lo, − at hi).

    Returns the best sign·f seen.
    """
    best = -np.inf
    side = 0
    for _ in range(60):
        x = (lo * ghi - hi * glo) / (ghi - glo)
        fx, gx = _fnorm2(np.cos(x), np.sin(x), p, e, c_a, c_e, c_w, n_c, n_s)
        best = max(best, sign * fx)
        gx *= sign
        if gx > 0.0:
            lo = x
            glo = gx
            if side == -1:
                ghi *= 0.5
            side = -1
        elif gx < 0.0:
            hi = x
            ghi = gx
            if side == 1:
                glo *= 0.5
            side = 1
        else:
            break
        if hi - lo <= 1e-11:
            break
    return best


@njit(cache=True)
def _refine(nu_j, f_j, g_j, dnu, sign, p, e, c_a, c_e, c_w, n_c, n_s):
    """Extreme (``sign`` = 1: max, −1: min) of f = h²‖Bᵀ∇Q‖² near the grid point ν_j.

    Brackets a zero of sign·f′ going from + to − on the side of ν_j where sign·f increases,
    then refines it by regula falsi. When that side holds no such bracket (several shallow
    extremes between grid points), the two neighbouring intervals are scanned on a 16-point
    subgrid around the best point and the search repeats there (twice at most).
    """
    best = sign * f_j
    c = nu_j
    gc = sign * g_j
    w = dnu
    for _level in range(3):
        if gc > 0.0:
            lo = c
            glo = gc
            hi = c + w
            f_hi, g_hi = _fnorm2(np.cos(hi), np.sin(hi), p, e, c_a, c_e, c_w, n_c, n_s)
            best = max(best, sign * f_hi)
            ghi = sign * g_hi
        else:
            hi = c
            ghi = gc
            lo = c - w
            f_lo, g_lo = _fnorm2(np.cos(lo), np.sin(lo), p, e, c_a, c_e, c_w, n_c, n_s)
            best = max(best, sign * f_lo)
            glo = sign * g_lo
        if glo > 0.0 and ghi < 0.0:
            return sign * max(best, _falsi(lo, glo, hi, ghi, sign, p, e, c_a, c_e, c_w, n_c,
                                           n_s))
        w_sub = w / 8.0
        c0 = c
        for k in range(-8, 9):
            x = c0 + k * w_sub
            fx, gx = _fnorm2(np.cos(x), np.sin(x), p, e, c_a, c_e, c_w, n_c, n_s)
            if sign * fx > best:
                best = sign * fx
                c = x
                gc = sign * gx
        w = w_sub
    return sign * best


@njit(cache=True)
def effectivity_extremes(a, e, inc, argp, grad, ngrid, B):
    """max and min over true anomaly of ‖Bᵀ∇Q‖ (grid of ``ngrid`` points + refinement).

    ``e`` and ``inc`` floored by the caller; ``B`` is unused (kept for the reference's
    signature). Q̇_nn = −F·max and Q̇_nx = −F·min. The extremes agree with the golden-section
    reference (:func:`~penaltyrun.dynamics.lowthrust.qlaw_complex.effectivity_extremes_golden`)
    to ≈ 1e-12 relative with about half the evaluations, each without the Gauss matrix.
    """
    p = a * (1.0 - e * e)
    hh = np.sqrt(MU * p)
    c_a = 2.0 * a * a * grad[0]
    c_e = grad[1]
    c_w = grad[4] / e
    si = np.sin(inc)
    ci = np.cos(inc)
    cw = np.cos(argp)
    sw = np.sin(argp)
    g_s = (grad[3] - grad[4] * ci) / si
    n_c = grad[2] * cw + g_s * sw
    n_s = g_s * cw - grad[2] * sw
    dnu = TWO_PI / ngrid
    cd = np.cos(dnu)
    sd = np.sin(dnu)
    cn = 1.0
    sn = 0.0
    jmax = 0
    jmin = 0
    fmax = -1.0
    fmin = np.inf
    gmx = 0.0
    gmn = 0.0
    for j in range(ngrid):
        fv, gv = _fnorm2(cn, sn, p, e, c_a, c_e, c_w, n_c, n_s)
        if fv > fmax:
            fmax = fv
            gmx = gv
            jmax = j
        if fv < fmin:
            fmin = fv
            gmn = gv
            jmin = j
        cn, sn = cn * cd - sn * sd, sn * cd + cn * sd
    fmax = _refine(jmax * dnu, fmax, gmx, dnu, 1.0, p, e, c_a, c_e, c_w, n_c, n_s)
    fmin = _refine(jmin * dnu, fmin, gmn, dnu, -1.0, p, e, c_a, c_e, c_w, n_c, n_s)
    return np.sqrt(fmax) / hh, np.sqrt(max(fmin, 0.0)) / hh


@njit(cache=True)
def law_eval_m(oe6, F, oeT, sel, K, M, prm, grad, B, work):
    """Evaluate the feedback law at Keplerian elements ``oe6`` = (a, e, i, Ω, ω, ν).

    Parameters
    ----------
    oe6 : ndarray, shape (6,)
        Osculating elements (a km, e, i, Ω, ω, ν rad).
    F : float
        Thrust acceleration, km/s².
    oeT, sel : ndarray, shape (5,)
        Target elements and binary selector.
    K, M : ndarray, shape (5, 5)
        Penalty matrix and its selector matrix (:func:`~.qlaw.selector_matrix`).
    prm : ndarray, shape (N_PRM,)
        Kernel settings (``prm[I_GRAD] = GRAD_COMPLEX`` selects the complex-step reference law).
    grad : ndarray, shape (5,)
        Receives ∇Q (or ∇V).
    B : ndarray, shape (5, 3)
        Scratch for the reference law.
    work : ndarray, shape (≥ N_WORK,)
        Scratch for the analytic Q-law.

    Returns
    -------
    ur, ut, un : float
        Unit thrust direction (radial, transverse, normal) −Bᵀ∇Q/‖Bᵀ∇Q‖ (zeros if undefined).
    on : bool
        Thrust flag (False when coasting by effectivity or when the direction is undefined).
    q : float
        Q (Q-law) or V (generic law).
    eta : float
        Effectivity (1 when coasting is disabled).
    """
    reference = prm[I_GRAD] == GRAD_COMPLEX
    if prm[I_LAW] == LAW_QLAW:
        if reference:
            q = qlaw_gradient_cs(oe6[:5], F, oeT, sel, K, prm, grad)
        else:
            q = qlaw_grad(oe6, F, oeT, sel, M, prm, work, grad)
    else:
        q = generic_grad(oe6, oeT, M, grad)
    ef = max(oe6[1], prm[I_EFLOOR])
    ifl = min(max(oe6[2], prm[I_IFLOOR]), np.pi - prm[I_IFLOOR])
    a = oe6[0]
    argp = oe6[4]
    d0, d1, d2 = bt_grad(a, ef, ifl, argp, oe6[5], grad)
    nrm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if not (nrm > 0.0) or not np.isfinite(nrm):
        return 0.0, 0.0, 0.0, False, q, 0.0
    eta = 1.0
    mode = int(prm[I_COAST])
    if mode != COAST_NONE:
        if reference:
            gmax, gmin = effectivity_extremes_golden(a, ef, ifl, argp, grad, int(prm[I_NGRID]),
                                                     B)
        else:
            gmax, gmin = effectivity_extremes(a, ef, ifl, argp, grad, int(prm[I_NGRID]), B)
        gmax = max(gmax, nrm)
        gmin = min(gmin, nrm)
        if mode == COAST_ETA_A:
            eta = nrm / gmax
        elif gmax > gmin:
            eta = (nrm - gmin) / (gmax - gmin)
    on = eta >= prm[I_ETACUT] or mode == COAST_NONE
    return -d0 / nrm, -d1 / nrm, -d2 / nrm, on, q, eta


@njit(cache=True)
def law_eval(oe6, F, oeT, sel, K, prm, grad, B):
    """:func:`law_eval_m` building the selector matrix and work array (allocates)."""
    M = np.empty((5, 5))
    selector_matrix(sel, K, prm[I_SIDES] > 1.5, M)
    work = np.empty(N_WORK)
    return law_eval_m(oe6, F, oeT, sel, K, M, prm, grad, B, work)
