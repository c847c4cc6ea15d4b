"""Closed-loop propagation of a low-thrust transfer with its stop rules.

The control (thrust direction in the radial/transverse/normal frame and the on/off flag) is
computed at the start of each fixed control step ``dt`` and held (zero-order hold); within the
step the dynamics, including the mass flow and F = T/m, are integrated with ``nsub`` classical
RK4 substeps. Stop rules, each a distinct status: convergence, escape (non-finite state, e ≥ 1
or a ≤ 0), impact, propellant floor, time-of-flight cap, revolution cap, step cap and stall
(``stall``), no progress (``no_progress``: the best Q, or V, has not fallen by the fraction
``prm[I_NPFRAC]`` over ``prm[I_NPREVS]`` revolutions) and the exact cutoff (``cutoff``).

Exact cutoff: with ``prm[I_CUTKIND]`` = ``CUT_TIME`` (elapsed time t/86400, days) or
``CUT_PROPELLANT`` (m0 − m, kg) the transfer stops as soon as that accumulated cost exceeds
``prm[I_CUTOFF]`` while it is still ≤ ``prm[I_CUTCAP]``. It is checked after every other stop
rule of the step, so a transfer that ends there anyway ends as without the cutoff. Both
accumulated costs never decrease along a transfer (t grows by dt per step, the mass never
grows), so a converged transfer's final cost is at least the accumulated one; a failed
transfer costs at least the failure penalty's base, which the caller passes as the cap. The
cut transfer's accumulated cost is therefore a bound: above the cutoff and never above the
cost of the uncut transfer.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.lowthrust.elements import (
    kep2mee,
    mee2cart,
    mee2kep,
    rk4_step,
)
from penaltyrun.dynamics.lowthrust.qlaw import N_WORK, selector_matrix
from penaltyrun.dynamics.lowthrust.settings import (
    CUT_NONE,
    CUT_TIME,
    G0,
    I_CUTCAP,
    I_CUTKIND,
    I_CUTOFF,
    I_DT,
    I_ISP,
    I_MAXSTEPS,
    I_MFLOOR,
    I_NPFRAC,
    I_NPREVS,
    I_NSUB,
    I_REVMAX,
    I_RIMPACT,
    I_SIDES,
    I_STALLREL,
    I_STALLREVS,
    I_THRUST,
    I_TMAX,
    ST_CONVERGED,
    ST_CUTOFF,
    ST_ESCAPE,
    ST_IMPACT,
    ST_NO_PROGRESS,
    ST_PROPELLANT,
    ST_REV,
    ST_STALL,
    ST_TOF,
    TWO_PI,
)
from penaltyrun.dynamics.lowthrust.steering import law_eval_m


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
    M = np.empty((5, 5))
    selector_matrix(sel, K, prm[I_SIDES] > 1.5, M)
    work = np.empty(N_WORK)
    oe = np.empty(6)
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
    np_win = prm[I_NPREVS]
    np_keep = 1.0 - prm[I_NPFRAC]
    np_ref = np.inf
    np_next = np_win
    cut_kind = int(prm[I_CUTKIND])
    cut_value = prm[I_CUTOFF]
    cut_cap = prm[I_CUTCAP]
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
        done = True
        for j in range(5):
            if sel[j] != 0.0:
                dj = oe[j] - oeT[j]
                if j >= 2:
                    dj -= TWO_PI * np.floor((dj + np.pi) / TWO_PI)
                if not abs(dj) <= tol[j]:
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
        elif cut_kind != CUT_NONE:
            spent = t / 86400.0 if cut_kind == CUT_TIME else m0 - y[6]
            if spent > cut_value and spent <= cut_cap:
                status = ST_CUTOFF
        on = False
        if status < 0:
            F = thrust / (1000.0 * y[6])
            if thrust > 0.0:
                ur, ut, un, on, q, _eta = law_eval_m(oe, F, oeT, sel, K, M, prm, grad, B, work)
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
            if np_ref == np.inf:
                np_ref = q_best
            if np_win > 0.0 and revs >= np_next and status < 0:
                if not (q_best <= np_keep * np_ref):
                    status = ST_NO_PROGRESS
                np_ref = q_best
                np_next += np_win
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

