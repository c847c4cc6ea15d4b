"""Q-law proximity quotient and its gradient in one real-valued pass (production kernel).

Q = (1 + W_p P) · ndᵀ M nd with nd_j = √S_j · D_j / œ̇_xx,j (paper Eq. 30), where the selector
matrix M = S K S (``sides = 2``) or S K (``sides = 1``) is built once per transfer
(:func:`selector_matrix`). The gradient w.r.t. the slow elements (a, e, i, Ω, ω) is derived
analytically (chain rule through the maximum rates, S_a, the ω̇_xx cube roots and the
periapsis/apoapsis penalty); with the two-sided selector the rates of untargeted elements are
not computed. No allocation: the caller passes the work arrays. The complex-step version in
:mod:`penaltyrun.dynamics.lowthrust.qlaw_complex` is the test reference (agreement ≈ 1e-12).

Floors as in the reference: e and i are floored inside the rates (zero derivative below the
floor, i also capped at π − floor); the errors D and the penalty use the unfloored elements.
"""

from __future__ import annotations

import numpy as np
from numba import njit

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

N_WORK = 30
"""Length of the work array of :func:`qlaw_grad` (nd (5) + Jacobian of nd (5×5))."""


@njit(cache=True)
def _wrap(x):
    """Wrap to (−π, π] by a multiple of 2π (same branch as the reference's complex wrap)."""
    return x - TWO_PI * np.floor((x + np.pi) / TWO_PI)


@njit(cache=True)
def selector_matrix(sel, K, two_sided, M):
    """M_jl = sel_j K_jl sel_l (two-sided) or sel_j K_jl (one-sided); fills ``M`` (5, 5)."""
    for j in range(5):
        for m in range(5):
            right = sel[m] if two_sided else 1.0
            M[j, m] = sel[j] * K[j, m] * right


