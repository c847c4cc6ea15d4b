"""Compiled forward sensitivities of the attitude closed loop (DOP853, numba).

The 152 augmented equations of :mod:`penaltyrun.dynamics.attitude_sens` — the closed loop
y = (q, ω), its running energy E, the gain sensitivities Y = ∂y/∂g (7 × 18) and
e = ∂E/∂g — integrated by the compiled Dormand–Prince 8(5,3) of
:mod:`penaltyrun.dynamics.dop853` instead of scipy's Python step loop. The right-hand side
is the same compiled function (:func:`~penaltyrun.dynamics.attitude_sens.augmented`); the
scipy run stays the reference it is checked against, and the integrator of the gains whose
loop is stiff (BDF there).

Events, as in the scipy run:

* the terminal event is the first crossing of ``min(d − tol, u_max − max_i |u_i|)`` to
  ≤ 0: the arrival (d the weighted event distance; free-final-time runs only) or the torque
  limit (only with one), told apart at the end;
* the local minima of d before the end (the *dips*, free-final-time runs only) are the
  integrator's switch points: the switch function is −ḋ while d decreases and ḋ while it
  increases, so each sign change is a local extremum of d, located on the dense output like
  the event, and the smallest d at a local minimum is kept. A switch point restarts the step
  there; nothing else changes (the right-hand side is smooth).

Kernel parameter vector (length :data:`N_PRM`): the first
:data:`penaltyrun.dynamics.attitude.N_PRM` entries are those of the closed-loop kernel
(:func:`penaltyrun.dynamics.attitude.pack_params`: inertia, its inverse, G, u_max, tol,
event weights), then the dip watcher's direction (+1: d decreasing, −1: increasing, 0: no
watcher), the smallest dip so far, the number of dips and the first :data:`N_DIPS` of them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics import attitude as loop
from penaltyrun.dynamics.attitude_sens import N_GAIN
from penaltyrun.dynamics.dop853 import make_dop853

#: Length of the augmented state: (q, ω, E) and the sensitivities (Y, e).
N_AUG = 8 + 8 * N_GAIN
_BASE = loop.N_PRM
#: Dips kept in the parameter vector (the smallest is kept beyond them).
N_DIPS = 64
_DIR = _BASE
_DIP = _BASE + 1
_NDIP = _BASE + 2
_DIPS = _BASE + 3
#: Length of the kernel parameter vector.
N_PRM = _DIPS + N_DIPS


@njit(cache=True)
def rhs(t, z, p, out):
    """Right-hand side of the 152 augmented equations into ``out`` (one small work array;
    the same equations as :func:`~penaltyrun.dynamics.attitude_sens.augmented`)."""
    loop.rhs(t, z, p, out)  # (q̇, ω̇, Ė) of the closed loop, unsaturated (u_max = inf)
    fy = np.empty((8, 8))
    loop.jacobian(t, z, p, fy)  # ∂f/∂y; its last column (∂f/∂E) is zero
    inv = p[9:18]
    for r in range(8):
        for c in range(N_GAIN):
            acc = 0.0
            for k in range(7):
                acc += fy[r, k] * z[8 + N_GAIN * k + c]
            out[8 + N_GAIN * r + c] = acc
    for i in range(3):  # ∂f/∂g: ω̇ rows −I⁻¹[k, i] x_j, Ė row −u_i x_j
        u = loop._linear(z, p, i)
        for j in range(6):
            c = 6 * i + j
            for k in range(3):
                out[8 + N_GAIN * (4 + k) + c] -= inv[3 * k + i] * z[1 + j]
            out[8 + N_GAIN * 7 + c] -= u * z[1 + j]


@njit(cache=True)
def _max_torque(z, p):
    """max_i |(G x)_i| (N·m) at the state z."""
    out = 0.0
    for i in range(3):
        out = max(out, abs(loop._linear(z, p, i)))
    return out


@njit(cache=True)
def event(t, z, p):
    """Terminal event: min(d − tol, u_max − max_i |u_i|) (fires when ≤ 0)."""
    e = loop.weighted_distance(z, p) - p[loop._TOL]
    if np.isfinite(p[loop._UMAX]):
        e = min(e, p[loop._UMAX] - _max_torque(z, p))
    return e


@njit(cache=True)
def event_slope(v, p):
    """Bound on |d event/dt|: the larger of ‖W v‖ and max_i Σ_j |G_ij| v_j."""
    s = loop.event_slope(v, p)
    if np.isfinite(p[loop._UMAX]):
        s = max(s, loop.switch_slope(v, p))
    return s


@njit(cache=True)
def _distance_rate(t, z, p):
    """ḋ = ∂d/∂y · f of the weighted event distance d at the state z."""
    f = np.empty(8)
    loop.rhs(t, z[:8], p, f)
    w0, wq, ww = p[loop._W], p[loop._W + 1], p[loop._W + 2]
    acc = w0 * w0 * (z[0] - 1.0) * f[0]
    for i in range(1, 4):
        acc += wq * wq * z[i] * f[i]
    for i in range(4, 7):
        acc += ww * ww * z[i] * f[i]
    d = loop.weighted_distance(z, p)
    return acc / d if d > 0.0 else 0.0


@njit(cache=True)
def switch(t, z, p):
    """Dip watcher: −ḋ while d decreases, ḋ while it increases (``inf`` without one)."""
    if p[_DIR] == 0.0:
        return np.inf
    return -p[_DIR] * _distance_rate(t, z, p)


@njit(cache=True)
def switch_slope(v, p):
    """Bound on |d switch/dt| (|d̈|): ``inf`` with a watcher, so that every step is probed
    on its dense output at the event spacing (the same probes as the event's near zero)."""
    if p[_DIR] == 0.0:
        return 0.0
    return np.inf


@njit(cache=True)
def set_mode(t, z, p):
    """Start the watcher at t = 0 from the sign of ḋ; at a switch point turn it round and
    keep d when the extremum is a minimum."""
    if p[_DIR] == 0.0:
        return
    if t == 0.0:
        p[_DIR] = 1.0 if _distance_rate(t, z, p) < 0.0 else -1.0
        return
    if p[_DIR] == 1.0:
        d = loop.weighted_distance(z, p)
        p[_DIP] = min(p[_DIP], d)
        k = int(p[_NDIP])
        if k < N_DIPS:
            p[_DIPS + k] = d
        p[_NDIP] = k + 1
    p[_DIR] = -p[_DIR]


_integrate = make_dop853(rhs, event, event_slope, switch, switch_slope, set_mode)
"""Dormand–Prince 8(5,3) bound to the augmented equations (callers are cacheable)."""


@njit(cache=True)
def _run(z0, p, t_end, rtol, atol, max_step, event_spacing, n_samples, max_steps):
    """One compiled run (a cached caller of the integrator, compiled once per machine)."""
    return _integrate(z0, p, t_end, rtol, atol, max_step, event_spacing, n_samples,
                      max_steps)


def pack(G: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray,
         weights: tuple[float, float, float], tol: float | None, u_max: float) -> np.ndarray:
    """The kernel parameter vector (shape (:data:`N_PRM`,)) of one run; ``tol`` None: a
    fixed horizon (no arrival event, no dip watcher)."""
    p = np.zeros(N_PRM)
    loop.pack_params(inertia, inertia_inv, G, u_max, -np.inf if tol is None else tol, p,
                     *weights)
    p[_DIR] = 0.0 if tol is None else 1.0
    p[_DIP] = np.inf
    return p


def integrate(G: np.ndarray, y0: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray,
              t_end: float, weights: tuple[float, float, float], tol: float | None,
              u_max: float, rtol: float, atol: float, max_step: float,
              event_spacing: float, n_samples: int, max_steps: int
              ) -> tuple[float, np.ndarray, int, int, np.ndarray]:
    """One compiled augmented run from ``y0`` (q, ω) with zero energy and sensitivities.

    Returns
    -------
    t : float
        End time (s).
    z : ndarray, shape (152,)
        Augmented state at ``t``.
    status : int
        :mod:`penaltyrun.dynamics.integrate` status (``EVENT``: arrival or torque limit).
    steps : int
        Steps taken (accepted, rejected and restarted at switch points).
    dips : ndarray, shape (k,)
        The weighted distance at the local minima before ``t``, in order: the first
        :data:`N_DIPS`, and the smallest of the others after them.
    """
    p = pack(G, inertia, inertia_inv, weights, tol, u_max)
    z0 = np.zeros(N_AUG)
    z0[:7] = y0
    t, z, status, steps = _run(z0, p, float(t_end), float(rtol), float(atol), float(max_step),
                               float(event_spacing), int(n_samples), int(max_steps))
    return float(t), z, int(status), int(steps), recorded_dips(p)


def recorded_dips(p: np.ndarray) -> np.ndarray:
    """The dips a run recorded in its parameter vector ``p``: the first :data:`N_DIPS`,
    then the smallest of the others where it is smaller than all of them."""
    count = int(p[_NDIP])
    dips = p[_DIPS:_DIPS + min(count, N_DIPS)].copy()
    if count > N_DIPS and p[_DIP] < dips.min():
        dips = np.append(dips, p[_DIP])
    return dips


__all__ = ["N_AUG", "N_DIPS", "N_PRM", "event", "event_slope", "integrate", "pack",
           "recorded_dips", "rhs", "set_mode", "switch", "switch_slope"]
