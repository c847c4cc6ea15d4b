"""Condensed MPC quadratic program and its closed loop, solved by DAQP.

With the predicted inputs U = (u_0, …, u_{N−1}) ∈ R^{3N} and x_i = Φ_i s + Γ_i U, the
horizon cost Σ_{i<N} (x_iᵀQx_i + u_iᵀRu_i) + x_NᵀPx_N equals UᵀHU + 2 sᵀFᵀU + const with

    H = Σ_{i=1}^{N−1} Γ_iᵀQΓ_i + Γ_NᵀPΓ_N + blkdiag(R, …, R),
    F = Σ_{i=1}^{N−1} Γ_iᵀQΦ_i + Γ_NᵀPΦ_N.

The QP is solved in the scaled input Ũ = U / u_max, so the box is |Ũ_j| ≤ 1 and the solver's
primal tolerance is relative to u_max; H̃ = u_max² H is further divided by its largest
diagonal entry (the minimizer does not change). DAQP (Arnström, Bemporad & Axehill 2022) is
a dual active-set solver for small dense QPs: :class:`daqp.Model` factorizes H̃ once per
candidate, and each closed-loop step only updates the linear term F̃ s_k, starting from the
previous step's active set (warm start). Its result is the exact minimizer of the QP up to
round-off: an active-set method ends on the optimal active set and solves the equality
system there, so the closed loop does not depend on tolerances (tested).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: DAQP exit flag of an optimal solution (see https://darnstrom.github.io/daqp/parameters).
DAQP_OPTIMAL = 1

CONVERGED = "converged"
HORIZON = "horizon"
CUTOFF = "cutoff"
QP_FAILURE = "qp_failure"
NONFINITE = "nonfinite"


def prediction_matrices(Ad: np.ndarray, Bd: np.ndarray, horizon: int
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Φ_i = A_dⁱ and Γ_i (x_i = Φ_i s + Γ_i U) for i = 0..N.

    Returns
    -------
    Phi : ndarray, shape (N + 1, n, n)
    Gam : ndarray, shape (N + 1, n, m·N)
    """
    nx, nu = Bd.shape
    Phi = np.zeros((horizon + 1, nx, nx))
    Gam = np.zeros((horizon + 1, nx, nu * horizon))
    Phi[0] = np.eye(nx)
    for i in range(horizon):
        Phi[i + 1] = Ad @ Phi[i]
        Gam[i + 1] = Ad @ Gam[i]
        Gam[i + 1][:, nu * i:nu * (i + 1)] = Bd
    return Phi, Gam


def qp_matrices(Phi: np.ndarray, Gam: np.ndarray, Q: np.ndarray, R: np.ndarray,
                P: np.ndarray, u_max: np.ndarray, normalize: bool = True
                ) -> tuple[np.ndarray, np.ndarray]:
    """Scaled condensed QP data for a batch of weights (see the module docstring).

    Parameters
    ----------
    Phi, Gam : ndarray
        From :func:`prediction_matrices`, shapes (N + 1, n, n) and (N + 1, n, m·N).
    Q : ndarray, shape (B, n, n)
    R : ndarray, shape (B, m, m)
    P : ndarray, shape (B, n, n)
        Terminal weights.
    u_max : ndarray, shape (m,)
        Input bounds (m/s²).
    normalize : bool
        Divide H̃ and F̃ by the largest diagonal entry of H̃ (False: the input-scaled data
        before that division; the QP's minimizer is the same).

    Returns
    -------
    H : ndarray, shape (B, m·N, m·N)
        Scaled Hessian H̃ (largest diagonal entry 1).
    F : ndarray, shape (B, m·N, n)
        Scaled linear map F̃ (f̃ = F̃ s).
    """
    horizon = Gam.shape[0] - 1
    nx, mn = Gam.shape[1], Gam.shape[2]
    nu = mn // horizon
    G = Gam[1:horizon].reshape(-1, mn)                           # ((N−1)·n, m·N)
    nb = Q.shape[0]
    QG = np.einsum("bac,icl->bial", Q, Gam[1:horizon]).reshape(nb, -1, mn)
    QPh = np.einsum("bac,icl->bial", Q, Phi[1:horizon]).reshape(nb, -1, nx)
    PG = P @ Gam[horizon]
    H = G.T @ QG + Gam[horizon].T @ PG
    F = G.T @ QPh + Gam[horizon].T @ (P @ Phi[horizon])
    for i in range(horizon):
        H[:, nu * i:nu * (i + 1), nu * i:nu * (i + 1)] += R
    scale = np.tile(np.asarray(u_max, float), horizon)
    H = H * scale[None, :, None] * scale[None, None, :]
    F = F * scale[None, :, None]
    H = 0.5 * (H + np.swapaxes(H, 1, 2))
    if not normalize:
        return H, F
    norm = np.max(np.diagonal(H, axis1=1, axis2=2), axis=1)
    return H / norm[:, None, None], F / norm[:, None, None]


