"""Compiled closed loop of the Zermelo navigation variation (2 states + running cost).

State ``y = (x, y, J)``; parameters ``p = (K11, K12, K21, K22, event_radius)``.
Drift d(X) = (−x cos y sin x, −y cos y sin x); control U = −d(X) − Kᵀ X; closed loop
Ẋ = U + d(X) = −Kᵀ X; running cost J̇ = ½ UᵀU (control energy). Integration: Dormand–Prince
8(5,3) (:mod:`penaltyrun.dynamics.dop853`). ‖X‖ decreases monotonically for K PD
(d‖X‖²/dt = −2 XᵀKX), so the event is checked at step ends, and inside a step only where the
dense output's slope bound allows a crossing.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.dop853 import make_dop853


@njit(cache=True)
def drift(x, y):
    """Current (drift) velocity d(X) at (x, y); returns (dx, dy)."""
    s = np.cos(y) * np.sin(x)
    return -x * s, -y * s


@njit(cache=True)
def rhs(t, y, p, out):
    """Closed-loop right-hand side dy/dt for ``y = (x, y, J)``: Ẋ = −Kᵀ X (the control
    cancels the drift), J̇ = ½ |U|² with U = −d(X) − Kᵀ X (one drift evaluation)."""
    x1 = y[0]
    x2 = y[1]
    k1 = p[0] * x1 + p[2] * x2
    k2 = p[1] * x1 + p[3] * x2
    dx, dy = drift(x1, x2)
    u1 = -dx - k1
    u2 = -dy - k2
    out[0] = -k1
    out[1] = -k2
    out[2] = 0.5 * (u1 * u1 + u2 * u2)


@njit(cache=True)
def event(t, y, p):
    """Terminal event ‖X‖ − r_event (fires when ≤ 0)."""
    return np.sqrt(y[0] * y[0] + y[1] * y[1]) - p[4]


@njit(cache=True)
def event_slope(v, p):
    """Bound on |d‖X‖/dt| from bounds ``v`` (≥ |dy_i/dt|)."""
    return np.sqrt(v[0] * v[0] + v[1] * v[1])


_integrate = make_dop853(rhs, event, event_slope)
"""Dormand–Prince 8(5,3) bound to this closed loop (callers are cacheable)."""


@njit(cache=True)
def simulate_batch(K, x0, t_max, event_radius, rtol, atol, max_step, max_steps, cutoff=None):
    """Closed-loop runs for a batch of gains.

    Parameters
    ----------
    K : ndarray, shape (B, 2, 2)
        Gain matrices.
    x0 : ndarray, shape (2,)
        Initial position (nondimensional).
    t_max : float
        Horizon cap.
    event_radius : float
        Target radius ‖X‖ of the terminal event.
    rtol, atol, max_step : float
        Integrator settings.
    max_steps : int
        Step cap per run.
    cutoff : ndarray, shape (B,), optional
        Exact cutoff per run (``inf``: none): a run stops with status ``CUTOFF`` at the end
        of the first accepted step where J exceeds it (see
        :mod:`penaltyrun.dynamics.integrate`); its J is then a value above the cutoff.

    Returns
    -------
    t_end, cost, dist : ndarray, shape (B,)
        Final time, J at the final time, ‖X‖ at the final time.
    status : ndarray of int64, shape (B,)
        Integrator status codes (see :mod:`penaltyrun.dynamics.integrate`).
    """
    B = K.shape[0]
    t_end = np.empty(B)
    cost = np.empty(B)
    dist = np.empty(B)
    status = np.empty(B, dtype=np.int64)
    p = np.empty(5)
    y0 = np.zeros(3)
    y0[0] = x0[0]
    y0[1] = x0[1]
    for b in range(B):
        p[0] = K[b, 0, 0]
        p[1] = K[b, 0, 1]
        p[2] = K[b, 1, 0]
        p[3] = K[b, 1, 1]
        p[4] = event_radius
        if cutoff is None:
            t, y, st, _ = _integrate(y0, p, t_max, rtol, atol, max_step, np.inf, 1, max_steps)
        else:
            t, y, st, _ = _integrate(y0, p, t_max, rtol, atol, max_step, np.inf, 1, max_steps,
                                     2, cutoff[b])
        t_end[b] = t
        cost[b] = y[2]
        dist[b] = np.sqrt(y[0] * y[0] + y[1] * y[1])
        status[b] = st
    return t_end, cost, dist, status
