"""What ``best_cost`` holds for each problem, with its unit (for axis labels and tables)."""

from __future__ import annotations

from typing import Any

from penaltyrun.io import decode_json

#: problem → label of a converged start's cost.
COST_LABELS = {
    "zermelo": "J = ∫½‖u‖² dt (nondimensional)",
    "attitude_lqr": "J = ∫½‖u‖² dt (N²·m²·s)",
    "attitude_lyapunov": "J = ∫½‖u‖² dt (N²·m²·s)",
}
#: Low-thrust objective → label (``best_cost`` is ToF in days or propellant used in kg).
LOWTHRUST = ("qlaw", "lyapunov_transfer")
LOWTHRUST_LABELS = {"min_time": "time of flight (days)", "min_fuel": "propellant used (kg)"}


def cost_label(problem: str, problem_params: Any = None, case: str | None = None) -> str:
    """Axis label of a problem's cost, with its unit.

    Parameters
    ----------
    problem : str
        Problem name.
    problem_params : str or dict, optional
        The job's problem overrides (JSON text or dict); the low-thrust ``objective`` is
        read from them, else from the case's defaults.
    case : str, optional
        Problem case (for the defaults).
    """
    if problem in COST_LABELS:
        return COST_LABELS[problem]
    params = decode_json(problem_params) if isinstance(problem_params, str) else problem_params
    objective = (params or {}).get("objective")
    if objective is None and case is not None:
        try:
            from penaltyrun import problems

            objective = getattr(problems.make(problem, case, {}).params, "objective", None)
        except Exception:  # an unknown problem in old results keeps a generic label
            objective = None
    if objective is None and problem in LOWTHRUST:
        objective = "min_time"
    return LOWTHRUST_LABELS.get(objective or "", "best cost (problem units)")
