"""A cost with a known, non-diagonal optimum, shared by the API tests."""

from __future__ import annotations

import numpy as np

#: The minimizer of :func:`frobenius_cost`: symmetric positive definite, not diagonal.
K_STAR = np.array([[2.0, 0.8], [0.8, 1.0]])
#: Best cost a diagonal K can reach: the off-diagonal entries it cannot match, 2 · 0.8².
DIAGONAL_FLOOR = 2 * 0.8**2
#: A few hundred evaluations per start keep every run well under a second.
BUDGET = {"max_evals": 300}


def frobenius_cost(K):
    """J(K) = ‖K − K*‖_F², minimum 0 at K = K*."""
    return float(np.sum((K - K_STAR) ** 2))
