"""Objective forms of the attitude problems: what the optimizer minimizes.

The recorded cost of a candidate is always J (or its graded penalty, see
:mod:`penaltyrun.problems.attitude.common`). The *objective form* (problem parameter
``objective_form``) decides the value handed to the optimizer:

``cost`` (default)
    The recorded cost itself.
``neg_reciprocal``
    The authors' companion-study objective (their public MATLAB code): ``−1/J`` when the
    terminal event fired, else the event function's value at the end of the run,
    ``d(t_end) − tol`` (a positive final error). Converged candidates are ordered as by J
    and every one of them beats every failure; failures are ordered by final distance
    alone. What changes is the *scale*: MATLAB's stall test compares the best value's
    change with ``FunctionTolerance · max(1, |f|)``, so with |−1/J| < 1 (J > 1) the test is
    absolute on −1/J and allows a change ΔJ ≈ tol · J², where a test on J allows
    tol · max(1, J).

A run stopped by the exact cutoff (status ``cutoff``, J at the cut above J's threshold)
gets ``−1/J_cut``: above the threshold's own ``−1/J`` and not above the value the finished
run would get (``−1/J_event ≥ −1/J_cut``, and a failure's value is positive). Thresholds
arrive in the optimizer's units and are converted by :func:`cost_thresholds`: a threshold
``f < 0`` is the value of a converged candidate with J = −1/f; a threshold ``f ≥ 0`` (a
failure's final error) can be beaten by a run of any energy, so nothing is cut.
"""

from __future__ import annotations

import numpy as np

from penaltyrun.dynamics import integrate

#: Objective forms (problem parameter ``objective_form``).
OBJECTIVE_FORMS = ("cost", "neg_reciprocal")


def optimizer_values(form: str, cost: np.ndarray, energy: np.ndarray, dist: np.ndarray,
                     tol: float, status: np.ndarray, ok: np.ndarray) -> np.ndarray | None:
    """Values the optimizer minimizes, or ``None`` when they are the recorded costs.

    Parameters
    ----------
    form : str
        One of :data:`OBJECTIVE_FORMS`.
    cost : ndarray, shape (R,)
        Recorded costs (J, or the graded / flat failure cost).
    energy : ndarray, shape (R,)
        J at the end of each run (N²·m²·s).
    dist : ndarray, shape (R,)
        Weighted event distance at the end of each run.
    tol : float
        Event threshold on that distance.
    status : ndarray of int, shape (R,)
        Integrator status codes.
    ok : ndarray of bool, shape (R,)
        Candidates that had a gain (the others keep their flat failure cost).

    Returns
    -------
    ndarray, shape (R,), or None
        ``neg_reciprocal``: ``−1/J`` (converged or cut), ``d − tol`` (horizon or step
        failure), and the recorded flat cost (non-finite runs, no gain: above every final
        error).
    """
    if form == "cost":
        return None
    if form != "neg_reciprocal":
        raise ValueError(f"unknown objective form {form!r}")
    energy = np.asarray(energy, dtype=float)
    reached = (status == integrate.EVENT) | (status == integrate.CUTOFF)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        neg_rec = -1.0 / np.maximum(energy, np.finfo(float).tiny)
        final_error = np.asarray(dist, dtype=float) - float(tol)
    value = np.where(reached, neg_rec, final_error)
    hard = ~ok | ~np.isfinite(value) | (status == integrate.NONFINITE)
    return np.where(hard, cost, value)


def cost_thresholds(form: str, thresholds: np.ndarray) -> np.ndarray:
    """Thresholds on J from thresholds in the optimizer's units (see the module docstring).

    Parameters
    ----------
    form : str
        One of :data:`OBJECTIVE_FORMS`.
    thresholds : ndarray, shape (B,)
        Values a candidate must beat (optimizer units; ``inf``: none).

    Returns
    -------
    ndarray, shape (B,)
        ``cost``: unchanged. ``neg_reciprocal``: ``−1/f`` where f < 0, ``inf`` elsewhere
        (NaN stays NaN, which cuts nothing).
    """
    thr = np.asarray(thresholds, dtype=float)
    if form == "cost":
        return thr
    with np.errstate(divide="ignore"):
        return np.where(thr < 0.0, -1.0 / thr, np.where(np.isnan(thr), np.nan, np.inf))


__all__ = ["OBJECTIVE_FORMS", "cost_thresholds", "optimizer_values"]
