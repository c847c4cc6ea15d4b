"""Orthogonal-matrix maps from angle vectors (batched, compiled).

Three maps from M = N(N−1)/2 numbers to an orthogonal N × N matrix Q:

* GEAGSP (generalised Euler angles + Gram–Schmidt), the paper's choice;
* Givens: Q = G_1 ⋯ G_M over the planes (j, i), j = 1..N−1, i = j+1..N;
* Cayley: Q = (I − C)(I + C)⁻¹ with C skew-symmetric.

Each ``*_batch`` function takes ``angles`` of shape (B, M) and returns Q of shape
(B, N, N). Inverse maps (Q → angles) are given for round trips.

GEAGSP basis construction (deterministic, documented so that the same angles give the same
K on every machine): the basis B_i of the orthogonal complement of the columns already
placed is built by classical Gram–Schmidt (applied twice) of the standard basis vectors
e_1, …, e_N, in that order, against the placed columns and the basis vectors already
accepted; a candidate whose residual norm is below ``GS_SKIP`` is skipped. Column i of Q is
B_i · v(row i); column N is the single remaining basis vector.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: Residual norm under which a standard basis vector is skipped in Gram–Schmidt.
GS_SKIP = 1e-6


def n_angles(n: int) -> int:
    """Number of angles M = N(N−1)/2 of an N × N orthogonal matrix."""
    return n * (n - 1) // 2


def geagsp_angle_bounds(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the GEAGSP angles: [0, π] except the last angle of each row, [0, 2π]."""
    lb = np.zeros(n_angles(n))
    ub = np.full(n_angles(n), np.pi)
    pos = 0
    for row in range(1, n):
        k = n - row
        ub[pos + k - 1] = 2.0 * np.pi
        pos += k
    return lb, ub


@njit(cache=True)
def _hypersphere(phi, out):
    """Unit vector of k angles in R^{k+1} (v_1 = cos φ_1, …, v_{k+1} = Π sin φ_j)."""
    k = phi.shape[0]
    s = 1.0
    for j in range(k):
        out[j] = s * np.cos(phi[j])
        s *= np.sin(phi[j])
    out[k] = s


@njit(cache=True)
def _complement_basis_margin(Qcols, n_placed, n, out):
    """Orthonormal basis (columns of ``out``) of the complement of Qcols[:, :n_placed].

    Returns the number of basis vectors found (n − n_placed unless degenerate) and the skip
    margin: the smallest |r − GS_SKIP| over the residual norms r of the standard basis
    vectors examined, accepted or skipped (how far the nearest of them is from changing
    the set of vectors the construction keeps).
    """
    need = n - n_placed
    found = 0
    margin = np.inf
    r = np.empty(n)
    for j in range(n):
        if found == need:
            break
        r[:] = 0.0
        r[j] = 1.0
        for _ in range(2):
            for c in range(n_placed):
                dot = 0.0
                for m in range(n):
                    dot += Qcols[m, c] * r[m]
                for m in range(n):
                    r[m] -= dot * Qcols[m, c]
            for c in range(found):
                dot = 0.0
                for m in range(n):
                    dot += out[m, c] * r[m]
                for m in range(n):
                    r[m] -= dot * out[m, c]
        nrm = np.sqrt(np.sum(r * r))
        margin = min(margin, abs(nrm - GS_SKIP))
        if nrm > GS_SKIP:
            for m in range(n):
                out[m, found] = r[m] / nrm
            found += 1
    return found, margin


@njit(cache=True)
def _complement_basis(Qcols, n_placed, n, out):
    """Orthonormal basis (columns of ``out``) of the complement of Qcols[:, :n_placed].

    Returns the number of basis vectors found (n − n_placed unless degenerate).
    """
    found, _ = _complement_basis_margin(Qcols, n_placed, n, out)
    return found