class LinearPlant:
    """The discrete CW model itself, with an optional thrust-magnitude error.

    s_{k+1} = A_d s_k + B_d (thrust_scale · u_k).
    """

    def __init__(self, Ad: np.ndarray, Bd: np.ndarray, thrust_scale: float = 1.0) -> None:
        self.Ad = Ad
        self.Bd = Bd * float(thrust_scale)

    def reset(self, s0: np.ndarray) -> np.ndarray:
        """Start at ``s0`` (6,); returns the measured state."""
        self.s = np.array(s0, dtype=float)
        return self.s

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply ``u`` (3,) m/s² for one sample; returns the next state (6,)."""
        self.s = self.Ad @ self.s + self.Bd @ u
        return self.s


class KeplerianPlant:
    """Nonlinear relative motion about a Keplerian target orbit (compiled RK4 kernel
    :func:`penaltyrun.dynamics.mpc_relative.propagate`), with a thrust-magnitude error.

    Parameters
    ----------
    semi_major_axis_m, eccentricity, true_anomaly_rad, mu_m3_s2 : float
        Target orbit at t = 0.
    dt : float
        Sample time (s).
    substeps : int
        RK4 steps per sample.
    thrust_scale : float
        Applied acceleration = thrust_scale · commanded.
    """

    def __init__(self, semi_major_axis_m: float, eccentricity: float, true_anomaly_rad: float,
                 mu_m3_s2: float, dt: float, substeps: int, thrust_scale: float = 1.0) -> None:
        a, e, nu, mu = semi_major_axis_m, eccentricity, true_anomaly_rad, mu_m3_s2
        p = a * (1.0 - e * e)
        r = p / (1.0 + e * math.cos(nu))
        self.target = np.array([r, math.sqrt(mu / p) * e * math.sin(nu),
                                math.sqrt(mu * p) / (r * r)])
        self.mu = float(mu)
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.thrust_scale = float(thrust_scale)

    def reset(self, s0: np.ndarray) -> np.ndarray:
        """Start at ``s0`` (6,) relative to the target at t = 0."""
        self.y = np.concatenate([np.asarray(s0, dtype=float), self.target])
        return self.y[:6]

    def step(self, u: np.ndarray) -> np.ndarray:
        """Apply ``u`` (3,) m/s² in LVLH for one sample; returns the next relative state."""
        from penaltyrun.dynamics.mpc_relative import propagate

        self.y = propagate(self.y, self.thrust_scale * np.asarray(u, dtype=float), self.dt,
                           self.substeps, self.mu)
        return self.y[:6]


@dataclass
class LoopResult:
    """One closed-loop run.

    Attributes
    ----------
    status : str
        ``converged``, ``horizon``, ``cutoff``, ``qp_failure`` or ``nonfinite``.
    delta_v : float
        Σ Tₛ ‖u_k‖₂ over the applied steps (m/s).
    steps : int
        Steps applied (t_final = steps · Tₛ).
    final_state : ndarray, shape (6,)
    qp_iterations : int
        DAQP iterations summed over the steps.
    states, inputs : ndarray or None
        Histories (steps + 1, 6) and (steps, 3) when recorded.
    energy : float
        Σ ½ ‖u_k‖² Tₛ over the applied steps (m²/s³), the discrete control energy.
    """

    status: str
    delta_v: float
    steps: int
    final_state: np.ndarray
    qp_iterations: int
    states: np.ndarray | None = None
    inputs: np.ndarray | None = None
    energy: float = 0.0


def closed_loop(H: np.ndarray, F: np.ndarray, plant: Any, s0: np.ndarray, n_steps: int,
                dt: float, u_max: np.ndarray, pos_tol: float, vel_tol: float,
                settings: dict[str, float], cutoff: float = math.inf,
                record: bool = False) -> LoopResult:
    """Run the receding-horizon controller of one candidate.

    At each step k (t = k·dt), the run has converged if ‖r_k‖ ≤ ``pos_tol`` and
    ‖v_k‖ ≤ ``vel_tol`` (checked before the step's QP, also at k = ``n_steps``); otherwise
    the QP is solved from the measured s_k and u_0 is applied for one sample.

    Parameters
    ----------
    H : ndarray, shape (3N, 3N)
        Scaled Hessian from :func:`qp_matrices` (factorized once here).
    F : ndarray, shape (3N, 6)
        Scaled linear map.
    plant : LinearPlant or KeplerianPlant
    s0 : ndarray, shape (6,)
        Initial relative state (m, m/s).
    n_steps : int
        Steps at most (t_max / dt).
    dt : float
        Sample time (s).
    u_max : ndarray, shape (3,)
        Input bounds (m/s²).
    pos_tol, vel_tol : float
        Convergence radii (m, m/s).
    settings : dict
        DAQP settings (``primal_tol``, ``dual_tol``, ``iter_limit``, ...).
    cutoff : float
        Stop with status ``cutoff`` once Δv exceeds this (m/s; ``inf``: never).
    record : bool
        Keep the state and input histories.
    """
    import daqp

    mn = H.shape[0]
    ones = np.ones(mn)
    model = daqp.Model()
    s = plant.reset(s0)
    model.setup(H, F @ s, np.zeros((0, mn)), ones, -ones)
    model.settings = settings
    dv, energy, iters, status, k = 0.0, 0.0, 0, HORIZON, 0
    states = [s.copy()] if record else None
    inputs: list[np.ndarray] = []
    umax = np.asarray(u_max, dtype=float)
    for k in range(n_steps + 1):
        if (math.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) <= pos_tol
                and math.sqrt(s[3] * s[3] + s[4] * s[4] + s[5] * s[5]) <= vel_tol):
            status = CONVERGED
            break
        if k == n_steps:
            break
        if k:
            model.update(f=F @ s)
        x, _, flag, info = model.solve()
        iters += int(info["iterations"])
        if flag != DAQP_OPTIMAL:
            status = QP_FAILURE
            break
        u = umax * np.clip(x[:3], -1.0, 1.0)
        uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2]
        dv += dt * math.sqrt(uu)
        energy += 0.5 * dt * uu
        s = plant.step(u)
        if record:
            states.append(s.copy())
            inputs.append(u)
        if not np.all(np.isfinite(s)):
            status = NONFINITE
            k += 1
            break
        if dv > cutoff:
            status = CUTOFF
            k += 1
            break
    return LoopResult(status, dv, k, np.array(s, dtype=float), iters,
                      np.asarray(states) if record else None,
                      np.asarray(inputs).reshape(-1, 3) if record else None, energy)


__all__ = ["CONVERGED", "CUTOFF", "HORIZON", "NONFINITE", "QP_FAILURE", "KeplerianPlant",
           "LinearPlant", "LoopResult", "closed_loop", "prediction_matrices", "qp_matrices"]
