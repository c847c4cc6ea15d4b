"""Compiled L-stable Rosenbrock integration (RODAS4) with a first-crossing terminal event.

For stiff closed loops (fast poles far left of the slow ones, e.g. LQR gains near the
eigenvalue bounds), whose explicit integration is limited by stability rather than
accuracy. The method is RODAS4 (Hairer & Wanner, *Solving ODEs II*, IV.7): 6 stages, order
4 with an embedded order-3 solution, stiffly accurate and L-stable, so the step size follows
the slow dynamics only. It needs the exact Jacobian of the right-hand side; every step forms
and factors (1/(γh)) I − J once (LU with partial pivoting, in place; no allocation) and
solves it six times. Autonomous right-hand sides only (no ∂f/∂t term).

The integrator is specialized to one closed loop by :func:`make_rodas` (a closure over
numba-compiled functions, so its compiled callers are cached on disk; the closures are not
cached themselves, for the reason given in :mod:`penaltyrun.dynamics.dop853`):

``rhs(t, y, p, dydt)``, ``event(t, y, p)``, ``event_slope(v, p)``
    As for :func:`penaltyrun.dynamics.dop853.make_dop853` (a smooth loop: no switch points).
``jac(t, y, p, out)``
    Writes ∂f/∂y (shape (n, n)) into ``out``.
``guard(y, p) -> bool``
    Divergence guard, checked at the end of every accepted step (status ``DIVERGED``).

Dense output and first crossing. Between accepted steps the solution is the cubic Hermite
interpolant of (y, f) at both ends (f at the new point is the next step's first stage, so it
costs nothing). The event is watched on it exactly as in
:mod:`penaltyrun.dynamics.dop853`: the cone test with a rigorous slope bound of the
interpolant skips steps where no crossing is possible, probes at most ``event_spacing``
apart (at least ``n_samples`` per step) where it comes close, bisection on the interpolant.
The interpolant is only third order, so the crossing found there is then corrected on the
method itself: Newton iterations on t* where every iterate y(t*) is a RODAS4 step of length
t* − t from the accepted step's start (each shorter than the accepted step, so within its
error control), with the event's time derivative ∇e · f. The event time and J there are
thus the method's own, not the interpolant's.

Statuses, the horizon check and the exact cutoff are those of
:mod:`penaltyrun.dynamics.integrate`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.dop853 import (
    _BASIS_SLOPE,
    EVENT_NEWTON,
    EVENT_NEWTON_TOL,
    SLOPE_SAFETY,
    _dense,
    _jump,
    make_event_newton,
    no_guard,
)
from penaltyrun.dynamics.integrate import (
    CUTOFF,
    DIVERGED,
    EVENT,
    HORIZON,
    NONFINITE,
    STEP_FAILURE,
)

#: RODAS4 (Hairer & Wanner): γ, stage coefficients A (Y_i = y + Σ_j A_ij K_j) and C
#: ((1/(γh) − J) K_i = f(Y_i) + Σ_j C_ij K_j / h), solution weights M (y + Σ M_j K_j) and
#: the error weights E (the last stage).
GAMMA = 0.25
_A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [1.544, 0.0, 0.0, 0.0, 0.0],
    [0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0],
    [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0],
    [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 0.0],
    [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950, 1.0],
])
_C = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0],
    [-5.6688, 0.0, 0.0, 0.0, 0.0],
    [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0],
    [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0],
    [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.70890893206160, 0.0],
    [8.083246795921522, -7.981132988064893, -31.52159432874371, 16.31930543123136,
     -6.058818238834054],
])
_M = np.array([1.221224509226641, 6.019134481288629, 12.53708332932087, -0.6878860361058950,
               1.0, 1.0])
#: Order of the error estimate (local error ∝ h^ELO).
ELO = 4.0


@njit(cache=True)
def _lu(M, piv):
    """In-place LU factorization with partial pivoting; False when singular."""
    n = M.shape[0]
    for k in range(n):
        imax = k
        vmax = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > vmax:
                vmax = abs(M[i, k])
                imax = i
        if vmax == 0.0 or not np.isfinite(vmax):
            return False
        piv[k] = imax
        if imax != k:
            for j in range(n):
                tmp = M[k, j]
                M[k, j] = M[imax, j]
                M[imax, j] = tmp
        inv = 1.0 / M[k, k]
        for i in range(k + 1, n):
            M[i, k] *= inv
            f = M[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    M[i, j] -= f * M[k, j]
    return True


@njit(cache=True)
def _solve(M, piv, b):
    """Solve in place with the factors of :func:`_lu`."""
    n = M.shape[0]
    for k in range(n):
        j = piv[k]
        if j != k:
            tmp = b[k]
            b[k] = b[j]
            b[j] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= M[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= M[i, j] * b[j]
        b[i] = acc / M[i, i]


def make_rodas(rhs, jac, event, event_slope, guard=no_guard):
    """Build RODAS4 specialized to one smooth closed loop (see the module docstring).

    Returns
    -------
    numba dispatcher
        ``integrate(y0, p, t_max, rtol, atol, max_step, event_spacing, n_samples, max_steps,
        cut_index=-1, cut_value=inf) -> (t_end, y_end, status, n_steps)`` with the arguments
        and results of the integrator of :func:`penaltyrun.dynamics.dop853.make_dop853`.
    """
    newton = make_event_newton(rhs, event)

    @njit
    def _step(y, f0, Jm, p, t, h, W, piv, K, y_tmp, y_out, err):
        """One RODAS4 step of length h from (t, y) with f0 = f(y) and Jm = J(y): writes the
        solution in ``y_out`` and the error estimate in ``err``; False when the iteration
        matrix is singular."""
        n = y.shape[0]
        inv_h = 1.0 / h
        g = inv_h / GAMMA
        for i in range(n):
            for j in range(n):
                W[i, j] = -Jm[i, j]
            W[i, i] += g
        if not _lu(W, piv):
            return False
        for s in range(6):
            if s == 0:
                for i in range(n):
                    K[0, i] = f0[i]
            else:
                for i in range(n):
                    acc = y[i]
                    for j in range(s):
                        acc += _A[s, j] * K[j, i]
                    y_tmp[i] = acc
                rhs(t, y_tmp, p, K[s])
                for i in range(n):
                    acc = K[s, i]
                    for j in range(s):
                        acc += _C[s, j] * inv_h * K[j, i]
                    K[s, i] = acc
            _solve(W, piv, K[s])
        for i in range(n):
            acc = y[i]
            for j in range(6):
                acc += _M[j] * K[j, i]
            y_out[i] = acc
            err[i] = K[5, i]
        return True

    @njit
    def integrate(y0, p, t_max, rtol, atol, max_step, event_spacing, n_samples, max_steps,
                  cut_index=-1, cut_value=np.inf):
        n = y0.shape[0]
        y = y0.copy()
        y_new = np.empty(n)
        y_tmp = np.empty(n)
        y_probe = np.empty(n)
        err = np.empty(n)
        f0 = np.empty(n)
        f1 = np.empty(n)
        v = np.empty(n)
        Jm = np.empty((n, n))
        W = np.empty((n, n))
        piv = np.empty(n, dtype=np.int64)
        K = np.empty((6, n))
        F = np.zeros((7, n))
        t = 0.0
        rhs(t, y, p, f0)
        e_old = event(t, y, p)
        if e_old <= 0.0:
            return t, y, EVENT, 0
        for i in range(n):
            if not np.isfinite(f0[i]):
                return t, y, NONFINITE, 0
        # Initial step (Hairer, Nørsett & Wanner, II.4) for a method of local order ELO.
        d0 = 0.0
        d1 = 0.0
        for i in range(n):
            sc = atol + abs(y[i]) * rtol
            d0 += (y[i] / sc) ** 2
            d1 += (f0[i] / sc) ** 2
        d0 = np.sqrt(d0 / n)
        d1 = np.sqrt(d1 / n)
        h = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h = min(h, max_step, t_max)
        if not h > 0.0:
            h = min(1e-6, t_max)
        jac(t, y, p, Jm)
        steps = 0
        while steps < max_steps:
            steps += 1
            if t + h > t_max:
                h = t_max - t
            ok = _step(y, f0, Jm, p, t, h, W, piv, K, y_tmp, y_new, err)
            e_norm = 0.0
            finite = ok
            if ok:
                for i in range(n):
                    sc = atol + rtol * max(abs(y[i]), abs(y_new[i]))
                    e_norm += (err[i] / sc) ** 2
                e_norm = np.sqrt(e_norm / n)
                finite = np.isfinite(e_norm)
            if not finite:
                if h < 1e-12 * max(1.0, t):
                    return t, y, NONFINITE, steps
                h *= 0.2
                continue
            if e_norm > 1.0:
                h *= max(0.2, 0.9 * e_norm ** (-1.0 / ELO))
                if h < 1e-14 * max(1.0, t):
                    return t, y, STEP_FAILURE, steps
                continue
            rhs(t + h, y_new, p, f1)
            e_new = event(t + h, y_new, p)
            # Cubic Hermite interpolant in the layout of dop853's dense output.
            for i in range(n):
                dy = y_new[i] - y[i]
                F[0, i] = dy
                F[1, i] = h * f0[i] - dy
                F[2, i] = 2.0 * dy - h * (f0[i] + f1[i])
                v[i] = SLOPE_SAFETY * max(abs(f0[i]), abs(f1[i]))
            se = event_slope(v, p)
            x_hit = -1.0
            if not (e_new > 0.0 and e_old + e_new > se * h):
                for i in range(n):
                    bound = 0.0
                    for r in range(3):
                        bound += _BASIS_SLOPE[r] * abs(F[r, i])
                    v[i] = bound / h
                se = event_slope(v, p)
                dx_min = min(event_spacing / h, 1.0 / n_samples)
                x = 0.0
                e_x = e_old
                while True:
                    if e_x + e_new > se * (1.0 - x) * h and e_new > 0.0:
                        break
                    x_next = min(x + max(_jump(e_x, se, h), dx_min), 1.0)
                    if x_next >= 1.0:
                        e_next = e_new
                    else:
                        _dense(y, F, x_next, y_probe)
                        e_next = event(t + x_next * h, y_probe, p)
                    if e_next <= 0.0:
                        lo = x
                        hi = x_next
                        for _ in range(60):
                            if (hi - lo) * h <= 1e-13 * max(1.0, t):
                                break
                            mid = 0.5 * (lo + hi)
                            _dense(y, F, mid, y_probe)
                            if event(t + mid * h, y_probe, p) <= 0.0:
                                hi = mid
                            else:
                                lo = mid
                        x_hit = hi
                        break
                    x = x_next
                    e_x = e_next
                    if x >= 1.0:
                        break
            if x_hit >= 0.0:
                # Newton on the event time, each iterate a RODAS4 step from (t, y).
                tau = x_hit * h
                for _ in range(EVENT_NEWTON):
                    if not _step(y, f0, Jm, p, t, tau, W, piv, K, y_tmp, y_probe, err):
                        break
                    d_tau = newton(t, tau, h, y_probe, p, y_tmp, v)
                    if not np.isfinite(d_tau):
                        break
                    tau += d_tau
                    if abs(d_tau) <= EVENT_NEWTON_TOL * max(1.0, t + tau):
                        break
                if _step(y, f0, Jm, p, t, tau, W, piv, K, y_tmp, y_probe, err):
                    return t + tau, y_probe, EVENT, steps
                _dense(y, F, x_hit, y_probe)
                return t + x_hit * h, y_probe, EVENT, steps
            t = t + h
            y[:] = y_new
            f0[:] = f1
            e_old = e_new
            if t >= t_max:
                return t, y, HORIZON, steps
            if cut_index >= 0 and y[cut_index] > cut_value:
                return t, y, CUTOFF, steps
            if guard(y, p):
                return t, y, DIVERGED, steps
            factor = 5.0 if e_norm == 0.0 else min(5.0, 0.9 * e_norm ** (-1.0 / ELO))
            h = min(h * factor, max_step)
            jac(t, y, p, Jm)
        return t, y, STEP_FAILURE, steps

    return integrate
