"""Binary diagonal selector S: untargeted states drop out of a quadratic penalty.

The paper writes the penalty as (S e)ᵀ K (S e) with S = diag(s), s_i ∈ {0, 1}. With S on
both factors, any K (full or diagonal) ignores the untargeted error components entirely,
so the cost need not be re-derived when the targeted set changes.
"""

from __future__ import annotations

import numpy as np


def selector(targeted: np.ndarray) -> np.ndarray:
    """S = diag(targeted) as a float matrix; ``targeted`` is a boolean mask (N,)."""
    return np.diag(np.asarray(targeted, dtype=bool).astype(float))


def selected_quadratic(error: np.ndarray, K: np.ndarray, targeted: np.ndarray,
                       two_sided: bool = True) -> np.ndarray:
    """(S e)ᵀ K (S e) (``two_sided``) or eᵀ K (S e) for errors (..., N) and K (N, N)."""
    S = selector(targeted)
    se = error @ S
    left = se if two_sided else np.asarray(error, float)
    return np.einsum("...i,ij,...j->...", left, K, se)
