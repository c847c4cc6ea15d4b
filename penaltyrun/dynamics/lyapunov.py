"""Continuous Lyapunov equations of one matrix, one Schur decomposition for all of them.

The exact LQR gradient solves three Lyapunov equations with the same closed-loop matrix
A (or its transpose): the loop's cost matrix, its adjoint and the Riccati adjoint.
Bartels–Stewart (``scipy.linalg.solve_continuous_lyapunov``) spends most of its time on
the real Schur decomposition A = U T Uᵀ, which the three share: with it,

* A X + X Aᵀ = C becomes T Y + Y Tᵀ = Uᵀ C U,
* Aᵀ X + X A = C becomes Tᵀ Y + Y T = Uᵀ C U,

each one quasi-triangular Sylvester solve (LAPACK ``trsyl``), and X = U Y Uᵀ.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import get_lapack_funcs, schur


class SchurLyapunov:
    """Solver of A X + X Aᵀ = C and Aᵀ X + X A = C for one real square A.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Real matrix; the equations have a unique solution when no two eigenvalues of A
        sum to zero (e.g. A Hurwitz).
    """

    def __init__(self, A: np.ndarray) -> None:
        self.T, self.U = schur(np.asarray(A, dtype=float), output="real")
        self._trsyl = get_lapack_funcs("trsyl", (self.T,))

    def solve(self, C: np.ndarray, transpose: bool = False) -> np.ndarray:
        """X with A X + X Aᵀ = C, or Aᵀ X + X A = C when ``transpose``.

        Parameters
        ----------
        C : ndarray, shape (n, n)
        transpose : bool

        Returns
        -------
        ndarray, shape (n, n)

        Raises
        ------
        np.linalg.LinAlgError
            If LAPACK reports an invalid argument. A nearly singular equation (A and −A
            with close eigenvalues, LAPACK's info = 1) is solved with the perturbed values
            LAPACK uses, as scipy's ``solve_continuous_lyapunov`` accepts it too.
        """
        U = self.U
        F = U.T @ np.asarray(C, dtype=float) @ U
        if transpose:
            Y, scale, info = self._trsyl(self.T, self.T, F, trana="T", tranb="N")
        else:
            Y, scale, info = self._trsyl(self.T, self.T, F, trana="N", tranb="T")
        if info < 0:
            raise np.linalg.LinAlgError(f"trsyl: argument {-info} is invalid")
        return U @ (Y / scale) @ U.T


__all__ = ["SchurLyapunov"]
