"""Example problem outside penaltyrun: LQR with actuator limits on a nonlinear cart-pole.

A pole (point mass ``m`` at distance ``l`` on a massless rod) is hinged on a cart (mass
``M``) pushed by a horizontal force ``F``. With ``θ`` the pole angle from upright
(positive when the mass is at ``x + l sin θ``), Lagrange's equations give

    (M + m) ẍ + m l cos θ θ̈ − m l sin θ θ̇² = F
    m l cos θ ẍ + m l² θ̈ − m g l sin θ = 0

so ẍ = (F + m sin θ (l θ̇² − g cos θ)) / (M + m sin² θ) and θ̈ = (g sin θ − cos θ ẍ) / l.

The controller is the LQR of the model linearized at upright, ``K = R⁻¹ Bᵀ P`` with ``P``
from the continuous algebraic Riccati equation (scipy ``solve_continuous_are``), applied
to the nonlinear plant through an actuator limit: ``F = clip(−K s, −u_max, u_max)`` with
``s = (x, ẋ, θ, θ̇)``. penaltyrun tunes ``Q`` (4 × 4) and ``R`` (1 × 1), diagonal or full.

Cost (SI units): ``J = ∫₀ᵀ (x² + θ² + rho F²) dt`` (m² s, rad² s, N² s) over a fixed
horizon ``T = t_max``. A run that leaves the track (``|x| > x_max``) or lets the pole fall
(``|θ| > theta_fail``) at time ``t_f`` costs ``J(t_f) + failure_penalty (1 + (T − t_f)/T)``;
one still away from upright at ``T`` (``‖s(T)‖ > tol``) costs
``J(T) + failure_penalty ‖s(T)‖ / ‖s(0)‖``. The simulation is a vectorized fixed-step
RK4 (step ``dt``) over the whole batch. The actuator limit's kink makes it second order
where the force leaves the limit: with ``dt`` = 5 ms the states agree with scipy
``solve_ivp`` to about 2e-4 and the cost to about 1e-5 (tests/examples/test_cartpole.py).

This module follows ``penaltyrun/problems/base.py`` (``CASES``, ``DEFAULT_CASE``,
``Params``, ``make_problem``) and is found through the ``module: cartpole`` key of
``conf/problem/cartpole.yaml`` with this folder on ``PYTHONPATH``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import solve_continuous_are

from penaltyrun.problems.base import (
    BatchEvaluation,
    MatrixSpec,
    ParamsMixin,
    ReportInfo,
    ScalarSpec,
    check_spd,
)

CASES = ("far", "near")
DEFAULT_CASE = "far"
#: Initial state (x m, ẋ m/s, θ rad, θ̇ rad/s) of each case.
CASE_PARAMS: dict[str, dict[str, Any]] = {
    "far": {"s0": (0.0, 0.0, float(np.deg2rad(35.0)), 0.0)},
    "near": {"s0": (0.5, 0.0, float(np.deg2rad(10.0)), 0.0)},
}
STATUSES = ("converged", "fell", "off_track", "not_settled", "no_gain", "nonfinite")


@dataclass(frozen=True)
class Params(ParamsMixin):
    """Cart-pole parameters (SI units).

    Attributes
    ----------
    cart_mass, pole_mass : float
        M and m, kg.
    length : float
        l, distance from the hinge to the pole's mass, m.
    gravity : float
        g, m/s².
    u_max : float
        Actuator limit on |F|, N.
    s0 : tuple of float
        Initial state (x m, ẋ m/s, θ rad, θ̇ rad/s); set by the case.
    t_max : float
        Horizon T, s.
    dt : float
        RK4 step, s.
    x_max : float
        Track half-length, m.
    theta_fail : float
        |θ| beyond which the pole has fallen, rad.
    tol : float
        ‖s(T)‖ at or below which the run has settled.
    rho : float
        Weight of F² in the cost, 1/N².
    eig_bounds_q, eig_bounds_r : tuple of float
        Eigenvalue (diagonal-entry) bounds of Q and R.
    failure_penalty : float
        Penalty scale of failed runs.
    """

    cart_mass: float = 1.0
    pole_mass: float = 0.1
    length: float = 0.5
    gravity: float = 9.81
    u_max: float = 10.0
    s0: tuple[float, float, float, float] = (0.0, 0.0, float(np.deg2rad(35.0)), 0.0)
    t_max: float = 8.0
    dt: float = 0.005
    x_max: float = 5.0
    theta_fail: float = float(np.pi / 2)
    tol: float = 1e-2
    rho: float = 0.01
    eig_bounds_q: tuple[float, float] = (1e-2, 100.0)
    eig_bounds_r: tuple[float, float] = (1e-2, 10.0)
    failure_penalty: float = 100.0


def rhs(s: np.ndarray, F: np.ndarray, p: Params) -> np.ndarray:
    """Nonlinear cart-pole dynamics, batched.

    Parameters
    ----------
    s : ndarray, shape (B, 4)
        States (x, ẋ, θ, θ̇).
    F : ndarray, shape (B,)
        Force on the cart, N.
    p : Params

    Returns
    -------
    ndarray, shape (B, 4)
        Time derivatives.
    """
    M, m, l, g = p.cart_mass, p.pole_mass, p.length, p.gravity
    th, om = s[:, 2], s[:, 3]
    sin, cos = np.sin(th), np.cos(th)
    xdd = (F + m * sin * (l * om**2 - g * cos)) / (M + m * sin**2)
    thdd = (g * sin - cos * xdd) / l
    return np.stack([s[:, 1], xdd, om, thdd], axis=1)


def linearization(p: Params) -> tuple[np.ndarray, np.ndarray]:
    """A (4 × 4) and B (4 × 1) of the dynamics linearized at upright, s = 0, F = 0."""
    M, m, l, g = p.cart_mass, p.pole_mass, p.length, p.gravity
    A = np.array([[0.0, 1.0, 0.0, 0.0],
                  [0.0, 0.0, -m * g / M, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [0.0, 0.0, (M + m) * g / (M * l), 0.0]])
    B = np.array([[0.0], [1.0 / M], [0.0], [-1.0 / (M * l)]])
    return A, B


def lqr_gain(Q: np.ndarray, R: np.ndarray, p: Params) -> np.ndarray:
    """LQR gain K = R⁻¹ Bᵀ P (shape (1, 4)) of the linearized model."""
    A, B = linearization(p)
    P = solve_continuous_are(A, B, Q, R)
    return np.linalg.solve(R, B.T @ P)


def energy(s: np.ndarray, p: Params) -> np.ndarray:
    """Mechanical energy T + V of states ``s`` (B, 4), J (V = 0 at the hinge height)."""
    M, m, l, g = p.cart_mass, p.pole_mass, p.length, p.gravity
    xd, th, om = s[:, 1], s[:, 2], s[:, 3]
    kin = 0.5 * (M + m) * xd**2 + m * l * np.cos(th) * xd * om + 0.5 * m * l**2 * om**2
    return kin + m * g * l * np.cos(th)


def simulate_batch(K: np.ndarray, p: Params, record: bool = False) -> dict[str, np.ndarray]:
    """RK4 closed-loop runs of a batch of gains with the actuator limit.

    Parameters
    ----------
    K : ndarray, shape (B, 4)
        State-feedback gains (F = clip(−K s, ±u_max)).
    p : Params
    record : bool
        Also return the time histories (for plots and tests).

    Returns
    -------
    dict
        ``cost`` (B,), ``t_end`` (B,), ``status`` (B,) int codes into :data:`STATUSES`,
        ``final`` (B, 4) state at the end; with ``record`` also ``t`` (n,), ``s`` (n, B, 4)
        and ``F`` (n, B) (entries after a run ended repeat its last value).
    """
    K = np.asarray(K, dtype=float)
    n_b = K.shape[0]
    n_steps = int(round(p.t_max / p.dt))
    h = p.t_max / n_steps
    s = np.tile(np.asarray(p.s0, float), (n_b, 1))
    cost = np.zeros(n_b)
    t_end = np.full(n_b, p.t_max)
    status = np.zeros(n_b, dtype=int)
    alive = np.ones(n_b, dtype=bool)

    def aug(s_: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        F = np.clip(-np.einsum("bi,bi->b", K, s_), -p.u_max, p.u_max)
        run_cost = s_[:, 0] ** 2 + s_[:, 2] ** 2 + p.rho * F**2
        return rhs(s_, F, p), run_cost

    hist_s, hist_F = [s.copy()], [np.clip(-np.einsum("bi,bi->b", K, s), -p.u_max, p.u_max)]
    for i in range(n_steps):
        k1, c1 = aug(s)
        k2, c2 = aug(s + 0.5 * h * k1)
        k3, c3 = aug(s + 0.5 * h * k2)
        k4, c4 = aug(s + h * k3)
        s_new = s + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        cost_new = cost + h / 6.0 * (c1 + 2 * c2 + 2 * c3 + c4)
        s = np.where(alive[:, None], s_new, s)
        cost = np.where(alive, cost_new, cost)
        bad = alive & ~np.all(np.isfinite(s), axis=1)
        fell = alive & ~bad & (np.abs(s[:, 2]) > p.theta_fail)
        off = alive & ~bad & ~fell & (np.abs(s[:, 0]) > p.x_max)
        for code, mask in ((STATUSES.index("nonfinite"), bad), (STATUSES.index("fell"), fell),
                           (STATUSES.index("off_track"), off)):
            status[mask] = code
            t_end[mask] = (i + 1) * h
        alive &= ~(bad | fell | off)
        if record:
            hist_s.append(s.copy())
            hist_F.append(np.clip(-np.einsum("bi,bi->b", K, s), -p.u_max, p.u_max))
        if not alive.any():
            break
    settled = np.linalg.norm(s, axis=1) <= p.tol
    status[alive & ~settled] = STATUSES.index("not_settled")
    out = {"cost": cost, "t_end": t_end, "status": status, "final": s}
    if record:
        out.update({"t": h * np.arange(len(hist_s)), "s": np.asarray(hist_s),
                    "F": np.asarray(hist_F)})
    return out


class CartPole:
    """Cart-pole swing-in by a saturated LQR; tuned matrices ``Q`` (4 × 4), ``R`` (1 × 1)."""

    name = "cartpole"

    def __init__(self, case: str, params: Params) -> None:
        self.case = case
        self.params = params
        self.matrices = (MatrixSpec("Q", 4, tuple(map(float, params.eig_bounds_q))),
                         MatrixSpec("R", 1, tuple(map(float, params.eig_bounds_r))))
        self.scalars: tuple[ScalarSpec, ...] = ()

    def gains(self, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Gains (B, 4) of a batch of (Q, R), and whether the Riccati solve succeeded."""
        K = np.zeros((Q.shape[0], 4))
        ok = np.ones(Q.shape[0], dtype=bool)
        for b in range(Q.shape[0]):
            try:
                K[b] = lqr_gain(Q[b], R[b], self.params)[0]
            except (np.linalg.LinAlgError, ValueError):
                ok[b] = False
        ok &= np.all(np.isfinite(K), axis=1)
        K[~ok] = 0.0
        return K, ok

    def _graded(self, run: dict[str, np.ndarray], ok: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        status = np.where(ok, run["status"], STATUSES.index("no_gain"))
        fail_early = p.failure_penalty * (1.0 + (p.t_max - run["t_end"]) / p.t_max)
        d0 = float(np.linalg.norm(p.s0)) or 1.0
        dist = np.linalg.norm(np.nan_to_num(run["final"], nan=1e6, posinf=1e6), axis=1)
        cost = np.nan_to_num(run["cost"], nan=0.0, posinf=0.0)
        graded = np.where(status == 0, cost, cost + fail_early)
        graded = np.where(status == STATUSES.index("not_settled"),
                          cost + p.failure_penalty * dist / d0, graded)
        graded = np.where(np.isin(status, [STATUSES.index("no_gain"),
                                           STATUSES.index("nonfinite")]),
                          10.0 * p.failure_penalty, graded)
        return graded, status

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None
    ) -> BatchEvaluation:
        """Costs of a batch: ``mats["Q"]`` (B, 4, 4), ``mats["R"]`` (B, 1, 1)."""
        K, ok = self.gains(np.asarray(mats["Q"], float), np.asarray(mats["R"], float))
        run = simulate_batch(K, self.params)
        graded, status = self._graded(run, ok)
        names = np.asarray([STATUSES[int(c)] for c in status], dtype=object)
        return BatchEvaluation(cost=graded, converged=status == 0, status=names)

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Detailed evaluation of one (Q, R); JSON-serializable."""
        Q = check_spd("matrices.Q", mats["Q"], 4)
        R = check_spd("matrices.R", mats["R"], 1)
        K, ok = self.gains(Q[None], R[None])
        run = simulate_batch(K, self.params)
        graded, status = self._graded(run, ok)
        return {"problem": self.name, "case": self.case, "cost": float(graded[0]),
                "tracking_cost": float(run["cost"][0]), "converged": bool(status[0] == 0),
                "status": STATUSES[int(status[0])], "t_final": float(run["t_end"][0]),
                "gain": K[0].tolist(), "final_state": run["final"][0].tolist()}

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, np.ndarray]:
        """Time histories of one (Q, R): ``t`` s, ``x`` m, ``theta`` rad, ``F`` N."""
        Q = check_spd("matrices.Q", mats["Q"], 4)
        R = check_spd("matrices.R", mats["R"], 1)
        K, _ = self.gains(Q[None], R[None])
        run = simulate_batch(K, self.params, record=True)
        return {"t": run["t"], "x": run["s"][:, 0, 0], "x_dot": run["s"][:, 0, 1],
                "theta": run["s"][:, 0, 2], "theta_dot": run["s"][:, 0, 3],
                "F": run["F"][:, 0]}


def make_problem(case: str, overrides: Mapping[str, Any]) -> CartPole:
    """Build the cart-pole problem: defaults → case entry → ``overrides``."""
    return CartPole(case, Params.from_mapping({**CASE_PARAMS[case], **dict(overrides)}))


def plot_response(paths: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Pole angle (deg) against time for several runs of :meth:`CartPole.simulate`."""
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    for label, path in paths.items():
        ax.plot(path["t"], np.rad2deg(path["theta"]), label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("θ (deg)")
    ax.legend(fontsize=8)
    return ax


def report_info(case: str, params: Mapping[str, Any]) -> ReportInfo:
    """Report hook: what the cost is, with its unit (SI; x in m, θ in rad, F in N)."""
    return ReportInfo(cost_name="J = ∫(x² + θ² + ρF²) dt", cost_unit="SI: m²·s, rad²·s")


def report_plots(sims: Mapping[str, Mapping[str, np.ndarray]], case: str,
                 params: Mapping[str, Any]) -> dict[str, Any]:
    """Report hook: the pole angle of the best diagonal and best full (Q, R)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    plot_response(sims, ax=ax)
    ax.set_title(f"cart-pole / {case}: pole angle of the best starts")
    return {"pole angle": fig}
