"""Batched test objectives shared by the optimizer tests (DE, PSO, MATLAB-faithful PSO):
the box [-1, 1]³, a sphere and an SPD-coupled quadratic with their minimum at ``CENTER``,
and a wrapper that records every batch an optimizer evaluates."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: The minimizer of :func:`sphere` and :func:`quadratic`, inside the box.
CENTER = np.array([0.3, -0.2, 0.5])
#: Lower and upper bounds of the box.
LB, UB = -np.ones(3), np.ones(3)
#: SPD coupling of :func:`quadratic`.
W = np.array([[2.0, 0.5, 0.0], [0.5, 1.0, 0.3], [0.0, 0.3, 4.0]])


def sphere(Z: np.ndarray) -> np.ndarray:
    """Squared distance of each row of ``Z`` (shape (B, 3)) to ``CENTER``; shape (B,)."""
    return ((Z - CENTER) ** 2).sum(axis=1)


def quadratic(Z: np.ndarray) -> np.ndarray:
    """(z − CENTER)ᵀ W (z − CENTER) for each row of ``Z`` (shape (B, 3)); shape (B,)."""
    D = Z - CENTER
    return np.einsum("bi,ij,bj->b", D, W, D)


class Recorder:
    """Batched objective that keeps a copy of every batch it was given."""

    def __init__(self, func: Callable[[np.ndarray], np.ndarray]) -> None:
        self.func = func
        self.batches: list[np.ndarray] = []

    def __call__(self, Z: np.ndarray) -> np.ndarray:
        self.batches.append(np.array(Z, copy=True))
        return self.func(Z)
