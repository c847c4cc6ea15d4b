"""A sub-level-set estimate of the region of attraction of an attitude feedback law.

The attitude laws apply u = −G x with x = (q_v, ω) ∈ R⁶ (the Lyapunov PD law: G = [K_p,
K_d]) to the rigid body

    q̇_v = ½ (q0 ω + q_v × ω),   q0 = +√(1 − |q_v|²),   I ω̇ = −ω × I ω + u,

on the hemisphere q0 > 0 (the problems start every run with q0 ≥ 0). With a full (not
scalar) K_p the classical energy function 2k(1 − q0) + ½ ωᵀIω is not a Lyapunov function
of the law (K_p q_v is then not the gradient of an attitude potential), so the function used
here is the law's own quadratic one: V(x) = xᵀ P x with P the solution of the Lyapunov
equation A_clᵀ P + P A_cl = −Q of the law linearized at the target,
A_cl = [[0, ½ I₃], [−I⁻¹ K_p, −I⁻¹ K_d]] (:meth:`AttitudeProblem.closed_loop`), and
Q = diag(I₃, τ² I₃), τ = 1 / min |Re λ(A_cl)| the loop's slowest time constant (s): the
rates are weighed in the loop's own time scale, so that a slow loop's small rates count as
much as its attitude errors (with Q = I₆ the set of a slow loop shrinks to a fraction of a
degree). Along the nonlinear flow, ẋ = A_cl x + g(x) and

    V̇(x) = −xᵀQx + 2 xᵀ P g(x),   g = (½ ((q0 − 1) ω + q_v × ω), −I⁻¹ (ω × I ω)).

The set must lie in the hemisphere |q_v| < 1: c ≤ c_edge = 1 / λ_max((P⁻¹)_qq), the level
at which the ellipsoid touches |q_v| = 1 (q0 = 0, a half turn).

Two estimates of the largest c with V̇ < 0 on {0 < V ≤ c} (inside the hemisphere), both
conservative, neither re-run by the optimizer:

``certified`` (analytic)
    With r = |x|: 1 − q0 ≤ |q_v|², |q_v|²|ω| ≤ (2/(3√3)) r³, |q_v||ω| ≤ r²/2 and
    |ω × I ω| = |ω × (I − ī I₃) ω| ≤ ½ (λ_max − λ_min) |ω|² (ī the mid-eigenvalue), so
    |g| ≤ a r² + b r³ with a = ¼ + (λ_max − λ_min)/(2 λ_min), b = 1/(3√3). V̇ < 0 for
    0 < r < r*, r* the positive root of 2‖P‖ (a r + b r²) = λ_min(Q), and
    {V ≤ λ_min(P) r*²} lies in that ball (r* capped below 1, inside the hemisphere): a
    proof, usually far smaller than the sampled level.
``sampled``
    V̇ on rays x = s d (dᵀ P d = 1, :data:`N_DIRECTIONS` seeded directions, s on
    :data:`N_RADII` points up to √c_edge); c is :data:`SAFETY` times the smallest V = s²
    at which a ray first reaches V̇ ≥ 0, or times c_edge when no ray does. A sampled
    estimate, not a proof: :func:`check` runs the law from seeded starts inside the set
    and on its boundary (among them the two of largest rotation) and reports how many
    converge.

Neither holds under a torque limit (u is then not −G x): :func:`estimate` returns None.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import linalg

#: Directions of the sampled estimate.
N_DIRECTIONS = 2000
#: Radial points per direction.
N_RADII = 200
#: Share of the sampled critical level kept (the sampled estimate's margin).
SAFETY = 0.9
#: Seed of the directions and of :func:`check`'s starts.
SEED = 20250422
#: Cubic constant of the certified bound: max of s²√(1 − s²) over s ∈ [0, 1].
CUBIC = 2.0 / (3.0 * np.sqrt(3.0))


@dataclass(frozen=True)
class SubLevelSet:
    """The estimate {x : xᵀ P x ≤ c} of one gain.

    Attributes
    ----------
    P : ndarray, shape (6, 6)
        V(x) = xᵀ P x, x = (q_v, ω) (ω in rad/s).
    Q : ndarray, shape (6, 6)
        Right-hand side of the Lyapunov equation (−V̇ of the linearized loop).
    edge : float
        c_edge: the level at which {V ≤ c} touches |q_v| = 1.
    certified : float
        Analytic level (V̇ < 0 proven on {0 < V ≤ certified}).
    sampled : float
        Sampled level (:data:`SAFETY` × the smallest sampled critical level).
    """

    P: np.ndarray
    Q: np.ndarray
    edge: float
    certified: float
    sampled: float

    def value(self, x: Any) -> np.ndarray:
        """V at states ``x`` (..., 6)."""
        x = np.asarray(x, dtype=float)
        return np.einsum("...i,ij,...j->...", x, self.P, x)


def closed_loop_matrix(G: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """A_cl (6 × 6) of u = −G x linearized at the target (q̇_v = ½ ω, I ω̇ = u)."""
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(inertia)])
    return A - B @ np.asarray(G, dtype=float)


def lyapunov_matrix(G: np.ndarray, inertia: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray] | None:
    """(P, Q): P of A_clᵀ P + P A_cl = −Q, Q = diag(I₃, τ² I₃) (module docstring); None
    when A_cl is not Hurwitz (no local V)."""
    A = closed_loop_matrix(G, inertia)
    slowest = float(np.max(np.linalg.eigvals(A).real))
    if slowest >= 0.0:
        return None
    Q = np.diag([1.0] * 3 + [1.0 / slowest ** 2] * 3)
    P = linalg.solve_continuous_lyapunov(A.T, -Q)
    return 0.5 * (P + P.T), Q


def edge_level(P: np.ndarray) -> float:
    """c_edge = 1 / λ_max((P⁻¹)_qq): the largest c with {xᵀPx ≤ c} inside |q_v| ≤ 1."""
    return 1.0 / float(np.linalg.eigvalsh(np.linalg.inv(P)[:3, :3])[-1])


def vdot(x: np.ndarray, P: np.ndarray, G: np.ndarray, inertia: np.ndarray
         ) -> np.ndarray:
    """V̇ = 2 xᵀ P ẋ of the nonlinear closed loop at states ``x`` (..., 6) with
    |q_v| ≤ 1 (q0 = +√(1 − |q_v|²))."""
    x = np.asarray(x, dtype=float)
    qv, w = x[..., :3], x[..., 3:]
    q0 = np.sqrt(np.clip(1.0 - np.sum(qv * qv, axis=-1), 0.0, None))[..., None]
    dq = 0.5 * (q0 * w + np.cross(qv, w))
    dw = (-np.cross(w, w @ inertia.T) - x @ G.T) @ np.linalg.inv(inertia).T
    return 2.0 * np.sum((x @ P) * np.concatenate([dq, dw], axis=-1), axis=-1)


def certified_level(P: np.ndarray, Q: np.ndarray, inertia: np.ndarray) -> float:
    """The analytic level λ_min(P) r*² (see the module docstring)."""
    lam = np.linalg.eigvalsh(inertia)
    a = 0.25 + (lam[-1] - lam[0]) / (2.0 * lam[0])
    k = float(np.linalg.eigvalsh(Q)[0]) / (2.0 * float(np.linalg.eigvalsh(P)[-1]))
    # positive root of CUBIC r² + a r − k = 0
    r = (-a + np.sqrt(a * a + 4.0 * CUBIC * k)) / (2.0 * CUBIC)
    r = min(float(r), 1.0 - 1e-9)
    return float(np.linalg.eigvalsh(P)[0]) * r * r


def _directions(P: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` seeded directions d (n, 6) with dᵀ P d = 1."""
    d = rng.standard_normal((n, 6))
    return d / np.sqrt(np.einsum("ni,ij,nj->n", d, P, d))[:, None]


