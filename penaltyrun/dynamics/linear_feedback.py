"""Vectorized adaptive integration of linear state-feedback loops on any plant.

Closed loop ẋ = f(x, u), u = sat(−K x) (saturation: each input clipped to ±u_max), with the
running cost J̇ = xᵀ W_x x + uᵀ W_u u, integrated over [0, T] for R rows (one gain and one
initial state per row) at once. ``f(X, U)`` is a plain vectorized NumPy function
(X: (R, n), U: (R, m) → (R, n)): a linear plant X Aᵀ + U Bᵀ or the user's nonlinear model,
which is why this integrator is NumPy over rows rather than a compiled kernel.

Dormand–Prince 5(4) (the coefficients of :mod:`penaltyrun.dynamics.integrate`) with the
usual mixed error test (RMS norm over x and J), every row with its own step size: each
iteration advances the rows still running by one trial step; rejected rows retry with a
smaller step. The clipped input has a kink where it leaves the limit; the error control
shortens the steps there (checked against ``solve_ivp`` in the tests).

A row ends with status

* ``HORIZON`` (t = T reached; the normal end),
* ``DIVERGED`` (‖x‖ above ``x_bound``: the loop blew up),
* ``NONFINITE`` (non-finite values that step-size reduction cannot remove),
* ``STEP_FAILURE`` (step-size underflow or more than ``max_steps`` trial steps),
* ``CUTOFF`` (exact cutoff: the summed J of a group of rows exceeded its threshold at the
  end of an accepted step; J only grows, so that sum is a lower bound of the final one),
* ``SETTLED`` (optional settling event: ‖x‖ fell to the row's level; checked at the end of
  every accepted step, the first crossing inside that step located by bisection on
  re-taken steps from its start, to 1e-13 of the time).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from penaltyrun.dynamics import integrate

HORIZON = integrate.HORIZON
STEP_FAILURE = integrate.STEP_FAILURE
NONFINITE = integrate.NONFINITE
CUTOFF = integrate.CUTOFF
DIVERGED = 5
SETTLED = 6

_A, _B, _C, _E = integrate.dopri54_tableau()


def feedback_input(K: np.ndarray, X: np.ndarray, u_max: np.ndarray | None) -> np.ndarray:
    """u = −K x per row, clipped to ±u_max (shape (R, m)); ``K`` (R, m, n), ``X`` (R, n)."""
    U = -np.einsum("rij,rj->ri", K, X)
    return U if u_max is None else np.clip(U, -u_max, u_max)


def _augmented(f: Callable[[np.ndarray, np.ndarray], np.ndarray], K: np.ndarray,
               Wx: np.ndarray, Wu: np.ndarray, u_max: np.ndarray | None,
               Y: np.ndarray) -> np.ndarray:
    X = Y[:, :-1]
    U = feedback_input(K, X, u_max)
    out = np.empty_like(Y)
    out[:, :-1] = f(X, U)
    out[:, -1] = np.einsum("ri,ij,rj->r", X, Wx, X) + np.einsum("ri,ij,rj->r", U, Wu, U)
    return out


def _step(f: Callable[[np.ndarray, np.ndarray], np.ndarray], K: np.ndarray, Wx: np.ndarray,
          Wu: np.ndarray, u_max: np.ndarray | None, y: np.ndarray, f0: np.ndarray,
          hh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One Dormand–Prince 5(4) step of size ``hh`` (per row) from ``y`` with slope ``f0``:
    the new state and the seven stages (7, R, n + 1)."""
    stages = np.empty((7, *y.shape))
    stages[0] = f0
    for s in range(1, 6):
        y_s = y + hh[:, None] * np.tensordot(_A[s, :s], stages[:s], axes=1)
        stages[s] = _augmented(f, K, Wx, Wu, u_max, y_s)
    y_new = y + hh[:, None] * np.tensordot(_B, stages[:6], axes=1)
    stages[6] = _augmented(f, K, Wx, Wu, u_max, y_new)
    return y_new, stages


