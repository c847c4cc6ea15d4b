"""Exact derivatives of the parameterizations z → K = Q diag(λ) Qᵀ.

Two products are offered for one decision vector z (dim,):

* the Jacobian dK/dz, shape (dim, N, N), slice i = ∂K/∂z_i (symmetric);
* the vector–Jacobian product (VJP) of a cotangent G (N, N),
  ``grad_i = Σ_ab G_ab ∂K_ab/∂z_i``, shape (dim,), in O(N³) (Givens, Cayley) or O(N⁴)
  (GEAGSP) operations without forming the Jacobian.

Convention for G: its N² entries are the partial derivatives ∂f/∂K_ab of a scalar f with
all entries of K treated as independent. G need not be symmetric; because K is symmetric
only (G + Gᵀ)/2 enters the result. A gradient taken with respect to the N(N+1)/2 free
entries of a symmetric matrix (the "symmetric-matrix gradient", whose off-diagonal entries
already carry both K_ab and K_ba) must be converted first: halve its off-diagonal entries
and fill the lower triangle with the upper one.

With Ω_i = Qᵀ ∂Q/∂z_i (skew-symmetric) the angle slices are
∂K/∂z_i = Q (Ω_i Λ − Λ Ω_i) Qᵀ, and ∂K/∂λ_i = q_i q_iᵀ. The orthogonal factor's derivatives:

* Givens, Q = G_1 ⋯ G_M: ∂Q/∂θ_k = G_1 ⋯ G_{k−1} G_k' G_{k+1} ⋯ G_M (rank two);
* Cayley, Q = (I − C)(I + C)⁻¹: ∂Q/∂c = −(I + Q) ∂C (I + C)⁻¹; ``cayley_tan`` adds the
  factor 1 + tan²θ;
* GEAGSP: column c is q_c = B_c v_c with B_c the Gram–Schmidt basis of the complement of
  the placed columns Q_c = [q_0 … q_{c−1}]. Without skipped vectors B_c is the unique
  orthonormal complement basis whose top (N − c) × (N − c) block L_c is lower triangular
  with a positive diagonal, which gives
  ∂B_c = −Q_c Y + B_c X, Y = ∂Q_cᵀ B_c, X = U − Uᵀ, U = strict upper part of
  L_c⁻¹ Q_c[:N−c] Y, and the VJP runs these relations backwards, column by column.

GEAGSP is discontinuous where its Gram–Schmidt construction skips a standard basis vector
(a residual below :data:`~penaltyrun.penalty.orthogonal.GS_SKIP`, e.g. the first angle of a
row at 0 or π). There the derivative does not exist; :class:`NotDifferentiableError` is raised
for every z whose construction has a residual within a factor 2 of that threshold. The
other maps are smooth (real-analytic) on the whole box, bounds included.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.penalty import orthogonal as orth
from penaltyrun.penalty.orthogonal import _complement_basis

#: Residuals below this (a factor 2 above the skip threshold) make GEAGSP non-differentiable.
GEAGSP_DERIVATIVE_MARGIN = 2.0 * orth.GS_SKIP


class NotDifferentiableError(ValueError):
    """The map has no derivative at this z (GEAGSP at or next to a skipped basis vector)."""


# --------------------------------------------------------------------------- hypersphere


@njit(cache=True)
def _hypersphere_jac(phi, v, D):
    """v(φ) into v (k+1,) and D[i, j] = ∂v_j/∂φ_i into D (k, k+1), O(k²)."""
    k = phi.shape[0]
    pre = 1.0
    for j in range(k):
        v[j] = pre * np.cos(phi[j])
        pre *= np.sin(phi[j])
    v[k] = pre
    for i in range(k):
        pre = 1.0
        for j in range(k + 1):
            g = np.cos(phi[j]) if j < k else 1.0
            if j < i:
                D[i, j] = 0.0
            elif j == i:
                D[i, j] = -pre * np.sin(phi[i])
            else:
                D[i, j] = pre * g
            if j < k:
                pre *= np.cos(phi[j]) if j == i else np.sin(phi[j])


def hypersphere_jacobian(phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit vector v(φ) ∈ R^{k+1} and its Jacobian D[i, j] = ∂v_j/∂φ_i, shape (k, k+1)."""
    phi = np.ascontiguousarray(phi, dtype=float)
    v, D = np.empty(phi.size + 1), np.empty((phi.size, phi.size + 1))
    _hypersphere_jac(phi, v, D)
    return v, D


