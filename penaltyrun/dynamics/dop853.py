"""Compiled Dormand–Prince 8(5,3) integration with a first-crossing event and switch points.

The method is DOP853 (Hairer, Nørsett & Wanner, *Solving ODEs I*, II.10): order 8 with the
blended 5th/3rd-order error estimate and the order-7 dense output (three extra stages,
computed only for the steps that need it). The integrator is specialized to one closed loop by
:func:`make_dop853` (a closure over numba-compiled functions, so its compiled callers are
cached on disk). The closures themselves are compiled but not cached: numba keeps the
machine code of every closure made by one factory in one index file, which two processes
compiling different loops at once (a cold cache, two workers or test processes) update
without a lock, so one could load the code of another loop. The cached caller holds the
code it needs; a closure called from Python is compiled once per process. The loop's
functions:

``rhs(t, y, p, dydt)``
    Writes dy/dt. For a piecewise-smooth loop it must use the *frozen* piece stored in ``p``
    by ``set_mode`` (the smooth continuation across a kink), so every step sees a smooth
    right-hand side and keeps the method's order.
``event(t, y, p) -> float``
    Positive away from the target; the run ends the FIRST time it becomes ≤ 0.
``event_slope(v, p) -> float``
    A bound on |d event/dt| given bounds ``v[i] ≥ |dy_i/dt|``.
``switch(t, y, p) -> float``
    ≥ 0 inside the current smooth piece; a crossing to < 0 is a kink (switch point).
    Return ``inf`` for a smooth loop.
``switch_slope(v, p) -> float``
    A bound on |d switch/dt| (0 for a smooth loop).
``set_mode(t, y, p)``
    Stores in ``p`` the smooth piece the state ``y`` lies in (called at t = 0 and at every
    switch point).
``guard(y, p) -> bool``
    Divergence guard: True when the state has left the loop's documented bound. Checked at
    the end of every accepted step (after the event search, the horizon check and the
    cutoff); the run then stops with status ``DIVERGED``. Default: never.

First crossing. After every accepted step both watched functions w (event and switch) are
checked on the step's dense output with a Lipschitz bound S ≥ |dw/dt|: no crossing is
possible in [t, t + h] when w(t) + w(t + h) > S·h (two cones from the end values), and from a
point where w = m > 0 the next probe may jump m / S ahead. The bound S comes from the stage
derivatives (times :data:`SLOPE_SAFETY`) for the quick test that skips the dense output, and
from the interpolant itself (rigorous for the interpolant) for the probes. Probes are at most
``event_spacing`` apart only where w comes within S·``event_spacing`` of zero, so every dip of
the event below zero that lasts longer than ``event_spacing`` is found; the crossing is then
refined by bisection on the interpolant. The interpolant's error is not under the step-size
control (on a long step near a slow arrival it moved the event by up to 1e-3 s at rtol 1e-10),
so an event crossing is then corrected on the method itself: Newton iterations on t* where
every iterate y(t*) is a DOP853 step of length t* − t from the accepted step's start (shorter
than the accepted step, so within its error control). At a switch point the state is taken
from the dense output, ``set_mode`` selects the new piece, and integration resumes from
there.

Statuses, the horizon check and the exact cutoff are those of
:mod:`penaltyrun.dynamics.integrate` (a step that ends at a switch point is an accepted step);
``DIVERGED`` comes from the guard.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.dop853_stages import dense_rows, error_norms, stage_input
from penaltyrun.dynamics.dop853_tableau import C
from penaltyrun.dynamics.integrate import (
    CUTOFF,
    DIVERGED,
    EVENT,
    HORIZON,
    NONFINITE,
    STEP_FAILURE,
)

#: Factor on the stage-derivative slope bound in the quick no-crossing test of a step.
SLOPE_SAFETY = 2.0
#: Derivative bounds of the dense-output basis x^a (1 − x)^b on [0, 1]: max(a, b).
_BASIS_SLOPE = np.array([1.0, 1.0, 2.0, 2.0, 3.0, 3.0, 4.0])
#: Newton iterations on the event time at most, and their relative stopping size.
EVENT_NEWTON = 8
EVENT_NEWTON_TOL = 1e-13


@njit(cache=True)
def no_switch(t, y, p):
    """Switch function of a smooth loop (never crosses)."""
    return np.inf


@njit(cache=True)
def no_slope(v, p):
    """Slope bound of :func:`no_switch`."""
    return 0.0


@njit(cache=True)
def no_mode(t, y, p):
    """Mode update of a smooth loop (nothing to store)."""


@njit(cache=True)
def no_guard(y, p):
    """Divergence guard that never fires."""
    return False


@njit(cache=True)
def _dense(y_old, F, x, out):
    """Order-7 dense output at fraction x ∈ [0, 1] of the step (F: 7 × n, includes h)."""
    x1 = 1.0 - x
    for i in range(y_old.shape[0]):
        acc = F[5, i] + x * F[6, i]
        acc = F[4, i] + x1 * acc
        acc = F[3, i] + x * acc
        acc = F[2, i] + x1 * acc
        acc = F[1, i] + x * acc
        acc = F[0, i] + x1 * acc
        out[i] = y_old[i] + x * acc


@njit(cache=True)
def _jump(margin, slope, h):
    """Fraction of a step of length h over which a function at ``margin`` cannot cross."""
    if slope * h <= margin:
        return 1.0
    return margin / (slope * h)


def make_event_newton(rhs, event):
    """Newton step on a terminal event's time, shared by the compiled integrators.

    Returns
    -------
    numba dispatcher
        ``newton(t, tau, h, y_tau, p, f_buf, v) -> d_tau``: with ``y_tau`` the method's state
        at t + tau, the step −e / (d e / dt) clamped to [−tau / 2, h − tau]; ``nan`` when the
        event does not fall along the flow there. d e / dt is a centred difference of e along
        f (e is not smooth at the target itself, which a run never reaches); ``f_buf`` and
        ``v`` are work arrays of the state's size.
    """

    @njit
    def newton(t, tau, h, y_tau, p, f_buf, v):
        n = y_tau.shape[0]
        e_val = event(t + tau, y_tau, p)
        rhs(t + tau, y_tau, p, f_buf)
        eps = 1e-7 * max(tau, 1e-3)
        for i in range(n):
            v[i] = y_tau[i] + eps * f_buf[i]
        e_plus = event(t + tau + eps, v, p)
        for i in range(n):
            v[i] = y_tau[i] - eps * f_buf[i]
        slope = (e_plus - event(t + tau - eps, v, p)) / (2.0 * eps)
        if not slope < 0.0:
            return np.nan
        return min(max(-e_val / slope, -0.5 * tau), h - tau)

    return newton


def make_dop853(rhs, event, event_slope, switch=no_switch, switch_slope=no_slope,
                set_mode=no_mode, guard=no_guard):
    """Build DOP853 specialized to one closed loop (see the module docstring).

    Returns
    -------
    numba dispatcher
        ``integrate(y0, p, t_max, rtol, atol, max_step, event_spacing, n_samples, max_steps,
        cut_index=-1, cut_value=inf) -> (t_end, y_end, status, n_steps)``. ``p`` is
        modified (``set_mode``). Tolerances: mixed error test ``atol + rtol·|y|``; ``max_step``
        the largest step; ``event_spacing`` the largest distance between probes of a watched
        function near zero (same time unit), with at least ``n_samples`` probes per step
        there; ``max_steps`` a cap on accepted + rejected steps; with ``cut_index ≥ 0`` the
        run stops with ``CUTOFF`` at the end of the first accepted step where
        ``y[cut_index] > cut_value`` (a running cost past what the optimizer compares it
        with; a run that ends in that step anyway ends as without the cutoff).
    """

    newton = make_event_newton(rhs, event)

    @njit
    def _bisect(y, F, h, t, p, x_lo, x_hi, use_event, y_probe):
        """Shrink [x_lo, x_hi] around the first sign change of the event or the switch."""
        for _ in range(60):
            if (x_hi - x_lo) * h <= 1e-13 * max(1.0, t):
                break
            x_mid = 0.5 * (x_lo + x_hi)
            _dense(y, F, x_mid, y_probe)
            if use_event:
                w = event(t + x_mid * h, y_probe, p)
            else:
                w = switch(t + x_mid * h, y_probe, p)
            if w <= 0.0:
                x_hi = x_mid
            else:
                x_lo = x_mid
        return x_hi

    @njit
    def _step_to(y, K, t, tau, p, y_tmp, out):
        """One DOP853 step of length tau from (t, y) into ``out`` (K[0] = f(t, y) kept)."""
        for s in range(1, 12):
            stage_input(s, y, tau, K, y_tmp)
            rhs(t + C[s] * tau, y_tmp, p, K[s])
        stage_input(12, y, tau, K, out)
        for i in range(out.shape[0]):
            if not np.isfinite(out[i]):
                return False
        return True

    @njit
    def _refine_event(y, K, t, h, x_hit, p, y_tmp, y_probe, v):
        """Event time t + tau on the method itself (Newton from the interpolant's x_hit).

        Each iterate is a step of length tau from the accepted step's start. Returns tau
        and leaves y(t + tau) in ``y_probe``; tau < 0 when the iteration cannot be trusted
        (the caller keeps the interpolant's crossing).
        """
        tau = x_hit * h
        for _ in range(EVENT_NEWTON):
            if not _step_to(y, K, t, tau, p, y_tmp, y_probe):
                return -1.0
            d_tau = newton(t, tau, h, y_probe, p, y_tmp, v)
            if not np.isfinite(d_tau):
                return -1.0
            tau += d_tau
            if abs(d_tau) <= EVENT_NEWTON_TOL * max(1.0, t + tau):
                break
        if not _step_to(y, K, t, tau, p, y_tmp, y_probe):
            return -1.0
        return tau

    @njit
    def integrate(y0, p, t_max, rtol, atol, max_step, event_spacing, n_samples, max_steps,
                  cut_index=-1, cut_value=np.inf):
        n = y0.shape[0]
        y = y0.copy()
        y_new = np.empty(n)
        y_tmp = np.empty(n)
        y_probe = np.empty(n)
        v = np.empty(n)
        K = np.empty((16, n))
        F = np.empty((7, n))
        t = 0.0
        set_mode(t, y, p)
        rhs(t, y, p, K[0])
        e_old = event(t, y, p)
        if e_old <= 0.0:
            return t, y, EVENT, 0
        g_old = switch(t, y, p)
        for i in range(n):
            if not np.isfinite(K[0, i]):  # e.g. a gain of 1e308: the first derivative overflows
                return t, y, NONFINITE, 0
        # Initial step (Hairer, Nørsett & Wanner, II.4): an Euler probe estimates the second
        # derivative, h = (0.01 / max(d1, d2))^(1/8) for the order-8 method.
        d0 = 0.0
        d1 = 0.0
        for i in range(n):
            sc = atol + abs(y[i]) * rtol
            d0 += (y[i] / sc) ** 2
            d1 += (K[0, i] / sc) ** 2
        d0 = np.sqrt(d0 / n)
        d1 = np.sqrt(d1 / n)
        h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h0 = min(h0, max_step, t_max)
        if not h0 > 0.0:
            h0 = min(1e-6, t_max)
        for i in range(n):
            y_tmp[i] = y[i] + h0 * K[0, i]
        rhs(t + h0, y_tmp, p, K[1])
        d2 = 0.0
        for i in range(n):
            sc = atol + abs(y[i]) * rtol
            d2 += ((K[1, i] - K[0, i]) / sc) ** 2
        d2 = np.sqrt(d2 / n) / h0
        if max(d1, d2) <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** 0.125
        h = min(100.0 * h0, h1, max_step, t_max)
        steps = 0
        while steps < max_steps:
            steps += 1
            if t + h > t_max:
                h = t_max - t
            for s in range(1, 12):
                stage_input(s, y, h, K, y_tmp)
                rhs(t + C[s] * h, y_tmp, p, K[s])
            stage_input(12, y, h, K, y_new)
            rhs(t + h, y_new, p, K[12])
            err5, err3, finite = error_norms(y, y_new, K, rtol, atol)
            if not finite:
                if h < 1e-12 * max(1.0, t):
                    return t, y, NONFINITE, steps
                h *= 0.2
                continue
            err = 0.0
            if err5 > 0.0 or err3 > 0.0:
                err = h * err5 / np.sqrt((err5 + 0.01 * err3) * n)
            if not np.isfinite(err):
                h *= 0.2
                continue
            if err > 1.0:
                h *= max(0.2, 0.9 * err ** -0.125)
                if h < 1e-14 * max(1.0, t):
                    return t, y, STEP_FAILURE, steps
                continue
            # Accepted step: is a crossing of the event or the switch possible inside?
            e_new = event(t + h, y_new, p)
            g_new = switch(t + h, y_new, p)
            for i in range(n):
                m = 0.0
                for j in range(13):
                    m = max(m, abs(K[j, i]))
                v[i] = SLOPE_SAFETY * m
            se = event_slope(v, p)
            sg = switch_slope(v, p)
            x_end = 1.0
            hit = -1  # -1 none, 0 event, 1 switch
            if not (e_new > 0.0 and g_new >= 0.0 and e_old + e_new > se * h
                    and g_old + g_new > sg * h):
                # Dense output: three extra stages, then the interpolant's coefficients.
                for s in range(13, 16):
                    stage_input(s, y, h, K, y_tmp)
                    rhs(t + C[s] * h, y_tmp, p, K[s])
                dense_rows(h, K, F)
                for i in range(n):
                    dy = y_new[i] - y[i]
                    F[0, i] = dy
                    F[1, i] = h * K[0, i] - dy
                    F[2, i] = 2.0 * dy - h * (K[12, i] + K[0, i])
                    bound = 0.0
                    for r in range(7):
                        bound += _BASIS_SLOPE[r] * abs(F[r, i])
                    v[i] = bound / h
                se = event_slope(v, p)
                sg = switch_slope(v, p)
                dx_min = min(event_spacing / h, 1.0 / n_samples)
                x = 0.0
                e_x = e_old
                g_x = g_old
                while True:
                    rest = (1.0 - x) * h
                    if e_x + e_new > se * rest and g_x + g_new > sg * rest \
                            and e_new > 0.0 and g_new >= 0.0:
                        break
                    dx = max(min(_jump(e_x, se, h), _jump(g_x, sg, h)), dx_min)
                    x_next = min(x + dx, 1.0)
                    if x_next >= 1.0:
                        e_next = e_new
                        g_next = g_new
                    else:
                        _dense(y, F, x_next, y_probe)
                        e_next = event(t + x_next * h, y_probe, p)
                        g_next = switch(t + x_next * h, y_probe, p)
                    if e_next <= 0.0 or g_next < 0.0:
                        x_e = 2.0
                        x_s = 2.0
                        if e_next <= 0.0:
                            x_e = _bisect(y, F, h, t, p, x, x_next, True, y_probe)
                        if g_next < 0.0:
                            x_s = _bisect(y, F, h, t, p, x, x_next, False, y_probe)
                        if x_e <= x_s:
                            hit = 0
                            x_end = x_e
                        else:
                            hit = 1
                            x_end = x_s
                        break
                    x = x_next
                    e_x = e_next
                    g_x = g_next
                    if x >= 1.0:
                        break
            if hit == 0:
                tau = _refine_event(y, K, t, h, x_end, p, y_tmp, y_probe, v)
                if tau > 0.0:
                    return t + tau, y_probe, EVENT, steps
                _dense(y, F, x_end, y_probe)
                return t + x_end * h, y_probe, EVENT, steps
            if hit == 1:
                # Switch point: resume from the dense output in the new smooth piece.
                _dense(y, F, x_end, y_probe)
                t = t + x_end * h
                y[:] = y_probe
                set_mode(t, y, p)
                rhs(t, y, p, K[0])
                e_old = event(t, y, p)
                if e_old <= 0.0:
                    return t, y, EVENT, steps
                g_old = switch(t, y, p)
                if t >= t_max:
                    return t, y, HORIZON, steps
                if cut_index >= 0 and y[cut_index] > cut_value:
                    return t, y, CUTOFF, steps
                if guard(y, p):
                    return t, y, DIVERGED, steps
                continue
            t = t + h
            y[:] = y_new
            K[0, :] = K[12, :]
            e_old = e_new
            g_old = g_new
            if t >= t_max:
                return t, y, HORIZON, steps
            if cut_index >= 0 and y[cut_index] > cut_value:
                return t, y, CUTOFF, steps
            if guard(y, p):
                return t, y, DIVERGED, steps
            factor = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** -0.125)
            h = min(h * factor, max_step)
        return t, y, STEP_FAILURE, steps

    return integrate
