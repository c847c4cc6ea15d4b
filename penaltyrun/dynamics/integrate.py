"""Compiled adaptive Runge–Kutta integration with a terminal event.

Dormand–Prince 5(4) (Dormand & Prince 1980; Shampine 1986 quartic dense output) with
standard error control, a maximum step, and a terminal event located on the dense output.
The right-hand side and the event are numba-compiled functions bound once by
:func:`make_dopri5` (a closure, so that its compiled callers can be cached):

``rhs(t, y, p, dydt)`` writes dy/dt into ``dydt`` (all float64 1-D arrays, ``p`` holds the
problem's parameters); ``event(t, y, p) -> float`` is positive away from the target and
the event fires the FIRST time it becomes ≤ 0.

Events are searched on the dense output at ``n_event_samples`` points inside every
accepted step (not only at step ends), so a non-monotone event function that dips below
zero inside a step is not stepped over; the crossing is then refined by bisection on the
interpolant.

Optional exact cutoff: with ``cut_index ≥ 0`` the integration stops with status ``CUTOFF``
at the end of the first accepted step where ``y[cut_index] > cut_value`` (after the event
search of that step and the horizon check, so a run that ends there anyway ends as without
the cutoff). Callers use it on a running cost that the optimizer will compare with
``cut_value``: the returned state is then a bound, ``y[cut_index] > cut_value``.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import njit

#: Integration status codes returned by :func:`dopri5`.
EVENT = 0
HORIZON = 1
STEP_FAILURE = 2
NONFINITE = 3
CUTOFF = 4
#: A divergence guard of the closed loop fired (the state left its documented bound; only
#: integrators built with a guard return it, e.g. the attitude kernels).
DIVERGED = 5
STATUS_NAMES = ("event", "horizon", "step_failure", "nonfinite", "cutoff", "diverged")

@njit(cache=True)
def _tableau():
    """Dormand–Prince 5(4) coefficients: A, B, C, E (error) and P (dense output)."""
    C = np.array([0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0])
    A = np.array(
        [
            [0.0, 0.0, 0.0, 0.0, 0.0],
            [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0],
            [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0],
            [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0],
            [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0],
            [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
        ]
    )
    B = np.array([35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0])
    E = np.array(
        [
            -71.0 / 57600.0,
            0.0,
            71.0 / 16695.0,
            -71.0 / 1920.0,
            17253.0 / 339200.0,
            -22.0 / 525.0,
            1.0 / 40.0,
        ]
    )
    P = np.array(
        [
            [1.0, -8048581381.0 / 2820520608.0, 8663915743.0 / 2820520608.0,
             -12715105075.0 / 11282082432.0],
            [0.0, 0.0, 0.0, 0.0],
            [0.0, 131558114200.0 / 32700410799.0, -68118460800.0 / 10900136933.0,
             87487479700.0 / 32700410799.0],
            [0.0, -1754552775.0 / 470086768.0, 14199869525.0 / 1410260304.0,
             -10690763975.0 / 1880347072.0],
            [0.0, 127303824393.0 / 49829197408.0, -318862633887.0 / 49829197408.0,
             701980252875.0 / 199316789632.0],
            [0.0, -282668133.0 / 205662961.0, 2019193451.0 / 616988883.0,
             -1453857185.0 / 822651844.0],
            [0.0, 40617522.0 / 29380423.0, -110615467.0 / 29380423.0, 69997945.0 / 29380423.0],
        ]
    )
    return A, B, C, E, P


@njit(cache=True)
def _dense(y_old, h, Q, x, out):
    """Quartic dense output at fraction x ∈ [0, 1] of the step; Q = Kᵀ P (n, 4)."""
    x2 = x * x
    x3 = x2 * x
    x4 = x3 * x
    for i in range(y_old.shape[0]):
        out[i] = y_old[i] + h * (Q[i, 0] * x + Q[i, 1] * x2 + Q[i, 2] * x3 + Q[i, 3] * x4)


def make_dopri5(rhs, event):
    """Build the integrator specialized to one right-hand side and event (cacheable).

    The returned numba function closes over ``rhs`` and ``event`` instead of taking them as
    arguments: numba cannot cache a function that passes compiled functions as arguments, but
    it caches callers of this closure (``cache=True``), so a fresh process loads them from the
    cache instead of recompiling. Build it once at module level and call it from ``@njit``
    code.

    Parameters
    ----------
    rhs, event : numba-compiled functions
        See the module docstring.

    Returns
    -------
    numba dispatcher
        ``integrate(y0, p, t_max, rtol, atol, max_step, n_event_samples, max_steps,
        cut_index=-1, cut_value=inf)``, see :func:`dopri5` for the arguments and results.
    """

    @njit(cache=True)
    def integrate(y0, p, t_max, rtol, atol, max_step, n_event_samples, max_steps,
                  cut_index=-1, cut_value=np.inf):
        _A, _B, _C, _E, _P = _tableau()
        n = y0.shape[0]
        y = y0.copy()
        y_new = np.empty(n)
        y_tmp = np.empty(n)
        y_probe = np.empty(n)
        K = np.empty((7, n))
        Q = np.empty((n, 4))
        t = 0.0
        f0 = np.empty(n)
        rhs(t, y, p, f0)
        K[0, :] = f0
        if event(t, y, p) <= 0.0:
            return t, y, EVENT, 0
        # Initial step (Hairer, Nørsett & Wanner, II.4).
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
        steps = 0
        while steps < max_steps:
            steps += 1
            if t + h > t_max:
                h = t_max - t
            for s in range(1, 6):
                for i in range(n):
                    acc = 0.0
                    for j in range(s):
                        acc += _A[s, j] * K[j, i]
                    y_tmp[i] = y[i] + h * acc
                rhs(t + _C[s] * h, y_tmp, p, f0)
                K[s, :] = f0
            for i in range(n):
                acc = 0.0
                for j in range(6):
                    acc += _B[j] * K[j, i]
                y_new[i] = y[i] + h * acc
            rhs(t + h, y_new, p, f0)
            K[6, :] = f0
            err = 0.0
            finite = True
            for i in range(n):
                e = 0.0
                for j in range(7):
                    e += _E[j] * K[j, i]
                sc = atol + max(abs(y[i]), abs(y_new[i])) * rtol
                err += (h * e / sc) ** 2
                if not np.isfinite(y_new[i]):
                    finite = False
            err = np.sqrt(err / n)
            if not finite:
                if h < 1e-12 * max(1.0, t):
                    return t, y, NONFINITE, steps
                h *= 0.2
                continue
            if err > 1.0:
                h *= max(0.2, 0.9 * err ** -0.2)
                if h < 1e-14 * max(1.0, t):
                    return t, y, STEP_FAILURE, steps
                continue
            # Accepted step: look for the event on the dense output.
            for i in range(n):
                for c in range(4):
                    acc = 0.0
                    for j in range(7):
                        acc += K[j, i] * _P[j, c]
                    Q[i, c] = acc
            x_lo = 0.0
            for k in range(1, n_event_samples + 1):
                x_hi = k / n_event_samples
                _dense(y, h, Q, x_hi, y_probe)
                if event(t + x_hi * h, y_probe, p) <= 0.0:
                    for _ in range(60):
                        x_mid = 0.5 * (x_lo + x_hi)
                        _dense(y, h, Q, x_mid, y_probe)
                        if event(t + x_mid * h, y_probe, p) <= 0.0:
                            x_hi = x_mid
                        else:
                            x_lo = x_mid
                        if (x_hi - x_lo) * h <= 1e-13 * max(1.0, t):
                            break
                    _dense(y, h, Q, x_hi, y_probe)
                    return t + x_hi * h, y_probe, EVENT, steps
                x_lo = x_hi
            t = t + h
            y[:] = y_new
            K[0, :] = K[6, :]
            if t >= t_max:
                return t, y, HORIZON, steps
            if cut_index >= 0 and y[cut_index] > cut_value:
                return t, y, CUTOFF, steps
            factor = 10.0 if err == 0.0 else min(10.0, 0.9 * err ** -0.2)
            h = min(h * factor, max_step)
        return t, y, STEP_FAILURE, steps

    return integrate


@functools.cache
def _specialized(rhs, event):
    return make_dopri5(rhs, event)


def dopri5(rhs, event, y0, p, t_max, rtol, atol, max_step, n_event_samples, max_steps,
           cut_index=-1, cut_value=np.inf):
    """Integrate from t = 0 until the event fires or ``t_max`` is reached.

    Python-level convenience (not callable from ``@njit`` code): compiled callers build
    their integrator once with :func:`make_dopri5`.

    Parameters
    ----------
    rhs, event : numba-compiled functions
        See the module docstring.
    y0 : ndarray, shape (n,)
        Initial state.
    p : ndarray, shape (m,)
        Parameters passed through to ``rhs`` and ``event``.
    t_max : float
        Horizon cap (same time unit as the dynamics).
    rtol, atol : float
        Relative and absolute tolerances (mixed error test, RMS norm).
    max_step : float
        Largest step allowed.
    n_event_samples : int
        Dense-output samples per step on which the event is checked (≥ 1; the step end
        is always one of them).
    max_steps : int
        Cap on accepted + rejected steps.
    cut_index : int, optional
        Component of ``y`` watched by the cutoff (−1: no cutoff).
    cut_value : float, optional
        Stop with ``CUTOFF`` at the end of the first accepted step where
        ``y[cut_index] > cut_value`` (and the run did not end in that step anyway).

    Returns
    -------
    t_end : float
        Event time, ``t_max``, or the time where integration stopped.
    y_end : ndarray, shape (n,)
        State at ``t_end``.
    status : int
        ``EVENT``, ``HORIZON``, ``STEP_FAILURE``, ``NONFINITE`` or ``CUTOFF``.
    n_steps : int
        Number of steps attempted.
    """
    return _specialized(rhs, event)(y0, p, t_max, rtol, atol, max_step, n_event_samples,
                                    max_steps, cut_index, cut_value)
