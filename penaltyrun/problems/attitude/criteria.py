"""The well-posed criteria of the attitude problems (see :mod:`penaltyrun.problems.criteria`).

In attitude terms, with the energy E(t) = ∫₀ᵗ ½ uᵀu dt (N²·m²·s) of the compiled kernel
(:mod:`penaltyrun.dynamics.attitude`, not modified here):

``time_energy``
    J = E(t_f) + ρ t_f, t_f the first time the weighted event distance
    ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ falls to ``tol``, searched up to ``free_time_cap``
    (default 10 000 s). ρ (``rho``) is in N²·m² (N²·m²·s per second; default 1e-3). A run
    that never arrives costs J(cap) + failure_penalty · (1 + d(cap) / d(0)); the exact
    cutoff compares E alone with the threshold (J ≥ E, so the bound stays exact).
``terminal``
    J = E(T) + x(T)ᵀ S x(T), T = ``t_max``, x = (q_v, ω) (the feedback's state; q0 follows
    from |q| = 1 up to the sign of the double cover), the event switched off (the kernel
    runs with a negative tolerance, so its event can never fire). S (``terminal_weight``)
    is in N²·m²·s per unit of x² (q_v dimensionless, ω in rad/s); the default
    S = diag(w_qv², w_qv², w_qv², w_ω², w_ω², w_ω²) / tol² makes a state on the event
    sphere (with q0 = 1) cost 1 N²·m²·s, about the paper's optimal energies. The runs go
    through the kernel's ``final_state`` one by one; the exact cutoff is not used.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import attitude as kernel
from penaltyrun.dynamics import integrate
from penaltyrun.problems import criteria
from penaltyrun.problems.attitude.reference import graded_cost

#: Default ρ of ``time_energy`` (N²·m²): one second costs as much as 1e-3 N²·m²·s of energy.
DEFAULT_RHO = 1e-3
#: Event tolerance that switches the kernel's event off (distances are ≥ 0).
NO_EVENT = -1.0


def terminal_weight(params: Any) -> np.ndarray:
    """S (6 × 6) of ``terminal`` on x = (q_v, ω): ``terminal_weight`` or the default
    diag(w_qv² I₃, w_ω² I₃) / tol² (N²·m²·s per unit of x²)."""
    if params.terminal_weight is not None:
        return criteria.terminal_matrix(params.terminal_weight, 6, "problem.terminal_weight")
    _, wq, ww = params.event_weights()
    return np.diag([wq ** 2] * 3 + [ww ** 2] * 3) / float(params.tol) ** 2


def terminal_runs(problem: Any, G: np.ndarray, y0: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Runs to ``t_max`` with the event off, paired as in
    :func:`penaltyrun.dynamics.attitude.simulate_batch` (B or S may be 1).

    Returns
    -------
    t_end : ndarray, shape (R,)
        ``t_max`` unless a run failed earlier (s).
    y_end : ndarray, shape (R, 8)
        (q, ω, E) at ``t_end``.
    status : ndarray of int, shape (R,)
        Kernel status codes (``HORIZON`` for a completed run).
    """
    p = problem.params
    n = max(G.shape[0], y0.shape[0])
    t_end = np.empty(n)
    y_end = np.empty((n, kernel.N_STATE))
    status = np.empty(n, dtype=np.int64)
    for r in range(n):
        g = np.ascontiguousarray(G[r if G.shape[0] > 1 else 0], dtype=float)
        y = np.ascontiguousarray(y0[r if y0.shape[0] > 1 else 0], dtype=float)
        t_end[r], y_end[r], status[r] = kernel.final_state(
            g, y, problem.inertia, problem.inertia_inv, float(p.t_max), NO_EVENT,
            p.saturation(), float(p.rtol), float(p.atol), float(p.max_step),
            float(p.event_spacing), int(p.n_event_samples), int(p.max_steps),
            *p.event_weights())
    return t_end, y_end, status


def finish(problem: Any, G: np.ndarray, ok: np.ndarray, y0: np.ndarray | None, d0: Any,
           cutoff: np.ndarray | None) -> dict[str, np.ndarray]:
    """Per-run results of a well-posed criterion (the ``deadline`` path stays in
    :meth:`~penaltyrun.problems.attitude.common.AttitudeProblem._finish`).

    Parameters
    ----------
    problem : AttitudeProblem
    G : ndarray, shape (B, 3, 6)
        Gains (zero where ``ok`` is False).
    ok : ndarray of bool, shape (B,)
    y0 : ndarray, shape (S, 7) or None
        Initial states (None: the problem's).
    d0 : float or ndarray, shape (R,)
        Initial event distances.
    cutoff : ndarray, shape (B,) or None
        Kernel cutoffs on E (``time_energy`` only).

    Returns
    -------
    dict
        ``cost`` (before the no-gain override), ``energy``, ``t_final``,
        ``final_distance`` and ``status`` (kernel codes; a completed ``terminal`` run is
        ``EVENT``, i.e. ``converged``), and ``terminal_cost`` (``terminal``; else zeros).
    """
    p = problem.params
    y_start = problem.y0[None] if y0 is None else y0
    if p.criterion == criteria.TIME_ENERGY:
        t_end, energy, dist, status = problem.run(G, y0, cutoff, t_max=p.free_time_cap)
        value = criteria.time_energy_cost(energy, t_end, p.rho)
        term = np.zeros_like(energy)
    else:
        t_end, y_end, status = terminal_runs(problem, G, y_start)
        energy = y_end[:, 7]
        dist = p.event_distance(y_end)
        term = criteria.terminal_cost(y_end[:, 1:7], terminal_weight(p))
        value = energy + term
        status = np.where(status == integrate.HORIZON, integrate.EVENT, status)
    cost = graded_cost(value, dist, d0, status, p.failure_penalty)
    return {"cost": cost, "energy": energy, "t_final": t_end, "final_distance": dist,
            "status": status, "terminal_cost": term}


def detail(params: Any, res: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """Keys ``evaluate`` adds under a well-posed criterion (none for ``deadline``):
    ``criterion``, ``horizon`` (s, how long a run may last), and ``rho`` with
    ``arrival_time`` (s, NaN if not arrived), or ``terminal_S`` (S, 6×6) with
    ``terminal_cost`` (x(T)ᵀ S x(T), N²·m²·s); ``res`` holds per-run arrays of one run."""
    if params.criterion == criteria.DEADLINE:
        return {}
    out: dict[str, Any] = {"criterion": params.criterion,
                           "horizon": criteria.run_horizon(params)}
    if params.criterion == criteria.TIME_ENERGY:
        out["rho"] = float(params.rho)
        out["arrival_time"] = float(res["t_final"][0]) if res["converged"][0] \
            else float("nan")
    else:
        out["terminal_S"] = terminal_weight(params).tolist()
        out["terminal_cost"] = float(res["terminal_cost"][0])
    return out


__all__ = ["DEFAULT_RHO", "NO_EVENT", "detail", "finish", "terminal_runs", "terminal_weight"]
