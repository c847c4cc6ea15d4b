"""Low-thrust discretization spread of tuned matrices, for the main comparison tables.

The time of flight (or propellant) of a low-thrust transfer depends on the control-hold step
and the RK4 substeps. Every job re-evaluates its best K at the held-out
control steps and substep counts (``holdout`` column, scenario kinds ``control_step`` and
``substeps``, with the training run under ``training``). For one K:

    spread = max − min of its cost over the training run and those re-evaluations,

over the converged runs only (at least two). For min-time the cost of a converged run is
the time of flight in days, for min-fuel the propellant in kg: the same units as the
tables' savings. A cell (diagonal vs one full map of one optimizer) gets the larger of the
two maps' median spreads over their converged starts, and a full-vs-diagonal saving whose
magnitude is below it is labelled "within discretization noise".
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.io import decode_json

#: Held-out scenario kinds that change the discretization, not the transfer.
KINDS = ("control_step", "substeps")
WITHIN = "within discretization noise"
BEYOND = "beyond discretization spread"
UNKNOWN = "—"


def k_spread(holdout: Any) -> float:
    """Discretization spread of one K from its ``holdout`` record (JSON text or dict).

    Returns
    -------
    float
        max − min of the cost (days or kg) over the converged training run and converged
        control-step / substep re-evaluations; NaN with fewer than two such runs or
        without discretization scenarios (e.g. results written before they existed).
    """
    data = decode_json(holdout) if isinstance(holdout, str) else holdout
    if not data or "kind" not in data or "cost" not in data:
        return np.nan
    kinds = np.asarray(data["kind"])
    sel = np.isin(kinds, KINDS) & np.asarray(data["converged"], bool)
    if not sel.any():
        return np.nan
    costs = list(np.asarray(data["cost"], float)[sel])
    train = data.get("training") or {}
    if train.get("converged"):
        costs.append(float(train["cost"]))
    return float(np.ptp(costs)) if len(costs) >= 2 else np.nan


def map_spread(rows: pd.DataFrame) -> tuple[float, int]:
    """Median spread over the converged starts of one map, and how many starts had one.

    Parameters
    ----------
    rows : DataFrame
        Job rows of one map (columns ``best_converged`` and, where stored, ``holdout``).
    """
    if "holdout" not in rows or rows.empty:
        return np.nan, 0
    ok = rows[rows["best_converged"].fillna(False).astype(bool)]
    spreads = np.array([k_spread(h) for h in ok["holdout"] if h is not None
                        and not (isinstance(h, float) and np.isnan(h))], float)
    spreads = spreads[np.isfinite(spreads)]
    return (float(np.median(spreads)) if spreads.size else np.nan), int(spreads.size)


def cell_check(diag: pd.DataFrame, full: pd.DataFrame, saving: float) -> dict[str, Any]:
    """Discretization columns of one comparison row.

    Parameters
    ----------
    diag, full : DataFrame
        Job rows of the diagonal map and of the full map of the row.
    saving : float
        The row's full-vs-diagonal saving (days of ToF or kg of final mass).

    Returns
    -------
    dict
        ``discr. spread`` (larger of the two median spreads, days or kg), ``discr. K``
        (number of diagonal / full starts with a spread) and ``discr. verdict``.
    """
    sd, nd = map_spread(diag)
    sf, nf = map_spread(full)
    spread = np.nanmax([sd, sf]) if np.isfinite([sd, sf]).any() else np.nan
    if not (np.isfinite(spread) and np.isfinite(saving)):
        verdict = UNKNOWN
    else:
        verdict = WITHIN if abs(saving) < spread else BEYOND
    return {"discr. spread": spread, "discr. K (diag/full)": f"{nd}/{nf}",
            "discr. verdict": verdict}


__all__ = ["BEYOND", "KINDS", "UNKNOWN", "WITHIN", "cell_check", "k_spread", "map_spread"]