# --------------------------------------------------------------------------- GEAGSP


@njit(cache=True)
def _geagsp_tape(angles, n):
    """Q, bases[c, :, :m] = B_c, vs[c, :m] = v_c, Ds[c, :m−1, :m] = ∂v_c/∂φ (m = n − c),
    and the smallest Gram–Schmidt residual (the diagonal of the bases' top blocks)."""
    Q = np.zeros((n, n))
    bases = np.zeros((n, n, n))
    vs = np.zeros((n, n))
    Ds = np.zeros((n, n, n))
    basis = np.empty((n, n))
    smallest = np.inf
    pos = 0
    for c in range(n):
        m = n - c
        if m > 1:
            _hypersphere_jac(angles[pos:pos + m - 1], vs[c, :m], Ds[c, :m - 1, :m])
            pos += m - 1
        else:
            vs[c, 0] = 1.0
        if c == 0:
            for i in range(n):
                bases[0, i, i] = 1.0
        else:
            found = _complement_basis(Q, c, n, basis)
            if found < m:
                smallest = 0.0
            for j in range(min(found, m)):
                smallest = min(smallest, basis[j, j])
                for i in range(n):
                    bases[c, i, j] = basis[i, j]
        for i in range(n):
            acc = 0.0
            for j in range(m):
                acc += bases[c, i, j] * vs[c, j]
            Q[i, c] = acc
    return Q, bases, vs, Ds, smallest


def geagsp_tape(angles: np.ndarray, n: int) -> tuple[np.ndarray, ...]:
    """Q (n, n), bases (n, n, n), vs (n, n), Ds (n, n, n) as in :func:`_geagsp_tape`.

    Raises
    ------
    NotDifferentiableError
        If a Gram–Schmidt residual is within :data:`GEAGSP_DERIVATIVE_MARGIN` of zero.
    """
    Q, bases, vs, Ds, smallest = _geagsp_tape(np.ascontiguousarray(angles, dtype=float), n)
    if smallest <= GEAGSP_DERIVATIVE_MARGIN:
        raise NotDifferentiableError(
            "GEAGSP has no derivative here: its Gram–Schmidt basis skips (or nearly "
            f"skips) a standard basis vector (smallest residual {smallest:.1e})")
    return Q, bases, vs, Ds


