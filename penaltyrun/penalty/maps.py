"""Parameterizations: decision vector z in a box → symmetric positive-definite matrix K.

* ``diagonal``: K = diag(z), N variables.
* ``geagsp`` (alias ``full``), ``givens``, ``cayley``, ``cayley_tan``: z = (λ_1..λ_N,
  angles_1..angles_M), K = Q diag(λ) Qᵀ with Q from :mod:`penaltyrun.penalty.orthogonal`;
  N + N(N−1)/2 variables. ``cayley_tan`` is the Cayley map with skew entries tan θ,
  θ ∈ [−(π/2 − 0.01), π/2 − 0.01] (the authors' companion study).

Every map is a pure function of z and decodes whole batches: ``decode(Z)`` with Z of shape
(B, dim) returns (B, N, N); a single vector (dim,) returns (N, N).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.penalty import derivatives as deriv
from penaltyrun.penalty import orthogonal as orth
from penaltyrun.typed import is_int

KINDS = ("diagonal", "full", "geagsp", "givens", "cayley", "cayley_tan")
ALIASES = {"full": "geagsp"}
#: Margin m of the Cayley-tan angles, θ ∈ [−(π/2 − m), π/2 − m] (entries |tan θ| ≤ ≈ 100).
CAYLEY_TAN_MARGIN = 0.01


@dataclass(frozen=True)
class Parameterization:
    """A map from a box of decision variables to N × N SPD matrices.

    Attributes
    ----------
    kind : str
        ``diagonal``, ``geagsp``, ``givens``, ``cayley`` or ``cayley_tan`` (``full`` is
        resolved to ``geagsp`` by :func:`make`).
    n : int
        Matrix dimension N.
    eig_bounds : tuple of float
        (lower, upper) bounds of the eigenvalues, 0 < lower < upper.
    cayley_bound : float
        Bound b of the Cayley skew entries, each in [−b, b] (``cayley`` only; the
        ``cayley_tan`` box is fixed by :data:`CAYLEY_TAN_MARGIN`).
    """

    kind: str
    n: int
    eig_bounds: tuple[float, float]
    cayley_bound: float = 100.0

    @property
    def n_angles(self) -> int:
        """Number of orthogonal-matrix variables (0 for diagonal)."""
        return 0 if self.kind == "diagonal" else orth.n_angles(self.n)

    @property
    def dim(self) -> int:
        """Number of decision variables."""
        return self.n + self.n_angles

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of z, each of shape (dim,)."""
        lo, hi = self.eig_bounds
        lb = [np.full(self.n, float(lo))]
        ub = [np.full(self.n, float(hi))]
        if self.kind == "geagsp":
            alb, aub = orth.geagsp_angle_bounds(self.n)
        elif self.kind == "givens":
            alb, aub = np.full(self.n_angles, -np.pi), np.full(self.n_angles, np.pi)
        elif self.kind == "cayley":
            b = float(self.cayley_bound)
            alb, aub = np.full(self.n_angles, -b), np.full(self.n_angles, b)
        elif self.kind == "cayley_tan":
            b = 0.5 * np.pi - CAYLEY_TAN_MARGIN
            alb, aub = np.full(self.n_angles, -b), np.full(self.n_angles, b)
        else:
            alb = aub = np.zeros(0)
        return np.concatenate(lb + [alb]), np.concatenate(ub + [aub])

    def orthogonal(self, Z: np.ndarray) -> np.ndarray:
        """Q for a batch of decision vectors (B, dim) → (B, N, N)."""
        Z = np.atleast_2d(np.asarray(Z, float))
        angles = np.ascontiguousarray(Z[:, self.n:])
        if self.kind == "diagonal":
            return np.broadcast_to(np.eye(self.n), (Z.shape[0], self.n, self.n)).copy()
        if self.kind == "geagsp":
            return orth.geagsp_batch(angles, self.n)
        if self.kind == "givens":
            return orth.givens_batch(angles, self.n)
        if self.kind == "cayley_tan":
            return orth.cayley_batch(np.tan(angles), self.n)
        return orth.cayley_batch(angles, self.n)

    def decode(self, Z: np.ndarray) -> np.ndarray:
        """K = Q diag(λ) Qᵀ for z (dim,) → (N, N) or a batch (B, dim) → (B, N, N)."""
        Z = np.asarray(Z, float)
        single = Z.ndim == 1
        Zb = np.atleast_2d(Z)
        if Zb.shape[1] != self.dim:
            raise ValueError(f"{self.kind} (N={self.n}) expects {self.dim} variables, "
                             f"got {Zb.shape[1]}")
        lam = Zb[:, : self.n]
        if self.kind == "diagonal":
            K = lam[:, :, None] * np.eye(self.n)[None]
        else:
            Q = self.orthogonal(Zb)
            K = (Q * lam[:, None, :]) @ np.transpose(Q, (0, 2, 1))
            K = 0.5 * (K + np.transpose(K, (0, 2, 1)))
        return K[0] if single else K

    def skip_margin(self, Z: np.ndarray) -> np.ndarray:
        """Distance of decision vectors from a discontinuity of the map.

        GEAGSP only (:func:`penaltyrun.penalty.orthogonal.geagsp_skip_margin`: the smallest
        distance of a Gram–Schmidt residual norm from the skip threshold); the other maps are
        continuous on the whole box and return inf.

        Parameters
        ----------
        Z : ndarray, shape (B, dim) or (dim,)

        Returns
        -------
        ndarray, shape (B,) or float
        """
        Zb = np.atleast_2d(np.asarray(Z, float))
        if self.kind == "geagsp":
            margins = orth.geagsp_skip_margin(np.ascontiguousarray(Zb[:, self.n:]), self.n)
        else:
            margins = np.full(Zb.shape[0], np.inf)
        return float(margins[0]) if np.ndim(Z) == 1 else margins

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """Exact Jacobian of the decode at one decision vector.

        Parameters
        ----------
        z : ndarray, shape (dim,)

        Returns
        -------
        ndarray, shape (dim, N, N)
            Slice i is ∂K/∂z_i (symmetric): q_i q_iᵀ for an eigenvalue, Q(Ω Λ − Λ Ω)Qᵀ
            with Ω = Qᵀ ∂Q/∂z_i for an angle (see :mod:`penaltyrun.penalty.derivatives`).

        Raises
        ------
        NotDifferentiableError
            GEAGSP at (or within a factor 2 of) a skipped Gram–Schmidt vector, where the
            map is discontinuous. The other maps are differentiable on the whole box.
        """
        return deriv.jacobian(self, z)

    def vjp(self, z: np.ndarray, G: np.ndarray) -> np.ndarray:
        """Gradient with respect to z of a scalar f(K) from G = ∂f/∂K.

        Computes ``grad_i = Σ_ab G_ab ∂K_ab/∂z_i`` without forming the Jacobian (O(N³)
        for Givens and Cayley, O(N⁴) for GEAGSP, O(N) for diagonal).

        Parameters
        ----------
        z : ndarray, shape (dim,)
        G : ndarray, shape (N, N)
            ∂f/∂K_ab with all N² entries of K treated as independent. G need not be
            symmetric: only (G + Gᵀ)/2 matters, since K is symmetric. A gradient with
            respect to the N(N+1)/2 free entries of a symmetric K must first be turned
            into this form (halve the off-diagonal entries, mirror them).

        Returns
        -------
        ndarray, shape (dim,)

        Raises
        ------
        NotDifferentiableError
            As for :meth:`jacobian`.
        """
        return deriv.vjp(self, z, G)

    def encode(self, K: np.ndarray) -> np.ndarray:
        """A decision vector z with decode(z) = K (inverse map).

        Raises
        ------
        ValueError
            If K is not representable (diagonal map and non-diagonal K; eigenvalues or
            Cayley entries / Cayley-tan angles outside the bounds).
        """
        K = np.asarray(K, float)
        if self.kind == "diagonal":
            if not np.allclose(K, np.diag(np.diag(K)), atol=1e-12 * np.abs(K).max()):
                raise ValueError("diagonal parameterization cannot represent a non-diagonal K")
            lam, angles = np.diag(K).copy(), np.zeros(0)
        else:
            lam, Q = orth.proper_eigenvectors(K, prefer_positive_diagonal=True)
            if self.kind == "geagsp":
                angles = orth.geagsp_inverse(Q)
            elif self.kind == "givens":
                angles = orth.givens_inverse(Q)
            elif self.kind == "cayley_tan":
                angles = np.arctan(orth.cayley_inverse(Q))
            else:
                angles = orth.cayley_inverse(Q)
        z = np.concatenate([lam, angles])
        lb, ub = self.bounds()
        tol = 1e-9 * np.maximum(1.0, np.abs(ub))
        if np.any(z < lb - tol) or np.any(z > ub + tol):
            raise ValueError(f"K is outside the {self.kind} box (eigenvalues or angles)")
        return np.clip(z, lb, ub)