def sampled_level(P: np.ndarray, G: np.ndarray, inertia: np.ndarray,
                  n_directions: int = N_DIRECTIONS, n_radii: int = N_RADII,
                  seed: int = SEED) -> float:
    """:data:`SAFETY` × the smallest level at which a sampled ray first has V̇ ≥ 0, or
    × c_edge when no sampled ray has V̇ ≥ 0 inside the hemisphere.

    The smallest first radius over the rays is the smallest radius at which any ray has
    V̇ ≥ 0: the compiled :func:`penaltyrun.dynamics.attitude_region.first_turn` visits the
    radii outward, every ray at each, and stops at the first such radius."""
    from penaltyrun.dynamics.attitude_region import first_turn

    d = _directions(P, n_directions, np.random.default_rng(seed))
    s_max = np.sqrt(edge_level(P))
    s = np.linspace(0.0, s_max, n_radii + 1)[1:]
    inertia = np.asarray(inertia, dtype=float)
    k = first_turn(np.asarray(P, dtype=float), np.asarray(G, dtype=float), inertia,
                   np.linalg.inv(inertia), d, s)
    return SAFETY * float(s[k] if k >= 0 else s_max) ** 2


def estimate(G: np.ndarray, inertia: np.ndarray, saturated: bool = False
             ) -> SubLevelSet | None:
    """The sub-level-set estimate of gain ``G`` (3 × 6) on inertia ``inertia`` (3 × 3);
    None under a torque limit or when the linearized loop is not stable."""
    if saturated:
        return None
    pq = lyapunov_matrix(G, inertia)
    if pq is None:
        return None
    P, Q = pq
    return SubLevelSet(P, Q, edge_level(P), certified_level(P, Q, inertia),
                       sampled_level(P, G, inertia))