def _geagsp_dq(angles: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Q (n, n) and ∂Q/∂φ_i for every angle, shape (M, n, n) (forward mode, all at once)."""
    Q, bases, vs, Ds = geagsp_tape(angles, n)
    M = orth.n_angles(n)
    dQ = np.zeros((M, n, n))
    pos = 0
    for c in range(n):
        m = n - c
        B, v, D = bases[c, :, :m], vs[c, :m], Ds[c, :m - 1, :m]
        if c == 0:
            dq = np.zeros((M, n))
        else:
            Qp = Q[:, :c]
            Y = np.einsum("dac,am->dcm", dQ[:, :, :c], B)
            Linv = _lower_inverse(np.ascontiguousarray(B[:m]))
            U = np.triu(Linv @ (Qp[:m] @ Y), 1)
            dB = -(Qp @ Y) + B @ (U - np.transpose(U, (0, 2, 1)))
            dq = dB @ v
        dq[pos:pos + m - 1] += D @ B.T
        pos += m - 1
        dQ[:, :, c] = dq
    return Q, dQ


@njit(cache=True)
def _lower_inverse(L):
    """Inverse of a lower-triangular matrix (m, m) by forward substitution."""
    m = L.shape[0]
    X = np.zeros((m, m))
    for j in range(m):
        X[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, m):
            acc = 0.0
            for k in range(j, i):
                acc += L[i, k] * X[k, j]
            X[i, j] = -acc / L[i, i]
    return X


@njit(cache=True)
def _geagsp_backward(Q, bases, vs, Ds, Qbar, starts):
    """Reverse sweep over the GEAGSP columns: angle gradient (M,) of ⟨Qbar, Q⟩.

    bases[c, :, :m] = B_c (n, m), vs[c, :m] = v_c, Ds[c, :m−1, :m] = ∂v_c/∂φ, m = n − c.
    """
    n = Q.shape[0]
    grad = np.zeros(starts[-1])
    for c in range(n - 1, -1, -1):
        m = n - c
        B = np.ascontiguousarray(bases[c, :, :m])
        Bt = np.ascontiguousarray(B.T)
        v = vs[c, :m].copy()
        g = Qbar[:, c].copy()
        vbar = Bt @ g
        for i in range(m - 1):
            acc = 0.0
            for j in range(m):
                acc += Ds[c, i, j] * vbar[j]
            grad[starts[c] + i] = acc
        if c == 0:
            continue
        S = np.zeros((m, m))
        for i in range(m):
            for j in range(i + 1, m):
                S[i, j] = vbar[i] * v[j] - v[i] * vbar[j]
        Z = np.ascontiguousarray(_lower_inverse(np.ascontiguousarray(B[:m, :])).T) @ S
        QpT = np.ascontiguousarray(Q[:, :c].T)
        Ybar = np.outer(-(QpT @ g), v) + np.ascontiguousarray(QpT[:, :m]) @ Z
        Qbar[:, :c] += B @ np.ascontiguousarray(Ybar.T)
    return grad


def _geagsp_vjp(angles: np.ndarray, n: int, lam: np.ndarray, Gs: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Q and the angle gradient for the symmetric cotangent Gs = G + Gᵀ."""
    Q, bases, vs, Ds = geagsp_tape(angles, n)
    starts = np.concatenate([[0], np.cumsum(np.arange(n - 1, -1, -1))]).astype(np.int64)
    Qbar = (Gs @ Q) * lam[None, :]
    return Q, _geagsp_backward(Q, bases, vs, Ds, Qbar, starts)


# --------------------------------------------------------------------------- Givens


@njit(cache=True)
def _givens_dq_kernel(angles, n):
    """Q and ∂Q/∂θ_k = −P_k[:, i] S_k[j, :] + P_k[:, j] S_k[i, :] for rotation k in plane
    (j, i), with the prefix P_k = G_1 ⋯ G_k and the suffix S_k = G_{k+1} ⋯ G_M."""
    M = angles.shape[0]
    pj = np.empty((M, n))
    pi_ = np.empty((M, n))
    sj = np.empty((M, n))
    si = np.empty((M, n))
    jj = np.empty(M, np.int64)
    ii = np.empty(M, np.int64)
    k = 0
    for j in range(n - 1):
        for i in range(j + 1, n):
            jj[k] = j
            ii[k] = i
            k += 1
    Pt = np.eye(n)  # Pᵀ: rows are the columns of P
    for k in range(M):
        j, i = jj[k], ii[k]
        c, s = np.cos(angles[k]), np.sin(angles[k])
        for m in range(n):
            a_j, a_i = Pt[j, m], Pt[i, m]
            Pt[j, m] = c * a_j - s * a_i
            Pt[i, m] = s * a_j + c * a_i
        pj[k] = Pt[j]
        pi_[k] = Pt[i]
    S = np.eye(n)
    for k in range(M - 1, -1, -1):
        j, i = jj[k], ii[k]
        sj[k] = S[j]
        si[k] = S[i]
        c, s = np.cos(angles[k]), np.sin(angles[k])
        for m in range(n):
            r_j, r_i = S[j, m], S[i, m]
            S[j, m] = c * r_j + s * r_i
            S[i, m] = -s * r_j + c * r_i
    dQ = np.empty((M, n, n))
    for k in range(M):
        for a in range(n):
            for b in range(n):
                dQ[k, a, b] = pj[k, a] * si[k, b] - pi_[k, a] * sj[k, b]
    return Pt.T.copy(), dQ


def _givens_dq(angles: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Q (n, n) and ∂Q/∂θ_k for every angle, shape (M, n, n)."""
    return _givens_dq_kernel(np.ascontiguousarray(angles, dtype=float), n)


@njit(cache=True)
def givens_vjp(angles, n, Q, Qbar):
    """Reverse sweep of Q = G_1 ⋯ G_M: angle gradient (M,) of ⟨Qbar, Q⟩."""
    M = angles.shape[0]
    P = Q.copy()
    Pb = Qbar.copy()
    grad = np.zeros(M)
    k = M
    for j in range(n - 2, -1, -1):
        for i in range(n - 1, j, -1):
            k -= 1
            c = np.cos(angles[k])
            s = np.sin(angles[k])
            acc = 0.0
            for m in range(n):
                acc += Pb[m, i] * P[m, j] - Pb[m, j] * P[m, i]
                pj, pi_ = P[m, j], P[m, i]
                P[m, j] = c * pj + s * pi_
                P[m, i] = -s * pj + c * pi_
                bj, bi = Pb[m, j], Pb[m, i]
                Pb[m, j] = c * bj + s * bi
                Pb[m, i] = -s * bj + c * bi
            grad[k] = acc
    return grad


# --------------------------------------------------------------------------- Cayley


def _cayley_parts(entries: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Q and W = (I + C)⁻¹ for the skew entries (M,)."""
    C = orth.skew_from_entries(entries[None], n)[0]
    eye = np.eye(n)
    W = np.linalg.inv(eye + C)
    return W @ (eye - C), W


def _cayley_dq(entries: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Q and ∂Q/∂c_k = −((I + Q)[:, a] W[b, :] − (I + Q)[:, b] W[a, :]), (a, b) = pair k."""
    Q, W = _cayley_parts(entries, n)
    a, b = np.triu_indices(n, 1)
    IQ = np.eye(n) + Q
    dQ = -(np.einsum("ka,kb->kab", IQ[:, a].T, W[b]) - np.einsum("ka,kb->kab", IQ[:, b].T, W[a]))
    return Q, dQ


def _cayley_vjp(entries: np.ndarray, n: int, Qbar_of_Q) -> tuple[np.ndarray, np.ndarray]:
    """Q and the entry gradient: C̄ = −(I + Q)ᵀ Q̄ Wᵀ, grad_k = C̄_ab − C̄_ba."""
    Q, W = _cayley_parts(entries, n)
    Qbar = Qbar_of_Q(Q)
    Cbar = -(np.eye(n) + Q).T @ Qbar @ W.T
    a, b = np.triu_indices(n, 1)
    return Q, Cbar[a, b] - Cbar[b, a]


# --------------------------------------------------------------------------- K level


def _split(p, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    z = np.asarray(z, float)
    if z.shape != (p.dim,):
        raise ValueError(f"{p.kind} (N={p.n}) expects z of shape ({p.dim},), got {z.shape}")
    return z[: p.n], np.ascontiguousarray(z[p.n:])


def jacobian(p, z: np.ndarray) -> np.ndarray:
    """dK/dz of parameterization ``p`` at z (dim,), shape (dim, N, N); see the module doc."""
    lam, ang = _split(p, z)
    n = p.n
    J = np.zeros((p.dim, n, n))
    if p.kind == "diagonal":
        J[np.arange(n), np.arange(n), np.arange(n)] = 1.0
        return J
    if p.kind == "geagsp":
        Q, dQ = _geagsp_dq(ang, n)
    elif p.kind == "givens":
        Q, dQ = _givens_dq(ang, n)
    elif p.kind == "cayley":
        Q, dQ = _cayley_dq(ang, n)
    else:
        Q, dQ = _cayley_dq(np.tan(ang), n)
        dQ *= (1.0 + np.tan(ang) ** 2)[:, None, None]
    J[:n] = np.einsum("ai,bi->iab", Q, Q)
    T = (dQ * lam[None, None, :]) @ Q.T
    J[n:] = T + np.transpose(T, (0, 2, 1))
    return J


def vjp(p, z: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Σ_ab G_ab ∂K_ab/∂z_i for z (dim,) and G (N, N), shape (dim,); see the module doc."""
    lam, ang = _split(p, z)
    n = p.n
    G = np.asarray(G, float)
    if G.shape != (n, n):
        raise ValueError(f"G must have shape ({n}, {n}), got {G.shape}")
    if p.kind == "diagonal":
        return np.diag(G).copy()
    Gs = G + G.T
    if p.kind == "geagsp":
        Q, g_ang = _geagsp_vjp(ang, n, lam, Gs)
    elif p.kind == "givens":
        Q = orth.givens_batch(ang[None], n)[0]
        g_ang = givens_vjp(ang, n, Q, (Gs @ Q) * lam[None, :])
    else:
        entries = np.tan(ang) if p.kind == "cayley_tan" else ang
        Q, g_ang = _cayley_vjp(entries, n, lambda Q: (Gs @ Q) * lam[None, :])
        if p.kind == "cayley_tan":
            g_ang = g_ang * (1.0 + entries ** 2)
    g_lam = np.einsum("ai,ab,bi->i", Q, G, Q)
    return np.concatenate([g_lam, g_ang])
