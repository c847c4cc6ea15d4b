"""Compiled low-thrust transfer kernels: MEE dynamics, Q-law and generic Lyapunov law.

Everything here is a numba ``@njit(cache=True)`` function of floats and arrays.

Units: km, s, kg, N (thrust), s (Isp); angles in rad. Slow (Keplerian) elements are ordered
``(a, e, i, Ω, ω)``; modified equinoctial elements (MEE) ``(p, f, g, h, k, L)``; the propagated
state is ``y = (p, f, g, h, k, L, m)`` with time as the independent variable.

Propagation (:func:`propagate`): the control (thrust direction in the radial/transverse/normal
frame and the on/off flag) is computed at the start of each fixed control step ``dt`` and held
(zero-order hold); within the step the dynamics, including the mass flow and F = T/m, are
integrated with ``nsub`` classical RK4 substeps.

Both laws share the penalty machinery: ``K`` (5×5, SPD), a binary selector ``sel`` (targeted
elements) applied to both factors of the quadratic form (``sides = 2``) or to the left factor
only (``sides = 1``). Gradients of the Q-law with respect to the slow elements use the
complex-step derivative (exact to round-off, includes the dependence of the maximum rates, of
S_a and of the penalty P on the elements); the generic law's gradient is analytic.
"""

from __future__ import annotations

import numpy as np
from numba import njit

MU = 398600.4418
"""Earth's gravitational parameter, km³/s²."""
G0 = 9.80665
"""Standard gravity, m/s²."""
R_E = 6378.137
"""Earth's equatorial radius, km."""

TWO_PI = 2.0 * np.pi
CS_STEP = 1e-30
"""Complex-step size (relative to 1 in each element's unit)."""

# Indices into the float64 parameter vector ``prm`` (length N_PRM).
I_THRUST = 0  # thrust, N
I_ISP = 1  # specific impulse, s
I_DT = 2  # control step, s
I_NSUB = 3  # RK4 substeps per control step
I_TMAX = 4  # time-of-flight cap, s
I_REVMAX = 5  # revolution cap
I_MFLOOR = 6  # mass floor, kg
I_RPMIN = 7  # Q-law minimum periapsis radius, km
I_KP = 8  # Q-law penalty sharpness k_p
I_WP = 9  # Q-law penalty weight W_p
I_MS = 10  # S_a parameter m_s
I_N = 11  # S_a parameter n
I_R = 12  # S_a parameter r
I_B = 13  # ω̇_xx blending b
I_LAW = 14  # LAW_QLAW or LAW_GENERIC
I_SIDES = 15  # 2: selector on both factors, 1: left factor only
I_COAST = 16  # COAST_NONE, COAST_ETA_A, COAST_ETA_R
I_ETACUT = 17  # effectivity threshold η_cut
I_NGRID = 18  # true-anomaly grid points for the effectivity search
I_STALLREVS = 19  # stall window, revolutions (0 disables the check)
I_STALLREL = 20  # relative decrease of min(Q) required per window
I_MAXSTEPS = 21  # evaluation cap (control steps)
I_ACAP = 22  # semi-major-axis cap for the Q-law penalty, km (0 disables)
I_EFLOOR = 23  # eccentricity floor inside the law
I_IFLOOR = 24  # inclination floor inside the law, rad
I_RIMPACT = 25  # impact radius (periapsis floor), km
N_PRM = 26

LAW_QLAW = 0
LAW_GENERIC = 1
COAST_NONE = 0
COAST_ETA_A = 1
COAST_ETA_R = 2

ST_CONVERGED = 0
ST_TOF = 1
ST_REV = 2
ST_IMPACT = 3
ST_PROPELLANT = 4
ST_STALL = 5
ST_ESCAPE = 6
STATUS_NAMES = ("converged", "tof_cap", "rev_cap", "impact", "propellant", "stall", "escape")
"""Kernel status code → name."""