def states_inside(region: SubLevelSet, level: float, n: int, seed: int = SEED,
                  boundary_share: float = 0.5) -> np.ndarray:
    """``n`` seeded initial states (n, 7) = (q, ω), q0 ≥ 0, in {V ≤ level}: the two
    boundary points of largest |q_v| (the largest rotations of the set), then a share
    ``boundary_share`` on the boundary V = level, the rest uniform in the ellipsoid."""
    rng = np.random.default_rng(seed)
    Pinv = np.linalg.inv(region.P)
    top = np.concatenate([np.linalg.eigh(Pinv[:3, :3])[1][:, -1], np.zeros(3)])
    far = Pinv @ top / np.sqrt(top @ Pinv @ top)  # boundary point of largest |q_v| at V = 1
    d = np.vstack([far, -far, _directions(region.P, max(n - 2, 0), rng)])[:n]
    n_edge = max(int(round(boundary_share * n)), min(n, 2))
    radius = np.sqrt(level) * np.concatenate([np.ones(n_edge),
                                              rng.random(n - n_edge) ** (1.0 / 6.0)])
    x = radius[:, None] * d
    q0 = np.sqrt(np.clip(1.0 - np.sum(x[:, :3] ** 2, axis=1), 0.0, None))
    return np.column_stack([q0, x])


def check(problem: Any, mats: Any, level: float, n: int = 64, seed: int = SEED
          ) -> dict[str, Any]:
    """Run one gain of ``problem`` from ``n`` seeded starts inside {V ≤ level} (half on its
    boundary) at the problem's own run horizon; ``converged`` (n,) and ``y0`` (n, 7)."""
    region = problem.sublevel_set(mats)
    y0 = states_inside(region, level, n, seed)
    res = problem.evaluate_states(mats, y0)
    return {"converged": np.asarray(res["converged"], bool), "y0": y0,
            "t_final": np.asarray(res["t_final"], float)}


__all__ = ["N_DIRECTIONS", "N_RADII", "SAFETY", "SEED", "SubLevelSet", "certified_level",
           "check", "closed_loop_matrix", "edge_level", "estimate", "lyapunov_matrix",
           "sampled_level", "states_inside", "vdot"]