def _settle_time(f: Callable[[np.ndarray, np.ndarray], np.ndarray], K: np.ndarray,
                 Wx: np.ndarray, Wu: np.ndarray, u_max: np.ndarray | None, y: np.ndarray,
                 f0: np.ndarray, hh: np.ndarray, level: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """First s ∈ (0, hh] with ‖x‖ ≤ level after a step of size s from ``y`` (the step of
    size hh ends there): bisection to 1e-13 of hh. Returns (s, state there)."""
    n = y.shape[1] - 1
    lo, hi = np.zeros_like(hh), hh.copy()
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        below = np.linalg.norm(_step(f, K, Wx, Wu, u_max, y, f0, mid)[0][:, :n], axis=1) \
            <= level
        hi, lo = np.where(below, mid, hi), np.where(below, lo, mid)
        if np.all(hi - lo <= 1e-13 * hh):
            break
    return hi, _step(f, K, Wx, Wu, u_max, y, f0, hi)[0]


def simulate(f: Callable[[np.ndarray, np.ndarray], np.ndarray], K: np.ndarray,
             X0: np.ndarray, Wx: np.ndarray, Wu: np.ndarray, u_max: np.ndarray | None,
             t_max: float, rtol: float = 1e-10, atol: float = 1e-12,
             max_steps: int = 100_000, x_bound: float = np.inf,
             groups: np.ndarray | None = None, group_cut: np.ndarray | None = None,
             settle: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Integrate R closed-loop rows from t = 0 to ``t_max``.

    Parameters
    ----------
    f : callable
        Vectorized plant f(X (R', n), U (R', m)) → Ẋ (R', n), called on subsets of rows.
    K : ndarray, shape (R, m, n)
        Gain of each row.
    X0 : ndarray, shape (R, n)
        Initial state of each row.
    Wx, Wu : ndarray, shapes (n, n), (m, m)
        Weights of the running cost.
    u_max : ndarray, shape (m,), or None
        Input limits (``None``: unsaturated).
    t_max : float
        Horizon T.
    rtol, atol : float
        Tolerances of the error test.
    max_steps : int
        Cap on trial steps per row.
    x_bound : float
        ‖x‖ above which a row is ``DIVERGED``.
    groups : ndarray of int, shape (R,), optional
        Group index of each row (e.g. the candidate), for the cutoff.
    group_cut : ndarray, shape (G,), optional
        The rows of group g stop with ``CUTOFF`` once the sum of their J exceeds
        ``group_cut[g]`` (``inf``: never).
    settle : ndarray, shape (R,), optional
        Settling levels: a row stops with ``SETTLED`` at the first time ‖x‖ ≤ its level
        (see the module docstring); ``None``: no event.

    Returns
    -------
    dict of ndarray
        ``cost`` (R,) J at the end, ``t_end`` (R,), ``x_final`` (R, n), ``status`` (R,) int,
        ``n_steps`` (R,) trial steps.
    """
    K = np.asarray(K, dtype=float)
    n_rows, n = np.shape(X0)
    Y = np.zeros((n_rows, n + 1))
    Y[:, :n] = X0
    t = np.zeros(n_rows)
    status = np.full(n_rows, HORIZON)
    steps = np.zeros(n_rows, dtype=int)
    running = np.ones(n_rows, dtype=bool)
    cut_on = groups is not None and group_cut is not None and np.any(np.isfinite(group_cut))
    if settle is not None:
        at_start = np.linalg.norm(Y[:, :n], axis=1) <= settle
        status[at_start] = SETTLED
        running[at_start] = False
    with np.errstate(all="ignore"):
        F0 = _augmented(f, K, Wx, Wu, u_max, Y)
        d0 = np.sqrt(np.mean((Y / (atol + rtol * np.abs(Y))) ** 2, axis=1))
        d1 = np.sqrt(np.mean((F0 / (atol + rtol * np.abs(Y))) ** 2, axis=1))
        h = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6, 0.01 * d0 / np.maximum(d1, 1e-300))
        h = np.minimum(h, t_max)
        while running.any():
            idx = np.flatnonzero(running)
            y, k_r, hh = Y[idx], K[idx], np.minimum(h[idx], t_max - t[idx])
            y_new, stages = _step(f, k_r, Wx, Wu, u_max, y, F0[idx], hh)
            scale = atol + rtol * np.maximum(np.abs(y), np.abs(y_new))
            err_vec = hh[:, None] * np.tensordot(_E, stages, axes=1) / scale
            err = np.sqrt(np.mean(err_vec ** 2, axis=1))
            finite = np.all(np.isfinite(y_new), axis=1) & np.all(np.isfinite(stages[6]), axis=1)
            steps[idx] += 1
            ok = finite & (err <= 1.0)
            acc = idx[ok]
            if settle is not None and acc.size:
                hit = ok & (np.linalg.norm(y_new[:, :n], axis=1) <= settle[idx])
                if hit.any():
                    rows = idx[hit]
                    hh[hit], y_new[hit] = _settle_time(f, k_r[hit], Wx, Wu, u_max, y[hit],
                                                       stages[0][hit], hh[hit], settle[rows])
                    status[rows] = SETTLED
                    running[rows] = False
            Y[acc], F0[acc] = y_new[ok], stages[6][ok]
            t[acc] = np.where(hh[ok] >= t_max - t[acc], t_max, t[acc] + hh[ok])
            grow = np.where(err[ok] == 0.0, 10.0, np.minimum(10.0, 0.9 * err[ok] ** -0.2))
            h[acc] = hh[ok] * grow
            shrink = np.where(finite, np.maximum(0.2, 0.9 * err ** -0.2), 0.2)[~ok]
            rej = idx[~ok]
            h[rej] = hh[~ok] * shrink
            tiny = h[rej] < 1e-14 * np.maximum(1.0, t[rej])
            status[rej[tiny]] = np.where(finite[~ok][tiny], STEP_FAILURE, NONFINITE)
            running[rej[tiny]] = False
            done = acc[t[acc] >= t_max]
            running[done] = False
            blown = acc[np.linalg.norm(Y[acc, :n], axis=1) > x_bound]
            status[blown] = DIVERGED
            running[blown] = False
            capped = idx[running[idx] & (steps[idx] >= max_steps)]
            status[capped] = STEP_FAILURE
            running[capped] = False
            if cut_on and acc.size:
                total = np.bincount(groups, weights=Y[:, n], minlength=group_cut.size)
                over = np.flatnonzero(total > group_cut)
                stop = running & np.isin(groups, over)
                status[stop] = CUTOFF
                running[stop] = False
    return {"cost": Y[:, n].copy(), "t_end": t, "x_final": Y[:, :n].copy(),
            "status": status, "n_steps": steps}


__all__ = ["CUTOFF", "DIVERGED", "HORIZON", "NONFINITE", "SETTLED", "STEP_FAILURE",
           "feedback_input", "simulate"]
