"""Closed-form evaluation of the Zermelo closed loop for a symmetric positive-definite K.

The control U = −d(X) − KX cancels the current, so the closed loop is linear, Ẋ = −KX, and
with K = V diag(λ₁, λ₂) Vᵀ (λ > 0)

    X(t) = ξ₁ e^{−λ₁t} v₁ + ξ₂ e^{−λ₂t} v₂,   ξ = Vᵀ X0,
    ‖X(t)‖² = ξ₁² e^{−2λ₁t} + ξ₂² e^{−2λ₂t}   (strictly decreasing).

* Eigen-decomposition: one Jacobi rotation (exact for 2×2, eigenvalues to an absolute
  error of a few ulps of ‖K‖, also for eigenvalues near zero).
* Event time: the root of g(t) = ln‖X(t)‖² − 2 ln r. g is convex and decreasing
  (log-sum-exp of affine functions), so Newton's method from t = 0 increases monotonically
  to the root without overshooting; it is guarded by the bracket
  [ln(‖X0‖/r)/λ_max, ln(‖X0‖/r)/λ_min] and falls back to bisection if it stalls.
* Cost: J = ∫₀ᵀ ½|U(t)|² dt (T = event time, or t_max when the event is not reached) by
  adaptive Gauss–Kronrod (7, 15) quadrature in the graded variable s = ln(1 + λ_max t),
  which resolves both the fast transient (time scale 1/λ_max) and the slow tail (1/λ_min).
  An interval is accepted when the Gauss and Kronrod values agree to :data:`QUAD_RTOL`
  relative; the Kronrod value is kept. Its error is far below that difference (the 7-point
  Gauss rule's): on random gains over the eigenvalue box the cost agrees with the same
  quadrature at 1e-13 to about 1e-14 relative. The integrand is non-negative, so local
  relative bounds add up to a relative bound on J.

Gains the closed form does not cover — K not symmetric (beyond round-off), an eigenvalue not
positive, a start already inside the event radius, a quadrature that does not settle — are
flagged (``covered`` False) for the caller to integrate (:mod:`penaltyrun.dynamics.zermelo`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.integrate import CUTOFF, EVENT, HORIZON

#: Relative Gauss–Kronrod agreement required on every quadrature interval.
QUAD_RTOL = 1e-8
#: Largest number of quadrature intervals per run (more: not covered, integrate instead).
MAX_INTERVALS = 400
#: Largest |K12 − K21| / max|K_ij| treated as round-off of a symmetric K.
SYM_RTOL = 1e-14

_XGK = np.array([0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                 0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                 0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                 0.207784955007898467600689403773245, 0.0])
_WGK = np.array([0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
                 0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
                 0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
                 0.204432940075298892414161999234649, 0.209482141084727828012999174891714])
_WG = np.array([0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                0.381830050505118944950369775488975, 0.417959183673469387755102040816327])
#: The non-negative Gauss–Kronrod (7, 15) abscissae on [−1, 1] (descending, last 0), their
#: Kronrod weights and the 7-point Gauss weights of the odd ones and of 0 (shared rules).
GK_NODES, GK_WEIGHTS, GL_WEIGHTS = _XGK, _WGK, _WG


@njit(cache=True)
def eig_sym2(a, b, c):
    """Eigen-decomposition of the symmetric matrix [[a, b], [b, c]] by one Jacobi rotation.

    Returns
    -------
    l1, l2 : float
        Eigenvalues, with eigenvectors v₁ = (cs, −sn) and v₂ = (sn, cs).
    cs, sn : float
        Cosine and sine of the rotation.
    """
    if b == 0.0:
        return a, c, 1.0, 0.0
    tau = (c - a) / (2.0 * b)
    t = 1.0 / (abs(tau) + np.sqrt(1.0 + tau * tau))
    if tau < 0.0:
        t = -t
    cs = 1.0 / np.sqrt(1.0 + t * t)
    return a - t * b, c + t * b, cs, t * cs


@njit(cache=True)
def _log_dist2(w1, l1, w2, l2, t):
    """ln‖X(t)‖² and its t-derivative from w_i = ln ξ_i² (−inf for ξ_i = 0)."""
    a1 = w1 - 2.0 * l1 * t
    a2 = w2 - 2.0 * l2 * t
    m = max(a1, a2)
    e1 = np.exp(a1 - m)
    e2 = np.exp(a2 - m)
    s = e1 + e2
    return m + np.log(s), -2.0 * (l1 * e1 + l2 * e2) / s


@njit(cache=True)
def event_time(w1, l1, w2, l2, log_r2, t_lo, t_hi):
    """Root of ln‖X(t)‖² = ln r² in [t_lo, t_hi] (safeguarded Newton, see module doc)."""
    t = t_lo
    for it in range(200):
        g, dg = _log_dist2(w1, l1, w2, l2, t)
        g -= log_r2
        if g <= 0.0:
            t_hi = t
        else:
            t_lo = t
        if g == 0.0 or t_hi - t_lo <= 4e-16 * t_hi:
            break
        step = -g / dg
        tn = t + step
        if not t_lo < tn < t_hi or it >= 60:  # outside the bracket or stalling: bisect
            tn = 0.5 * (t_lo + t_hi)
        if abs(tn - t) <= 2e-16 * abs(tn):
            t = tn
            break
        t = tn
    return t


@njit(cache=True)
def _integrand(s, lmax, c1, c2, cs, sn, l1, l2):
    """½|U|² dt/ds at s (t = (eˢ − 1)/λ_max, absolute error of a few ulps of 1/λ_max);
    c_i = ξ_i."""
    es = np.exp(s)
    t = (es - 1.0) / lmax
    p1 = c1 * np.exp(-l1 * t)
    p2 = c2 * np.exp(-l2 * t)
    x = cs * p1 + sn * p2
    y = -sn * p1 + cs * p2
    kx = cs * l1 * p1 + sn * l2 * p2
    ky = -sn * l1 * p1 + cs * l2 * p2
    sc = np.cos(y) * np.sin(x)
    u1 = x * sc - kx
    u2 = y * sc - ky
    return 0.5 * (u1 * u1 + u2 * u2) * es / lmax


@njit(cache=True)
def energy(T, c1, c2, cs, sn, l1, l2, rtol):
    """J = ∫₀ᵀ ½|U|² dt by adaptive Gauss–Kronrod (7, 15) in s = ln(1 + λ_max t).

    Returns
    -------
    J : float
    ok : bool
        False when the interval budget :data:`MAX_INTERVALS` ran out.
    """
    lmax = max(l1, l2)
    S = np.log1p(lmax * T)
    n0 = max(1, min(16, int(np.ceil(S))))
    lo = np.empty(MAX_INTERVALS + 64)
    hi = np.empty(MAX_INTERVALS + 64)
    n = 0
    for k in range(n0):
        lo[n] = S * (n0 - 1 - k) / n0
        hi[n] = S * (n0 - k) / n0
        n += 1
    total = 0.0
    used = 0
    while n > 0:
        n -= 1
        a = lo[n]
        b = hi[n]
        half = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        fc = _integrand(mid, lmax, c1, c2, cs, sn, l1, l2)
        rk = fc * _WGK[7]
        rg = fc * _WG[3]
        for j in range(7):
            dx = half * _XGK[j]
            f = _integrand(mid - dx, lmax, c1, c2, cs, sn, l1, l2) + \
                _integrand(mid + dx, lmax, c1, c2, cs, sn, l1, l2)
            rk += f * _WGK[j]
            if j % 2 == 1:
                rg += f * _WG[j // 2]
        rk *= half
        rg *= half
        used += 1
        if abs(rk - rg) <= rtol * abs(rk) or b - a <= 1e-14 * S:
            total += rk
        elif used + n >= MAX_INTERVALS:
            return total, False
        else:
            lo[n] = mid
            hi[n] = b
            lo[n + 1] = a
            hi[n + 1] = mid
            n += 2
    return total, True


@njit(cache=True)
def closed_batch(K, X0, t_max, event_radius, cutoff, rtol):
    """Closed-form runs of a batch of gains from a batch of starts.

    Parameters
    ----------
    K : ndarray, shape (B, 2, 2)
        Gain matrices (symmetric positive definite to be covered).
    X0 : ndarray, shape (B, 2)
        Start of each run (nondimensional).
    t_max : float
        Horizon cap.
    event_radius : float
        Target radius ‖X‖ of the terminal event.
    cutoff : ndarray, shape (B,)
        Exact cutoff per run (``inf``: none): a run whose J (at the event, or at ``t_max``)
        exceeds it gets status ``CUTOFF`` and that J.
    rtol : float
        Quadrature tolerance (see :func:`energy`).

    Returns
    -------
    t_end, cost, dist : ndarray, shape (B,)
        Event time (or ``t_max``), J at that time, ‖X‖ at that time.
    status : ndarray of int64, shape (B,)
        ``EVENT``, ``HORIZON`` or ``CUTOFF`` (:mod:`penaltyrun.dynamics.integrate`).
    covered : ndarray of bool, shape (B,)
        False where the closed form does not apply (the other outputs are then NaN / −1).
    """
    B = K.shape[0]
    t_end = np.full(B, np.nan)
    cost = np.full(B, np.nan)
    dist = np.full(B, np.nan)
    status = np.full(B, -1, dtype=np.int64)
    covered = np.zeros(B, dtype=np.bool_)
    log_r2 = 2.0 * np.log(event_radius)
    for i in range(B):
        a = K[i, 0, 0]
        c = K[i, 1, 1]
        scale = max(abs(a), abs(c), abs(K[i, 0, 1]), abs(K[i, 1, 0]))
        if not (abs(K[i, 0, 1] - K[i, 1, 0]) <= SYM_RTOL * scale and np.isfinite(scale)):
            continue
        l1, l2, cs, sn = eig_sym2(a, 0.5 * (K[i, 0, 1] + K[i, 1, 0]), c)
        x0 = X0[i, 0]
        y0 = X0[i, 1]
        d0 = np.hypot(x0, y0)
        if not (min(l1, l2) > 0.0 and d0 > event_radius and np.isfinite(d0)):
            continue
        c1 = cs * x0 - sn * y0
        c2 = sn * x0 + cs * y0
        w1 = 2.0 * np.log(abs(c1)) if c1 != 0.0 else -np.inf
        w2 = 2.0 * np.log(abs(c2)) if c2 != 0.0 else -np.inf
        g_end, _ = _log_dist2(w1, l1, w2, l2, t_max)
        if g_end > log_r2:
            T = t_max
            st = HORIZON
        else:
            ln_ratio = np.log(d0 / event_radius)
            lo = ln_ratio / max(l1, l2)
            hi = min(t_max, ln_ratio / min(l1, l2))
            T = event_time(w1, l1, w2, l2, log_r2, min(lo, hi), hi)
            st = EVENT
        J, ok = energy(T, c1, c2, cs, sn, l1, l2, rtol)
        if not (ok and np.isfinite(J)):
            continue
        if J > cutoff[i]:
            st = CUTOFF
        g, _ = _log_dist2(w1, l1, w2, l2, T)
        t_end[i] = T
        cost[i] = J
        dist[i] = np.exp(0.5 * g)
        status[i] = st
        covered[i] = True
    return t_end, cost, dist, status, covered