HIST_COLS = ("t", "a", "e", "i", "Omega", "omega", "mass", "thrust_on", "x", "y", "z", "Q")
"""Columns of the history array filled by :func:`propagate`."""
N_HIST = 12


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
def qlaw_gradient(oe, F, oeT, sel, K, prm, grad):
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
def generic_gradient(oe, oeT, sel, K, prm, grad):
    """Generic law V = ½ (S W D)ᵀ K (S W D) (or one-sided) and ∇V; fills ``grad``, returns V.

    W = diag(1/a_T, 1, 1, 1, 1); angle errors wrapped to (−π, π].
    """
    wd = np.empty(5)
    wd[0] = (oe[0] - oeT[0]) / oeT[0]
    wd[1] = oe[1] - oeT[1]
    for j in range(2, 5):
        wd[j] = wrap_angle(oe[j] - oeT[j])
    two_sided = prm[I_SIDES] > 1.5
    M = np.zeros((5, 5))
    for j in range(5):
        for l in range(5):
            right = sel[l] if two_sided else 1.0
            M[j, l] = sel[j] * K[j, l] * right
    v = 0.0
    for j in range(5):
        gj = 0.0
        for l in range(5):
            v += 0.5 * wd[j] * M[j, l] * wd[l]
            gj += 0.5 * (M[j, l] + M[l, j]) * wd[l]
        grad[j] = gj
    grad[0] /= oeT[0]
    return v


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
def effectivity_extremes(a, e, inc, argp, grad, ngrid, B):
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


