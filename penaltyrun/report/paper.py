"""Numbers the paper (arXiv 2504.16328) reports, for side-by-side comparison.

Only what the paper / its public review states is here; nothing is tuned to it.
"""

from __future__ import annotations

import numpy as np

#: Mean costs per (problem, case): {param: mean J}. ``full`` means GEAGSP.
MEAN_COST: dict[tuple[str, str], dict[str, float]] = {
    ("attitude_lqr", "detumble"): {"diagonal": 0.423, "full": 0.146},
    ("attitude_lqr", "rest_to_rest"): {"diagonal": 0.400, "full": 0.152},
    ("attitude_lyapunov", "detumble"): {"diagonal": 0.107, "full": 0.076},
    ("attitude_lyapunov", "rest_to_rest"): {"diagonal": 0.091, "full": 0.068},
}

#: Best matrices published for single runs.
BEST_MATRICES: dict[tuple[str, str], dict[str, dict[str, np.ndarray]]] = {
    ("zermelo", "default"): {
        "diagonal": {"K": np.diag([0.8094, 0.1611])},
        "full": {"K": np.array([[1.7421, 0.9560], [0.9560, 1.1414]])},
    },
}

#: Qualitative claims without per-case numbers in the public record.
CLAIMS: dict[str, str] = {
    "lyapunov_transfer": "full better in all five cases A–E; largest mean ToF savings "
                         "≈ 3.2 d (B) and ≈ 2.2 d (E)",
    "qlaw": "full better in every case; E*: ≈ 10.5 d ToF (min time) or ≈ 90 kg final mass "
            "(min fuel)",
}

FULL_KINDS = ("full", "geagsp", "givens", "cayley", "cayley_tan")


def paper_mean(problem: str, case: str, param: str) -> float:
    """The paper's mean cost for a cell (NaN where it reports none)."""
    cell = MEAN_COST.get((problem, case), {})
    key = "full" if param in ("full", "geagsp") else param
    return float(cell.get(key, np.nan))
