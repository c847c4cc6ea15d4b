"""Decision-vector layout: several parameterized matrices plus extra scalars in one box.

z = [z_matrix_1 | z_matrix_2 | … | scalar_1 | …]; the optimizer sees one box, the problem
sees named matrices and scalars.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from penaltyrun.penalty.maps import Parameterization


@dataclass(frozen=True)
class DecisionLayout:
    """Named blocks of a decision vector.

    Attributes
    ----------
    matrices : tuple of (name, Parameterization)
    scalars : tuple of (name, (lower, upper))
    """

    matrices: tuple[tuple[str, Parameterization], ...]
    scalars: tuple[tuple[str, tuple[float, float]], ...] = ()

    @property
    def dim(self) -> int:
        """Total number of decision variables."""
        return sum(p.dim for _, p in self.matrices) + len(self.scalars)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds (dim,) of the whole box."""
        lbs, ubs = [], []
        for _, p in self.matrices:
            lb, ub = p.bounds()
            lbs.append(lb)
            ubs.append(ub)
        lbs.append(np.array([float(b[0]) for _, b in self.scalars]))
        ubs.append(np.array([float(b[1]) for _, b in self.scalars]))
        return np.concatenate(lbs), np.concatenate(ubs)

    def names(self) -> list[str]:
        """One label per decision variable, e.g. ``K.lam1``, ``K.ang2``, ``eta_cut``."""
        out: list[str] = []
        for name, p in self.matrices:
            out += [f"{name}.lam{i + 1}" for i in range(p.n)]
            out += [f"{name}.ang{i + 1}" for i in range(p.n_angles)]
        out += [name for name, _ in self.scalars]
        return out

    def split(self, Z: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
        """Decode a batch Z (B, dim) into matrices {name: (B, N, N)} and scalars {name: (B,)}."""
        Z = np.atleast_2d(np.asarray(Z, float))
        if Z.shape[1] != self.dim:
            raise ValueError(f"expected {self.dim} decision variables, got {Z.shape[1]}")
        mats: dict[str, np.ndarray] = {}
        pos = 0
        for name, p in self.matrices:
            mats[name] = p.decode(Z[:, pos:pos + p.dim])
            pos += p.dim
        scalars = {name: Z[:, pos + i].copy() for i, (name, _) in enumerate(self.scalars)}
        return mats, scalars

    def skip_margin(self, Z: np.ndarray) -> np.ndarray:
        """Smallest distance from a discontinuity of a map over the matrix blocks.

        See :meth:`~penaltyrun.penalty.maps.Parameterization.skip_margin` (inf where every
        map is continuous).

        Parameters
        ----------
        Z : ndarray, shape (B, dim)

        Returns
        -------
        ndarray, shape (B,)
        """
        Z = np.atleast_2d(np.asarray(Z, float))
        if Z.shape[1] != self.dim:
            raise ValueError(f"expected {self.dim} decision variables, got {Z.shape[1]}")
        margins, pos = np.full(Z.shape[0], np.inf), 0
        for _, p in self.matrices:
            margins = np.minimum(margins, p.skip_margin(Z[:, pos:pos + p.dim]))
            pos += p.dim
        return margins

    def vjp(self, z: np.ndarray, mat_grads: dict[str, np.ndarray],
            scalar_grads: dict[str, float] | None = None) -> np.ndarray:
        """Gradient with respect to the whole decision vector z (dim,).

        Parameters
        ----------
        z : ndarray, shape (dim,)
        mat_grads : dict of str to ndarray (N, N)
            ∂f/∂K for each matrix, in the convention of
            :meth:`~penaltyrun.penalty.maps.Parameterization.vjp`; a missing name counts as 0.
        scalar_grads : dict of str to float, optional
            ∂f/∂s for the extra scalars (missing → 0).

        Returns
        -------
        ndarray, shape (dim,)

        Raises
        ------
        NotDifferentiableError
            If one of the maps has no derivative at its block of z.
        """
        z = np.asarray(z, float)
        if z.shape != (self.dim,):
            raise ValueError(f"expected z of shape ({self.dim},), got {z.shape}")
        parts, pos = [], 0
        for name, p in self.matrices:
            G = mat_grads.get(name)
            parts.append(np.zeros(p.dim) if G is None else p.vjp(z[pos:pos + p.dim], G))
            pos += p.dim
        parts.append(np.array([float((scalar_grads or {}).get(name, 0.0))
                               for name, _ in self.scalars]))
        return np.concatenate(parts)

    def join(self, mats: dict[str, np.ndarray], scalars: dict[str, float] | None = None
             ) -> np.ndarray:
        """Encode single matrices (N, N) and scalars into one decision vector (dim,)."""
        parts = [p.encode(mats[name]) for name, p in self.matrices]
        parts.append(np.array([float((scalars or {})[name]) for name, _ in self.scalars]))
        return np.concatenate(parts)


def build_layout(specs: Sequence[tuple[str, Parameterization]],
                 scalars: Sequence[tuple[str, tuple[float, float]]] = ()) -> DecisionLayout:
    """Convenience constructor from sequences."""
    return DecisionLayout(tuple(specs), tuple(scalars))
