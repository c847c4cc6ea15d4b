"""Exact gradient of the Zermelo cost with respect to a symmetric positive-definite K.

With the closed loop Ẋ = −KX (:mod:`penaltyrun.dynamics.zermelo_closed`), X(t) = e^{−Kt}X0,
the control U = c(X) X − K X (c = cos y sin x, so −d(X) = c X), L = ½|U|² and the event
time T (‖X(T)‖ = r), the cost J(K) = ∫₀^T L dt has, for every symmetric direction E,

    dJ = L(T) dT + ∫₀^T (gᵀ dX − Uᵀ E X) dt,   g = ∂L/∂X = (c I + X ∇cᵀ − K)ᵀ U,
    dX(t) = d e^{−Kt}[E] X0,   dT = X(T)ᵀ dX(T) / (X(T)ᵀ K X(T))

(implicit function theorem on ‖X(T)‖² = r²; Ẋ(T) = −K X(T)); at a fixed T (the event
not reached) dT = 0 and d‖X(T)‖ = X(T)ᵀ dX(T) / ‖X(T)‖ is returned besides. The
derivative of the matrix exponential is its Fréchet derivative in the eigenbasis
K = V diag(λ) Vᵀ (Daleckii–Krein): d e^{−Kt}[E] = V (D(t) ∘ VᵀEV) Vᵀ with the divided differences
D_ij = (e^{−λ_i t} − e^{−λ_j t}) / (λ_i − λ_j), D_ii = −t e^{−λ_i t}, computed with
``expm1`` so that close eigenvalues lose no digits. Collecting the terms in E gives the
gradient matrix G with dJ = Σ_ij G_ij E_ij:

    G = sym( ∫₀^T [V ((Vᵀg ξᵀ) ∘ D) Vᵀ − U Xᵀ] dt + L(T) V ((VᵀX(T) ξᵀ) ∘ D(T)) Vᵀ
             / (X(T)ᵀ K X(T)) ),   ξ = VᵀX0.

The integral is taken by adaptive Gauss–Kronrod (7, 15) quadrature in the graded variable
s = ln(1 + λ_max t) of the cost's own quadrature, with a global error target relative to
∫ max |integrand| dt (so a gradient near zero, at a stationary point, is resolved in
absolute terms). J itself is integrated alongside (a consistency check against the cost).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from penaltyrun.dynamics.zermelo_closed import GK_NODES, GK_WEIGHTS, GL_WEIGHTS

#: Error target of the gradient quadrature, relative to ∫ max|integrand| dt.
GRAD_RTOL = 1e-11
#: Largest number of quadrature intervals (more: the gradient is reported as not settled).
GRAD_MAX_INTERVALS = 4000


@dataclass(frozen=True)
class ZermeloSensitivity:
    """J and dJ/dK of one gain from one start (:func:`cost_gradient`).

    Attributes
    ----------
    cost : float
        J = ∫₀^T ½|U|² dt (recomputed by the gradient's quadrature).
    grad : ndarray, shape (2, 2)
        Symmetric G with dJ = Σ_ij G_ij dK_ij for symmetric dK.
    dist : float
        ‖X(T)‖.
    dist_grad : ndarray, shape (2, 2)
        Symmetric d‖X(T)‖ / dK at a fixed T (the graded penalty's derivative when the
        event does not fire).
    event_rate : float
        X(T)ᵀ K X(T) / ‖X(T)‖², the rate at which ln‖X‖ decreases at the event (1/time);
        dT/dK is proportional to its inverse (a tangential event has rate 0).
    settled : bool
        Whether the quadrature met its error target within its interval budget.
    """

    cost: float
    grad: np.ndarray
    dist: float
    dist_grad: np.ndarray
    event_rate: float
    settled: bool


def _divided(lam: np.ndarray, t: np.ndarray) -> np.ndarray:
    """D(t), shape (P, 2, 2): divided differences of λ ↦ e^{−λt} at the eigenvalues."""
    low = np.minimum(lam[:, None], lam[None, :])                        # (2, 2)
    x = np.abs(lam[:, None] - lam[None, :])[None] * t[:, None, None]    # ≥ 0
    safe = np.where(x == 0.0, 1.0, x)
    ratio = np.where(x == 0.0, 1.0, -np.expm1(-x) / safe)              # (1 − e^{−x}) / x
    return -t[:, None, None] * np.exp(-low[None] * t[:, None, None]) * ratio


def _state(K: np.ndarray, V: np.ndarray, lam: np.ndarray, xi: np.ndarray, t: np.ndarray
           ) -> tuple[np.ndarray, ...]:
    """X (P, 2), U (P, 2), L (P,), g (P, 2) and D (P, 2, 2) at the times t (P,)."""
    X = (np.exp(-lam[None, :] * t[:, None]) * xi[None, :]) @ V.T
    x, y = X[:, 0], X[:, 1]
    c = np.cos(y) * np.sin(x)
    grad_c = np.stack([np.cos(y) * np.cos(x), -np.sin(y) * np.sin(x)], axis=1)
    U = c[:, None] * X - X @ K.T
    L = 0.5 * np.sum(U * U, axis=1)
    # ∂U/∂X = c I + X ∇cᵀ − K; g = (∂U/∂X)ᵀ U
    g = c[:, None] * U + grad_c * np.sum(X * U, axis=1)[:, None] - U @ K
    return X, U, L, g, _divided(lam, t)


def _integrand(K: np.ndarray, V: np.ndarray, lam: np.ndarray, xi: np.ndarray,
               lmax: float, s: np.ndarray) -> np.ndarray:
    """(P, 5): L and the four entries of the gradient integrand, times dt/ds."""
    es = np.exp(s)
    t = np.expm1(s) / lmax
    X, U, L, g, D = _state(K, V, lam, xi, t)
    gh = g @ V                                                          # Vᵀg per row
    M = np.einsum("ai,pij,bj->pab", V, gh[:, :, None] * xi[None, None, :] * D, V)
    M -= U[:, :, None] * X[:, None, :]
    out = np.concatenate([L[:, None], M.reshape(-1, 4)], axis=1)
    return out * (es / lmax)[:, None]


def _gauss_kronrod(f, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """Kronrod values (I, C), error estimates (I,) and ∫ max|f| (I,) on intervals [a, b]."""
    half = 0.5 * (b - a)
    mid = 0.5 * (a + b)
    nodes = np.concatenate([-GK_NODES[:7], GK_NODES[::-1]])            # 15 ascending
    s = mid[:, None] + half[:, None] * nodes[None, :]
    vals = f(s.reshape(-1)).reshape(a.size, 15, -1)
    wk = np.concatenate([GK_WEIGHTS[:7], GK_WEIGHTS[::-1]])
    wg = np.zeros(15)
    wg[1:7:2] = GL_WEIGHTS[:3]
    wg[9:15:2] = GL_WEIGHTS[2::-1]
    wg[7] = GL_WEIGHTS[3]
    rk = half[:, None] * np.einsum("q,iqc->ic", wk, vals)
    rg = half[:, None] * np.einsum("q,iqc->ic", wg, vals)
    err = np.max(np.abs(rk - rg), axis=1)
    mag = half * np.einsum("q,iq->i", wk, np.max(np.abs(vals), axis=2))
    return rk, err, mag


def _quadrature(f, S: float, rtol: float) -> tuple[np.ndarray, bool]:
    """∫₀^S f ds of a vector integrand, globally adaptive; returns (integral, settled)."""
    n0 = max(1, min(16, int(np.ceil(S))))
    edges = np.linspace(0.0, S, n0 + 1)
    a, b = edges[:-1], edges[1:]
    rk, err, mag = _gauss_kronrod(f, a, b)
    while True:
        if not (np.all(np.isfinite(err)) and np.all(np.isfinite(mag))):
            return np.sum(rk, axis=0), False
        tol = rtol * max(float(np.sum(mag)), 1e-300)
        if float(np.sum(err)) <= tol:
            return np.sum(rk, axis=0), True
        split = (err > tol * (b - a) / S) | (err >= np.max(err))
        if a.size + np.count_nonzero(split) > GRAD_MAX_INTERVALS:
            return np.sum(rk, axis=0), False
        mid = 0.5 * (a[split] + b[split])
        na = np.concatenate([a[split], mid])
        nb = np.concatenate([mid, b[split]])
        nrk, nerr, nmag = _gauss_kronrod(f, na, nb)
        keep = ~split
        a = np.concatenate([a[keep], na])
        b = np.concatenate([b[keep], nb])
        rk = np.concatenate([rk[keep], nrk])
        err = np.concatenate([err[keep], nerr])
        mag = np.concatenate([mag[keep], nmag])


def cost_gradient(K: np.ndarray, x0: np.ndarray, T: float, event: bool,
                  rtol: float = GRAD_RTOL) -> ZermeloSensitivity:
    """J(K) = ∫₀^T ½|U|² dt and dJ/dK (module docstring) for one symmetric PD gain.

    Parameters
    ----------
    K : ndarray, shape (2, 2)
        Symmetric positive-definite gain (nondimensional, 1/time).
    x0 : ndarray, shape (2,)
        Start.
    T : float
        Event time (``event``) or the fixed horizon (time).
    event : bool
        Whether T is the event time ‖X(T)‖ = r (then dT/dK enters) or a fixed horizon.
    rtol : float
        Quadrature error target (see :data:`GRAD_RTOL`).

    Returns
    -------
    ZermeloSensitivity
    """
    K = 0.5 * (np.asarray(K, dtype=float) + np.asarray(K, dtype=float).T)
    lam, V = np.linalg.eigh(K)
    xi = V.T @ np.asarray(x0, dtype=float)
    lmax = float(lam[-1])
    S = float(np.log1p(lmax * T))
    total, settled = _quadrature(lambda s: _integrand(K, V, lam, xi, lmax, s), S, rtol)
    M = total[1:].reshape(2, 2)
    XT, _, LT, _, DT = _state(K, V, lam, xi, np.array([T]))
    XT, LT, DT = XT[0], float(LT[0]), DT[0]
    rate = float(XT @ K @ XT)
    dist = float(np.linalg.norm(XT))
    dXT = V @ (((V.T @ XT)[:, None] * xi[None, :]) * DT) @ V.T     # d(½‖X(T)‖²)/dK
    if event:
        M = M + LT / rate * dXT
    return ZermeloSensitivity(cost=float(total[0]), grad=0.5 * (M + M.T), dist=dist,
                              dist_grad=0.5 * (dXT + dXT.T) / dist,
                              event_rate=rate / dist ** 2, settled=settled)


__all__ = ["GRAD_MAX_INTERVALS", "GRAD_RTOL", "ZermeloSensitivity", "cost_gradient"]