@njit(cache=True)
def qlaw_grad(oe, F, oeT, sel, M, prm, work, grad):
    """Q and ∇Q w.r.t. (a, e, i, Ω, ω) in one pass; fills ``grad`` (5,), returns Q.

    Parameters
    ----------
    oe : ndarray, shape (≥5,)
        Slow elements (a km, e, i, Ω, ω rad).
    F : float
        Thrust acceleration, km/s².
    oeT : ndarray, shape (5,)
        Target slow elements.
    sel : ndarray, shape (5,)
        Binary selector.
    M : ndarray, shape (5, 5)
        Selector matrix from :func:`selector_matrix`.
    prm : ndarray, shape (N_PRM,)
        Kernel settings.
    work : ndarray, shape (≥ N_WORK,)
        Scratch space.
    grad : ndarray, shape (5,)
        Receives ∂Q/∂(a km, e, i, Ω, ω).
    """
    two = prm[I_SIDES] > 1.5
    a = oe[0]
    e = oe[1]
    inc = oe[2]
    argp = oe[4]
    for j in range(N_WORK):
        work[j] = 0.0
    # work[0:5] = nd, work[5 + 5 j + k] = ∂nd_j/∂x_k
    need_a = sel[0] != 0.0 or not two
    need_e = sel[1] != 0.0 or not two
    need_i = sel[2] != 0.0 or not two
    need_o = sel[3] != 0.0 or not two
    need_w = sel[4] != 0.0 or not two
    efl = prm[I_EFLOOR]
    if e >= efl:
        ef = e
        de = 1.0
    else:
        ef = efl
        de = 0.0
    ifl = prm[I_IFLOOR]
    if inc >= ifl:
        ii = inc
        di = 1.0
    else:
        ii = ifl
        di = 0.0
    if ii > np.pi - ifl:
        ii = np.pi - ifl
        di = 0.0
    e2 = ef * ef
    ome2 = 1.0 - e2
    p = a * ome2
    sp = np.sqrt(p / MU)  # p / h
    half_a = 0.5 / a
    dlp_e = -ef / ome2 * de  # ½ ∂ln p/∂e (the h-scaled rates go like √p)
    if need_a:
        adot = 2.0 * F * np.sqrt(a * a * a * (1.0 + ef) / (MU * (1.0 - ef)))
        aT = oeT[0]
        da = a - aT
        x = abs(da / (prm[I_MS] * aT))
        sa = 1.0
        dsa = 0.0  # ½ (a − a_T) ∂ln S_a/∂a
        if x > 0.0:
            xn = np.exp(prm[I_N] * np.log(x))
            sa = np.exp(np.log(1.0 + xn) / prm[I_R])
            dsa = 0.5 * prm[I_N] * xn / (prm[I_R] * (1.0 + xn))
        rs = np.sqrt(sa) / adot
        nd = rs * da
        work[0] = nd
        work[5] = rs * (1.0 + dsa) - nd * 3.0 * half_a
        work[6] = -nd * de / ome2
    if need_e:
        edot = 2.0 * F * sp
        nd = (e - oeT[1]) / edot
        work[1] = nd
        work[10] = -nd * half_a
        work[11] = 1.0 / edot - nd * dlp_e
    sw = np.sin(argp)
    cw = np.cos(argp)
    if need_i:
        s1 = np.sqrt(1.0 - e2 * sw * sw)
        sgc = 1.0 if cw >= 0.0 else -1.0
        di_ = s1 - ef * abs(cw)
        idot = F * sp / di_
        dd_e = -ef * sw * sw / s1 - abs(cw)
        dd_w = -e2 * sw * cw / s1 + ef * sgc * sw
        nd = _wrap(inc - oeT[2]) / idot
        work[2] = nd
        work[15] = -nd * half_a
        work[16] = -nd * (dlp_e - dd_e / di_ * de)
        work[17] = 1.0 / idot
        work[19] = nd * dd_w / di_
    if need_o or need_w:
        si = np.sin(ii)
        ci = np.cos(ii)
        s2 = np.sqrt(1.0 - e2 * cw * cw)
        sgs = 1.0 if sw >= 0.0 else -1.0
        do_ = s2 - ef * abs(sw)
        odot = F * sp / (si * do_)
        lo_e = dlp_e - (-ef * cw * cw / s2 - abs(sw)) / do_ * de
        lo_i = -ci / si * di
        lo_w = -(e2 * cw * sw / s2 - ef * sgs * cw) / do_
        if need_o:
            nd = _wrap(oe[3] - oeT[3]) / odot
            work[3] = nd
            work[20] = -nd * half_a
            work[21] = -nd * lo_e
            work[22] = -nd * lo_i
            work[23] = 1.0 / odot
            work[24] = -nd * lo_w
        if need_w:
            # in-plane maximum: ω̇_xxi = F √(p/μ)/e · √Y, Y = c² + (1 + t)²(1 − c²),
            # t = 1/(1 + e c), c = cos θ from the cube roots (differentiated through).
            e3 = e2 * ef
            uu = ome2 / (2.0 * e3)
            vv = np.sqrt(uu * uu + 1.0 / 27.0)
            ss = uu + vv
            cr = np.cbrt(ss)
            c = cr - 1.0 / (3.0 * cr) - 1.0 / ef
            du = (e2 - 3.0) / (2.0 * e2 * e2)
            dss = du * (1.0 + uu / vv)
            dc = dss * (1.0 / (3.0 * cr * cr) + 1.0 / (9.0 * cr * cr * cr * cr)) + 1.0 / e2
            t = 1.0 / (1.0 + ef * c)
            w1 = 1.0 + t
            sth2 = 1.0 - c * c
            yy = c * c + w1 * w1 * sth2
            dt = -t * t * (c + ef * dc)
            dyy = 2.0 * c * dc * (1.0 - w1 * w1) + 2.0 * w1 * sth2 * dt
            wxxi = F * sp / ef * np.sqrt(yy)
            li_e = (dlp_e + (-1.0 / ef + 0.5 * dyy / yy) * de)
            aci = abs(ci)
            sgci = 1.0 if ci >= 0.0 else -1.0
            wxxo = odot * aci
            b = prm[I_B]
            wdot = (wxxi + b * wxxo) / (1.0 + b)
            dw_a = (wxxi * half_a + b * wxxo * half_a) / (1.0 + b)
            dw_e = (wxxi * li_e + b * wxxo * lo_e) / (1.0 + b)
            dw_i = b * (wxxo * lo_i - odot * sgci * si * di) / (1.0 + b)
            dw_w = b * wxxo * lo_w / (1.0 + b)
            nd = _wrap(argp - oeT[4]) / wdot
            rw = nd / wdot
            work[4] = nd
            work[25] = -rw * dw_a
            work[26] = -rw * dw_e
            work[27] = -rw * dw_i
            work[29] = 1.0 / wdot - rw * dw_w
    quad = 0.0
    for k in range(5):
        grad[k] = 0.0
    for j in range(5):
        gj = 0.0
        for m in range(5):
            gj += (M[j, m] + M[m, j]) * work[m]
            quad += work[j] * M[j, m] * work[m]
        if gj != 0.0:
            for k in range(5):
                grad[k] += gj * work[5 + 5 * j + k]
    rpmin = prm[I_RPMIN]
    kp = prm[I_KP]
    pen = np.exp(kp * (1.0 - a * (1.0 - e) / rpmin))
    dpen_a = -pen * kp * (1.0 - e) / rpmin
    dpen_e = pen * kp * a / rpmin
    acap = prm[I_ACAP]
    if acap > 0.0:
        pen2 = np.exp(kp * (a / acap - 1.0))
        pen += pen2
        dpen_a += pen2 * kp / acap
    wp = prm[I_WP]
    fac = 1.0 + wp * pen
    for k in range(5):
        grad[k] *= fac
    grad[0] += wp * dpen_a * quad
    grad[1] += wp * dpen_e * quad
    return fac * quad


@njit(cache=True)
def qlaw_gradient(oe, F, oeT, sel, K, prm, grad):
    """Q and ∇Q (analytic) from ``K`` directly; fills ``grad`` (5,), returns Q.

    Convenience form of :func:`qlaw_grad` that builds the selector matrix and the work array
    (it allocates; the propagation loop calls :func:`qlaw_grad` with hoisted ones).
    """
    M = np.empty((5, 5))
    selector_matrix(sel, K, prm[I_SIDES] > 1.5, M)
    work = np.empty(N_WORK)
    return qlaw_grad(oe, F, oeT, sel, M, prm, work, grad)