@njit(cache=True)
def _geagsp_batch_margin(angles, n):
    """GEAGSP map and skip margin for a batch: angles (B, M) → Q (B, n, n), margin (B,).

    The margin of a decision vector is the smallest skip margin of its Gram–Schmidt steps
    (see :func:`_complement_basis_margin`): the map is discontinuous where it reaches 0.
    """
    B = angles.shape[0]
    Q = np.zeros((B, n, n))
    margins = np.full(B, np.inf)
    basis = np.empty((n, n))
    v = np.empty(n)
    for b in range(B):
        Qb = Q[b]
        pos = 0
        for col in range(n - 1):
            k = n - 1 - col
            _hypersphere(angles[b, pos:pos + k], v[: k + 1])
            pos += k
            if col == 0:
                for m in range(n):
                    Qb[m, 0] = v[m]
            else:
                _, margin = _complement_basis_margin(Qb, col, n, basis)
                margins[b] = min(margins[b], margin)
                for m in range(n):
                    acc = 0.0
                    for c in range(k + 1):
                        acc += basis[m, c] * v[c]
                    Qb[m, col] = acc
        _, margin = _complement_basis_margin(Qb, n - 1, n, basis)
        margins[b] = min(margins[b], margin)
        for m in range(n):
            Qb[m, n - 1] = basis[m, 0]
    return Q, margins


@njit(cache=True)
def geagsp_batch(angles, n):
    """GEAGSP map for a batch: angles (B, M) → Q (B, n, n)."""
    Q, _ = _geagsp_batch_margin(angles, n)
    return Q


def geagsp_skip_margin(angles: np.ndarray, n: int) -> np.ndarray:
    """Distance of GEAGSP decision vectors from the map's discontinuities.

    Each Gram–Schmidt step keeps a standard basis vector whose residual norm r exceeds
    :data:`GS_SKIP` and skips it otherwise, so Q jumps where some r crosses that threshold.
    The margin is the smallest |r − GS_SKIP| over every residual the construction examines.
    Next to the pole of the first angle φ of a row, r = |sin φ|, so a margin m puts a jump
    about m radians away. For random angles it shrinks quickly as N grows, because the
    Gram–Schmidt residuals shrink from column to column.

    Parameters
    ----------
    angles : ndarray, shape (B, M) or (M,)
        GEAGSP angles, M = n(n − 1)/2 (rad).
    n : int
        Matrix dimension.

    Returns
    -------
    ndarray, shape (B,) or scalar float
        The margins (dimensionless, like the residual norms).
    """
    A = np.asarray(angles, dtype=float)
    single = A.ndim == 1
    _, margins = _geagsp_batch_margin(np.ascontiguousarray(np.atleast_2d(A)), int(n))
    return float(margins[0]) if single else margins


@njit(cache=True)
def givens_batch(angles, n):
    """Givens map for a batch: angles (B, M) → Q = G_1 ⋯ G_M, shape (B, n, n).

    Works on Qᵀ (each rotation mixes two contiguous rows) and transposes at the end.
    """
    B = angles.shape[0]
    Q = np.zeros((B, n, n))
    Qt = np.empty((n, n))
    for b in range(B):
        for m in range(n):
            for j in range(n):
                Qt[m, j] = 1.0 if m == j else 0.0
        pos = 0
        for j in range(n - 1):
            for i in range(j + 1, n):
                c = np.cos(angles[b, pos])
                s = np.sin(angles[b, pos])
                pos += 1
                for m in range(n):
                    a_j = Qt[j, m]
                    a_i = Qt[i, m]
                    Qt[j, m] = c * a_j - s * a_i
                    Qt[i, m] = s * a_j + c * a_i
        for m in range(n):
            for j in range(n):
                Q[b, m, j] = Qt[j, m]
    return Q


def skew_from_entries(entries: np.ndarray, n: int) -> np.ndarray:
    """Skew-symmetric matrices (B, n, n) from their upper-triangle entries (B, M), row-major."""
    entries = np.atleast_2d(entries)
    C = np.zeros((entries.shape[0], n, n))
    iu = np.triu_indices(n, 1)
    C[:, iu[0], iu[1]] = entries
    return C - np.transpose(C, (0, 2, 1))


def cayley_batch(entries: np.ndarray, n: int) -> np.ndarray:
    """Cayley map for a batch: upper entries of C (B, M) → Q = (I − C)(I + C)⁻¹."""
    C = skew_from_entries(entries, n)
    eye = np.eye(n)
    return np.linalg.solve(eye + C, eye - C)  # (I + C)⁻¹ and (I − C) commute