@njit(cache=True)
def law_eval(oe6, F, oeT, sel, K, prm, grad, B):
    """Evaluate the feedback law at Keplerian elements ``oe6`` = (a, e, i, Ω, ω, ν).

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
    if prm[I_LAW] == LAW_QLAW:
        q = qlaw_gradient(oe6[:5], F, oeT, sel, K, prm, grad)
    else:
        q = generic_gradient(oe6[:5], oeT, sel, K, prm, grad)
    ef = max(oe6[1], prm[I_EFLOOR])
    ifl = min(max(oe6[2], prm[I_IFLOOR]), np.pi - prm[I_IFLOOR])
    a = oe6[0]
    argp = oe6[4]
    nu = oe6[5]
    gauss_matrix(a, ef, ifl, argp, nu, B)
    d0 = 0.0
    d1 = 0.0
    d2 = 0.0
    for j in range(5):
        d0 += B[j, 0] * grad[j]
        d1 += B[j, 1] * grad[j]
        d2 += B[j, 2] * grad[j]
    nrm = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if not (nrm > 0.0) or not np.isfinite(nrm):
        return 0.0, 0.0, 0.0, False, q, 0.0
    eta = 1.0
    mode = int(prm[I_COAST])
    if mode != COAST_NONE:
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
def element_errors(oe6, oeT, out):
    """Signed errors (a − a_T, e − e_T, wrapped angle errors) into ``out`` (5,)."""
    out[0] = oe6[0] - oeT[0]
    out[1] = oe6[1] - oeT[1]
    for j in range(2, 5):
        out[j] = wrap_angle(oe6[j] - oeT[j])


@njit(cache=True)
def propagate(oe0, m0, oeT, sel, tol, K, prm, hist, record_every):
    """Closed-loop transfer from ``oe0`` until convergence or a failure rule.

    Parameters
    ----------
    oe0 : ndarray, shape (6,)
        Initial Keplerian elements (a km, e, i, Ω, ω, ν rad).
    m0 : float
        Initial mass, kg.
    oeT : ndarray, shape (5,)
        Target slow elements (a km, e, i, Ω, ω rad); untargeted entries are ignored.
    sel : ndarray, shape (5,)
        Binary selector (1 = targeted).
    tol : ndarray, shape (5,)
        Convergence tolerances (km, -, rad, rad, rad) on targeted elements.
    K : ndarray, shape (5, 5)
        Penalty matrix (SPD).
    prm : ndarray, shape (N_PRM,)
        Settings, see the ``I_*`` indices.
    hist : ndarray, shape (n_rec, N_HIST)
        History buffer (columns :data:`HIST_COLS`); pass shape (0, N_HIST) to record nothing.
    record_every : int
        Record every this many control steps (plus the final state) while space remains.

    Returns
    -------
    status : int
        Status code (see :data:`STATUS_NAMES`).
    t : float
        Final time, s.
    y : ndarray, shape (7,)
        Final MEE state and mass.
    revs : float
        Revolutions (L_final − L_0)/2π.
    n_steps : int
        Control steps taken.
    n_rec : int
        Rows of ``hist`` filled.
    q : float
        Last Q (or V) evaluated.
    """
    y = np.empty(7)
    p, f, g, h, k, L = kep2mee(oe0[0], oe0[1], oe0[2], oe0[3], oe0[4], oe0[5])
    y[0] = p
    y[1] = f
    y[2] = g
    y[3] = h
    y[4] = k
    y[5] = L
    y[6] = m0
    L0 = L
    k1 = np.empty(7)
    k2 = np.empty(7)
    k3 = np.empty(7)
    k4 = np.empty(7)
    tmp = np.empty(7)
    grad = np.empty(5)
    B = np.empty((5, 3))
    oe = np.empty(6)
    err = np.empty(5)
    thrust = prm[I_THRUST]
    mdot = thrust / (G0 * prm[I_ISP])
    dt = prm[I_DT]
    nsub = max(1, int(prm[I_NSUB]))
    max_steps = int(prm[I_MAXSTEPS])
    win = prm[I_STALLREVS]
    n_hist = hist.shape[0]
    n_rec = 0
    t = 0.0
    step = 0
    q = np.inf
    q_best = np.inf
    q_ref = np.inf
    next_check = win
    status = -1
    while True:
        a, e, inc, raan, argp, nu = mee2kep(y[0], y[1], y[2], y[3], y[4], y[5])
        oe[0] = a
        oe[1] = e
        oe[2] = inc
        oe[3] = raan
        oe[4] = argp
        oe[5] = nu
        revs = (y[5] - L0) / TWO_PI
        element_errors(oe, oeT, err)
        done = True
        for j in range(5):
            if sel[j] != 0.0 and not abs(err[j]) <= tol[j]:
                done = False
        finite = True
        for j in range(7):
            if not np.isfinite(y[j]):
                finite = False
        if done:
            status = ST_CONVERGED
        elif not finite or not (e < 1.0) or not (a > 0.0):
            status = ST_ESCAPE
        elif a * (1.0 - e) < prm[I_RIMPACT]:
            status = ST_IMPACT
        elif y[6] <= prm[I_MFLOOR]:
            status = ST_PROPELLANT
        elif t >= prm[I_TMAX]:
            status = ST_TOF
        elif revs >= prm[I_REVMAX]:
            status = ST_REV
        elif step >= max_steps:
            status = ST_STALL
        on = False
        if status < 0:
            F = thrust / (1000.0 * y[6])
            if thrust > 0.0:
                ur, ut, un, on, q, _eta = law_eval(oe, F, oeT, sel, K, prm, grad, B)
            else:
                ur = ut = un = 0.0
            if q < q_best:
                q_best = q
            if q_ref == np.inf:
                q_ref = q_best
            if win > 0.0 and revs >= next_check:
                if not (q_best <= (1.0 - prm[I_STALLREL]) * q_ref):
                    status = ST_STALL
                q_ref = q_best
                next_check += win
        last = status >= 0
        if n_rec < n_hist and (last or (record_every > 0 and step % record_every == 0)):
            x, yy, z = mee2cart(y[0], y[1], y[2], y[3], y[4], y[5])
            hist[n_rec, 0] = t
            for j in range(5):
                hist[n_rec, 1 + j] = oe[j]
            hist[n_rec, 6] = y[6]
            hist[n_rec, 7] = 1.0 if on else 0.0
            hist[n_rec, 8] = x
            hist[n_rec, 9] = yy
            hist[n_rec, 10] = z
            hist[n_rec, 11] = q
            n_rec += 1
        if last:
            return status, t, y, revs, step, n_rec, q
        if on:
            rk4_step(y, dt, nsub, ur, ut, un, thrust, mdot, k1, k2, k3, k4, tmp)
        else:
            rk4_step(y, dt, nsub, 0.0, 0.0, 0.0, 0.0, mdot, k1, k2, k3, k4, tmp)
        t += dt
        step += 1