def make(kind: str, n: int, eig_bounds: tuple[float, float], cayley_bound: float = 100.0,
         key: str = "param.name") -> Parameterization:
    """Build a parameterization, validating its settings.

    Parameters
    ----------
    kind : str
        One of :data:`KINDS` (``"full"``, ``"diagonal"``, ``"givens"``, ``"cayley"``, ...).
    n : int
        Size of the n × n matrix.
    eig_bounds : (float, float)
        Bounds (lower, upper) of its eigenvalues, 0 < lower < upper.
    cayley_bound : float
        Box half-width of the Cayley map's skew entries (``kind="cayley"``).
    key : str
        Config key named in the error of an unknown ``kind``.

    Returns
    -------
    Parameterization

    Raises
    ------
    ConfigError
        Unknown kind, a size ``n`` that is not a positive integer, or bounds that do not
        satisfy 0 < lower < upper.
    """
    if kind not in KINDS:
        raise ConfigError(key, f"unknown parameterization {kind!r}", allowed=KINDS)
    if not is_int(n, any_integral=True) or n < 1:
        raise ConfigError("n", f"the matrix size must be a positive integer, got {n!r}")
    try:
        lo, hi = (float(b) for b in eig_bounds)
    except (TypeError, ValueError):
        raise ConfigError("param.eig_bounds", f"need two numbers [lower, upper], got "
                          f"{eig_bounds!r}") from None
    if not (0.0 < lo < hi and np.isfinite(hi)):
        raise ConfigError("param.eig_bounds",
                          f"need 0 < lower < upper < inf for a PD matrix, got [{lo}, {hi}]")
    if not cayley_bound > 0.0:
        raise ConfigError("param.cayley_bound", f"must be > 0, got {cayley_bound}")
    return Parameterization(ALIASES.get(kind, kind), int(n), (lo, hi), float(cayley_bound))