def _hypersphere_inverse(v: np.ndarray) -> np.ndarray:
    """Angles φ of a unit vector v ∈ R^{k+1} (inverse of the hyperspherical map)."""
    k = v.size - 1
    phi = np.empty(k)
    for j in range(k - 1):
        phi[j] = np.arctan2(np.linalg.norm(v[j + 1:]), v[j])
    phi[k - 1] = np.mod(np.arctan2(v[k], v[k - 1]), 2.0 * np.pi)
    return phi


def geagsp_inverse(Q: np.ndarray) -> np.ndarray:
    """GEAGSP angles reproducing the columns 1..N−1 of orthogonal Q (column N up to sign)."""
    n = Q.shape[0]
    angles = []
    basis = np.empty((n, n))
    for col in range(n - 1):
        if col == 0:
            coords = Q[:, 0]
        else:
            _complement_basis(np.ascontiguousarray(Q), col, n, basis)
            coords = basis[:, : n - col].T @ Q[:, col]
        coords = coords / np.linalg.norm(coords)
        angles.append(_hypersphere_inverse(coords))
    return np.concatenate(angles) if angles else np.zeros(0)


def givens_inverse(Q: np.ndarray) -> np.ndarray:
    """Givens angles θ with G_1 ⋯ G_M = Q for a rotation Q (det Q = +1)."""
    n = Q.shape[0]
    Mx = np.array(Q, dtype=float)
    angles = []
    for j in range(n - 1):
        for i in range(j + 1, n):
            theta = np.arctan2(-Mx[i, j], Mx[j, j])
            c, s = np.cos(theta), np.sin(theta)
            row_j = c * Mx[j] - s * Mx[i]
            row_i = s * Mx[j] + c * Mx[i]
            Mx[j], Mx[i] = row_j, row_i
            angles.append(theta)
    return np.array(angles)


def cayley_inverse(Q: np.ndarray) -> np.ndarray:
    """Upper entries of C = (I − Q)(I + Q)⁻¹ for a rotation Q without eigenvalue −1."""
    n = Q.shape[0]
    eye = np.eye(n)
    C = np.linalg.solve(eye + Q, eye - Q)  # the two factors commute
    return C[np.triu_indices(n, 1)]


def proper_eigenvectors(K: np.ndarray, prefer_positive_diagonal: bool = False) -> tuple:
    """Eigen-decomposition K = Q diag(λ) Qᵀ with det Q = +1.

    Parameters
    ----------
    K : ndarray, shape (N, N)
        Symmetric matrix.
    prefer_positive_diagonal : bool
        Flip column signs so that diag(Q) ≥ 0 where possible (keeps Q away from
        eigenvalue −1, as the Cayley inverse needs).

    Returns
    -------
    lam : ndarray (N,), Q : ndarray (N, N)
    """
    lam, Q = np.linalg.eigh(np.asarray(K, float))
    if prefer_positive_diagonal:
        # Assign eigenvectors to the coordinate axes they align with best, so that a
        # (near-)diagonal K gives Q ≈ I rather than a permutation.
        order = _alignment_order(Q)
        lam, Q = lam[order], Q[:, order]
        Q = Q * np.where(np.diag(Q) < 0.0, -1.0, 1.0)
    if np.linalg.det(Q) < 0.0:
        weakest = int(np.argmin(np.abs(np.diag(Q))))
        Q[:, weakest] = -Q[:, weakest]
    return lam, Q


def _alignment_order(Q: np.ndarray) -> np.ndarray:
    """Column order that puts on the diagonal the largest available |Q_ij| (greedy)."""
    n = Q.shape[0]
    A = np.abs(Q)
    order = np.empty(n, dtype=int)
    free_rows, free_cols = set(range(n)), set(range(n))
    for _ in range(n):
        best = max((A[r, c], r, c) for r in free_rows for c in free_cols)
        _, r, c = best
        order[r] = c
        free_rows.remove(r)
        free_cols.remove(c)
    return order
