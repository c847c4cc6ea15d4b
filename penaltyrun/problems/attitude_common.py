"""Shared parts of the spacecraft attitude problems (``attitude_lyapunov``, ``attitude_lqr``).

Rigid spacecraft, quaternion kinematics and Euler's equation (see
:mod:`penaltyrun.dynamics.attitude`), a linear state feedback u = −G (q_v, ω) whose gain
G (3 × 6) comes from the tuned matrices (PD: G = [K_p, K_d]; LQR: G = R⁻¹BᵀP), and the
minimum-energy cost J = ∫ ½ uᵀu dt (N²·m²·s) up to the FIRST time the distance
‖(q0 − 1, q1, q2, q3, ω)‖ falls to ``tol``.

Cost of a candidate (always finite):

* event fired before ``t_max``: ``cost = J(t_event)``;
* otherwise (``horizon``, ``step_failure``): the graded penalty
  ``cost = J(t_end) + failure_penalty · (1 + d(t_end) / d(0))`` where d is the distance to
  the target, so every failure costs more than ``failure_penalty`` and failures are ranked
  by how close they got;
* non-finite results (``nonfinite``) and LQR gains whose Riccati equation has no
  stabilizing solution (``care_failure``): ``cost = 1000 · failure_penalty``.

Cases: ``detumble`` (ω0 = (0.01, −0.01, 0.01) rad/s) and ``rest_to_rest`` (ω0 = 0), both
from Euler angles (yaw, pitch, roll) = (60°, 80°, −60°), intrinsic Z-Y-X, I = diag(10, 15, 20)
kg·m², t_max = 100 s. Initial quaternions are normalized to unit length with q0 ≥ 0.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from numbers import Integral, Real
from typing import Any

import numpy as np

from penaltyrun.dynamics import attitude as kernel
from penaltyrun.dynamics import integrate
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import BatchEvaluation, MatrixSpec, ParamsMixin, ScalarSpec

logger = logging.getLogger(__name__)

#: Parameters that do not change a run's result (reports do not split cells by them).
VARIANT_IGNORE = ("holdout_n", "holdout_lo_deg", "holdout_hi_deg")

CASES = ("detumble", "rest_to_rest")
DEFAULT_CASE = "detumble"
CASE_PARAMS: dict[str, dict[str, Any]] = {
    "detumble": {"omega0": (0.01, -0.01, 0.01)},
    "rest_to_rest": {"omega0": (0.0, 0.0, 0.0)},
}
#: Allowed values of :attr:`Params.attitude_type`.
ATTITUDE_TYPES = ("euler", "quaternion", "mrp")
#: Status name of an LQR candidate without a stabilizing Riccati solution.
CARE_FAILURE = "care_failure"
#: Cost multiple of ``failure_penalty`` for non-finite runs and Riccati failures.
HARD_FAILURE_FACTOR = 1000.0
#: Held-out set (referee objection 3): rest-to-rest from yaw, pitch, roll each in
#: linspace(lo, hi, n) degrees (216 starts).


@dataclass(frozen=True)
class Params(ParamsMixin):
    """Attitude problem parameters (SI units).

    Attributes
    ----------
    inertia : tuple
        Inertia in kg·m²: 3 principal moments (diagonal) or a symmetric PD 3×3 nested tuple.
    attitude_type : str
        How ``attitude`` is given: ``"euler"`` (yaw, pitch, roll in degrees, intrinsic
        Z-Y-X), ``"quaternion"`` (q0, q1, q2, q3, scalar first; normalized) or ``"mrp"``
        (modified Rodrigues parameters σ1, σ2, σ3).
    attitude : tuple of float
        Initial attitude in the representation ``attitude_type``.
    omega0 : tuple of float
        Initial body rates (rad/s).
    t_max : float
        Horizon cap t_f (s); the terminal event must fire before it.
    tol : float
        Terminal event ‖(q0 − 1, q_v, ω)‖ ≤ tol (mixed units: quaternion and rad/s).
    u_max : float or None
        Per-axis torque limit |u_i| ≤ u_max (N·m); ``None``: no saturation.
    rtol, atol : float
        Integration tolerances (paper: 1e-10).
    max_step : float
        Largest integration step (s).
    n_event_samples : int
        Dense-output points per step where the event is checked (so a short dip of the
        non-monotone distance under ``tol`` is not stepped over).
    max_steps : int
        Step cap per run (hitting it counts as ``step_failure``).
    eig_bounds : tuple of float
        Eigenvalue (or diagonal-entry) bounds of every tuned matrix.
    failure_penalty : float
        Scale of the graded penalty of runs whose event does not fire (N²·m²·s).
    holdout_n : int
        Held-out robustness grid: yaw, pitch and roll each take ``holdout_n`` values in
        linspace(holdout_lo_deg, holdout_hi_deg) → holdout_n³ rest-to-rest starts
        (0 disables the held-out evaluation).
    holdout_lo_deg, holdout_hi_deg : float
        Range of the held-out Euler angles (degrees).
    """

    inertia: tuple = (10.0, 15.0, 20.0)
    attitude_type: str = "euler"
    attitude: tuple = (60.0, 80.0, -60.0)
    omega0: tuple = (0.01, -0.01, 0.01)
    t_max: float = 100.0
    tol: float = 1e-4
    u_max: float | None = None
    rtol: float = 1e-10
    atol: float = 1e-10
    max_step: float = 0.2
    n_event_samples: int = 4
    max_steps: int = 1_000_000
    eig_bounds: tuple = (1e-8, 10.0)
    failure_penalty: float = 1000.0
    holdout_n: int = 6
    holdout_lo_deg: float = 10.0
    holdout_hi_deg: float = 350.0

    def __post_init__(self) -> None:
        inertia = self.inertia
        if len(inertia) == 3 and all(np.ndim(row) == 1 for row in inertia):
            object.__setattr__(self, "inertia", tuple(tuple(float(v) for v in row)
                                                      for row in inertia))
        else:
            object.__setattr__(self, "inertia", tuple(inertia))

    def inertia_matrix(self) -> np.ndarray:
        """Inertia as a 3×3 array (kg·m²)."""
        arr = np.asarray(self.inertia, dtype=float)
        return np.diag(arr) if arr.ndim == 1 else arr

    def initial_quaternion(self) -> np.ndarray:
        """Unit initial quaternion with q0 ≥ 0, shape (4,)."""
        return attitude_to_quaternion(self.attitude_type, self.attitude)

    def initial_state(self) -> np.ndarray:
        """Initial (q, ω), shape (7,)."""
        return np.concatenate([self.initial_quaternion(), np.asarray(self.omega0, float)])

    def saturation(self) -> float:
        """Per-axis torque limit for the kernel (``inf`` when saturation is off)."""
        return float("inf") if self.u_max is None else float(self.u_max)


def validate(params: Params) -> Params:
    """Check parameter values; returns ``params`` unchanged.

    Raises
    ------
    ConfigError
        Naming the first offending key.
    """
    try:
        inertia = params.inertia_matrix()
    except (TypeError, ValueError):
        raise ConfigError("problem.inertia", "expected 3 moments or a 3x3 matrix") from None
    if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)):
        raise ConfigError("problem.inertia", "expected 3 moments or a 3x3 matrix")
    if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-12 * np.max(np.abs(inertia))) \
            or np.linalg.eigvalsh(inertia)[0] <= 0.0:
        raise ConfigError("problem.inertia", "inertia must be symmetric positive definite")
    if params.attitude_type not in ATTITUDE_TYPES:
        raise ConfigError("problem.attitude_type", f"unknown type {params.attitude_type!r}",
                          allowed=ATTITUDE_TYPES)
    need = 4 if params.attitude_type == "quaternion" else 3
    att = np.asarray(params.attitude, dtype=float)
    if att.shape != (need,) or not np.all(np.isfinite(att)):
        raise ConfigError("problem.attitude",
                          f"expected {need} finite numbers for type {params.attitude_type!r}")
    if need == 4 and np.linalg.norm(att) == 0.0:
        raise ConfigError("problem.attitude", "quaternion must be nonzero")
    w0 = np.asarray(params.omega0, dtype=float)
    if w0.shape != (3,) or not np.all(np.isfinite(w0)):
        raise ConfigError("problem.omega0", "expected 3 finite rates (rad/s)")
    for key in ("t_max", "tol", "rtol", "atol", "max_step", "failure_penalty"):
        value = getattr(params, key)
        if not (isinstance(value, Real) and value > 0):
            raise ConfigError(f"problem.{key}", f"must be a positive number, got {value!r}")
    if params.u_max is not None and not (isinstance(params.u_max, Real) and params.u_max > 0):
        raise ConfigError("problem.u_max", "must be null (off) or a positive torque (N·m)")
    for key in ("n_event_samples", "max_steps"):
        value = getattr(params, key)
        if not (isinstance(value, Integral) and value >= 1):
            raise ConfigError(f"problem.{key}", f"must be a positive integer, got {value!r}")
    lo, hi = (float(v) for v in params.eig_bounds)
    if not 0.0 < lo < hi:
        raise ConfigError("problem.eig_bounds", "need 0 < lower < upper")
    return params


def build_params(cls: type[Params], case: str, overrides: Mapping[str, Any]) -> Params:
    """Defaults → case entry → ``overrides``, validated.

    Raises
    ------
    ConfigError
        Unknown case or parameter, or an invalid value.
    """
    if case not in CASES:
        raise ConfigError("case", f"unknown case {case!r}", allowed=CASES)
    merged = {**CASE_PARAMS[case], **dict(overrides)}
    return validate(cls.from_mapping(merged))


# --------------------------------------------------------------------------- attitudes


def normalize_quaternion(q: Any) -> np.ndarray:
    """Unit quaternion(s) with q0 ≥ 0 (q and −q are the same attitude).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first quaternions.

    Returns
    -------
    ndarray, shape (..., 4)
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def euler_to_quaternion(angles_deg: Any) -> np.ndarray:
    """Quaternion of intrinsic Z-Y-X Euler angles, normalized to q0 ≥ 0.

    Parameters
    ----------
    angles_deg : array_like, shape (..., 3)
        (yaw, pitch, roll) in degrees; the rotation is yaw about z, then pitch about the new
        y, then roll about the newest x (q = q_z(yaw) ⊗ q_y(pitch) ⊗ q_x(roll)).

    Returns
    -------
    ndarray, shape (..., 4)
        Scalar-first unit quaternions with q0 ≥ 0.
    """
    a = np.radians(np.asarray(angles_deg, dtype=float)) / 2.0
    cy, sy = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cr, sr = np.cos(a[..., 2]), np.sin(a[..., 2])
    q = np.stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ], axis=-1)
    return normalize_quaternion(q)


def mrp_to_quaternion(sigma: Any) -> np.ndarray:
    """Quaternion of modified Rodrigues parameters, normalized to q0 ≥ 0.

    Parameters
    ----------
    sigma : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    s = np.asarray(sigma, dtype=float)
    s2 = np.sum(s * s, axis=-1, keepdims=True)
    q = np.concatenate([(1.0 - s2) / (1.0 + s2), 2.0 * s / (1.0 + s2)], axis=-1)
    return normalize_quaternion(q)


def attitude_to_quaternion(kind: str, values: Any) -> np.ndarray:
    """Unit quaternion (q0 ≥ 0) from an attitude given as ``kind`` (see :data:`ATTITUDE_TYPES`).

    Raises
    ------
    ConfigError
        Unknown ``kind``.
    """
    if kind == "euler":
        return euler_to_quaternion(values)
    if kind == "quaternion":
        return normalize_quaternion(values)
    if kind == "mrp":
        return mrp_to_quaternion(values)
    raise ConfigError("problem.attitude_type", f"unknown type {kind!r}", allowed=ATTITUDE_TYPES)


def robustness_grid(n: int = 6, lo: float = 10.0, hi: float = 350.0) -> np.ndarray:
    """Grid of (yaw, pitch, roll) in degrees, each in linspace(lo, hi, n); shape (n³, 3)."""
    g = np.linspace(lo, hi, n)
    Y, P, R = np.meshgrid(g, g, g, indexing="ij")
    return np.stack([Y.ravel(), P.ravel(), R.ravel()], axis=1)


# --------------------------------------------------------------------------- problem


def graded_cost(energy: np.ndarray, dist: np.ndarray, d0: Any, status: np.ndarray,
                failure_penalty: float) -> np.ndarray:
    """Objective from raw run results (see the module docstring), always finite.

    Parameters
    ----------
    energy : ndarray, shape (R,)
        J at the end of each run (N²·m²·s).
    dist : ndarray, shape (R,)
        Distance to the target at the end of each run.
    d0 : float or ndarray, shape (R,)
        Initial distance(s) (floored at a tiny positive value).
    status : ndarray of int, shape (R,)
        Integrator status codes.
    failure_penalty : float

    Returns
    -------
    ndarray, shape (R,)
    """
    d0 = np.maximum(np.asarray(d0, dtype=float), 1e-300)
    with np.errstate(invalid="ignore", over="ignore"):
        failed = energy + failure_penalty * (1.0 + dist / d0)
    cost = np.where(status == integrate.EVENT, energy, failed)
    hard = (~np.isfinite(cost)) | (status == integrate.NONFINITE)
    return np.where(hard, HARD_FAILURE_FACTOR * failure_penalty, cost)


def status_strings(status: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Status names: ``"converged"``, the integrator failure name, or ``"care_failure"``."""
    names = []
    for s, good in zip(status, ok):
        if not good:
            names.append(CARE_FAILURE)
        elif int(s) == integrate.EVENT:
            names.append("converged")
        else:
            names.append(integrate.STATUS_NAMES[int(s)])
    return np.asarray(names, dtype=object)


class AttitudeProblem:
    """Attitude closed loop with a linear gain built from the tuned matrices.

    Parameters
    ----------
    name : str
        Registered problem name.
    case : str
        Case name (one of :data:`CASES`).
    params : Params
        Validated parameters.
    matrices : tuple of MatrixSpec
        The tuned matrices.
    gains : callable
        ``gains(mats) -> (G, ok)`` with ``mats[name]`` of shape (B, N, N), ``G`` of shape
        (B, 3, 6) and ``ok`` (B,) bool (False: no gain could be built).
    """

    def __init__(self, name: str, case: str, params: Params, matrices: tuple[MatrixSpec, ...],
                 gains: Callable[[Mapping[str, np.ndarray]], tuple[np.ndarray, np.ndarray]]
                 ) -> None:
        self.name = name
        self.case = case
        self.params = params
        self.matrices = matrices
        self.scalars: tuple[ScalarSpec, ...] = ()
        self.gains = gains
        self.inertia = params.inertia_matrix()
        self.inertia_inv = np.linalg.inv(self.inertia)
        self.y0 = params.initial_state()
        self.d0 = float(np.sqrt((self.y0[0] - 1.0) ** 2 + np.sum(self.y0[1:] ** 2)))

    def run(self, G: np.ndarray, y0: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Raw kernel runs (see :func:`penaltyrun.dynamics.attitude.simulate_batch`).

        Parameters
        ----------
        G : ndarray, shape (B, 3, 6)
            Gains.
        y0 : ndarray, shape (S, 7), optional
            Initial states (default: the problem's); B or S may be 1 (broadcast).

        Returns
        -------
        t_end, energy, dist, status : ndarray, shape (max(B, S),)
        """
        p = self.params
        y0 = self.y0[None] if y0 is None else y0
        return kernel.simulate_batch(
            np.ascontiguousarray(G, dtype=float), np.ascontiguousarray(y0, dtype=float),
            self.inertia, self.inertia_inv, float(p.t_max), float(p.tol), p.saturation(),
            float(p.rtol), float(p.atol), float(p.max_step), int(p.n_event_samples),
            int(p.max_steps))

    def _finish(self, G: np.ndarray, ok: np.ndarray, y0: np.ndarray | None,
                d0: Any) -> dict[str, np.ndarray]:
        n = max(G.shape[0], 1 if y0 is None else y0.shape[0])
        t_end, energy, dist, status = self.run(np.where(ok[:, None, None], G, 0.0), y0)
        ok_full = np.broadcast_to(ok, (n,))
        cost = graded_cost(energy, dist, d0, status, self.params.failure_penalty)
        cost = np.where(ok_full, cost, HARD_FAILURE_FACTOR * self.params.failure_penalty)
        converged = ok_full & (status == integrate.EVENT)
        return {"cost": cost, "converged": converged, "status": status_strings(status, ok_full),
                "energy": energy, "t_final": t_end, "final_distance": dist}

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None
    ) -> BatchEvaluation:
        """Costs of B candidates; ``mats[name]`` has shape (B, N, N) (not re-validated)."""
        G, ok = self.gains(mats)
        res = self._finish(G, ok, None, self.d0)
        return BatchEvaluation(cost=res["cost"], converged=res["converged"],
                               status=res["status"])

    def _check(self, mats: Mapping[str, Any]) -> dict[str, np.ndarray]:
        from penaltyrun.problems.base import check_spd

        out = {}
        for spec in self.matrices:
            if spec.name not in mats:
                raise ConfigError(f"matrices.{spec.name}", "missing matrix")
            out[spec.name] = check_spd(f"matrices.{spec.name}", mats[spec.name], spec.size)
        return out

    def gain(self, mats: Mapping[str, Any]) -> np.ndarray:
        """Validated gain G (3, 6) of one candidate.

        Raises
        ------
        ConfigError
            Malformed matrices, or (LQR) no stabilizing Riccati solution.
        """
        checked = self._check(mats)
        G, ok = self.gains({k: v[None] for k, v in checked.items()})
        if not ok[0]:
            raise ConfigError("matrices", "no stabilizing Riccati solution for these Q, R")
        return G[0]

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Detailed evaluation of one candidate; JSON-serializable.

        Returns
        -------
        dict
            ``problem``, ``case``, ``cost`` (objective), ``energy`` (J at the end, N²·m²·s),
            ``converged``, ``status``, ``t_final`` (s), ``t_max`` (s), ``final_distance``,
            ``initial_distance``, ``gain`` (3×6 nested list, u = −gain·(q_v, ω)).
        """
        checked = self._check(mats)
        G, ok = self.gains({k: v[None] for k, v in checked.items()})
        res = self._finish(G, ok, None, self.d0)
        return {
            "problem": self.name,
            "case": self.case,
            "cost": float(res["cost"][0]),
            "energy": float(res["energy"][0]),
            "converged": bool(res["converged"][0]),
            "status": str(res["status"][0]),
            "t_final": float(res["t_final"][0]),
            "t_max": float(self.params.t_max),
            "final_distance": float(res["final_distance"][0]),
            "initial_distance": self.d0,
            "gain": G[0].tolist(),
        }

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None,
        n_points: int = 500,
    ) -> dict[str, np.ndarray]:
        """Time histories of one candidate for plots, up to its event time (or ``t_max``).

        The end time comes from the production kernel; the histories are scipy DOP853 dense
        output at the problem's tolerances.

        Returns
        -------
        dict
            ``t`` (n,) s, ``q`` (n, 4), ``w`` (n, 3) rad/s, ``u`` (n, 3) N·m, ``J`` (n,),
            ``dist`` (n,) distance to the target.
        """
        G = self.gain(mats)
        t_end = float(self.run(G[None])[0][0])
        return trajectory(G, self.params, t_end, n_points, self.y0)

    def evaluate_grid(self, mats: Mapping[str, Any], attitudes_deg: Any) -> dict[str, np.ndarray]:
        """Evaluate one candidate from many initial attitudes (Euler angles, degrees).

        Rates, inertia, horizon and tolerances are this problem's. See :func:`evaluate_grid`.
        """
        G = self.gain(mats)
        att = np.atleast_2d(np.asarray(attitudes_deg, dtype=float))
        if att.ndim != 2 or att.shape[1] != 3:
            raise ConfigError("attitudes_deg", f"expected shape (n, 3), got {att.shape}")
        q = euler_to_quaternion(att)
        y0 = np.concatenate([q, np.broadcast_to(np.asarray(self.params.omega0, float),
                                                (q.shape[0], 3))], axis=1)
        d0 = np.sqrt((y0[:, 0] - 1.0) ** 2 + np.sum(y0[:, 1:] ** 2, axis=1))
        res = self._finish(G[None], np.ones(1, dtype=bool), y0, d0)
        res.update({"attitudes_deg": att, "q0": q, "initial_distance": d0})
        return res

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, np.ndarray] | None:
        """Evaluate one candidate on the held-out set (runner hook).

        The set is rest-to-rest (ω0 = 0, whatever this problem's case) from the attitudes of
        :func:`robustness_grid` with ``holdout_n``, ``holdout_lo_deg``, ``holdout_hi_deg``;
        inertia, horizon and tolerances are this problem's.

        Returns
        -------
        dict of ndarray or None
            As :func:`evaluate_grid` without ``q0``; ``None`` if the candidate has no gain
            (LQR without a stabilizing Riccati solution) or ``holdout_n`` is 0.
        """
        p = self.params
        if p.holdout_n <= 0:
            return None
        grid = robustness_grid(p.holdout_n, p.holdout_lo_deg, p.holdout_hi_deg)
        params = replace(p, omega0=(0.0, 0.0, 0.0))
        rest = AttitudeProblem(self.name, "rest_to_rest", params, self.matrices, self.gains)
        try:
            res = rest.evaluate_grid(mats, grid)
        except ConfigError as exc:
            logger.warning("no held-out evaluation: %s", exc)
            return None
        res.pop("q0")
        return res


def evaluate_grid(problem: Any, mats: Mapping[str, Any], attitudes_deg: Any,
                  params: Mapping[str, Any] | None = None) -> dict[str, np.ndarray]:
    """Evaluate tuned matrices over a grid of initial attitudes (robustness study).

    All starts run in one call of the compiled kernel with the same gain.

    Parameters
    ----------
    problem : str or AttitudeProblem
        A problem instance (its rates, inertia, horizon and tolerances are used), or a
        registered name (``"attitude_lyapunov"`` / ``"attitude_lqr"``), built for the
        ``rest_to_rest`` case with ``params`` overrides.
    mats : mapping
        The candidate's matrices (e.g. ``{"Kp": ..., "Kd": ...}``), each (N, N).
    attitudes_deg : array_like, shape (n, 3)
        (yaw, pitch, roll) in degrees, intrinsic Z-Y-X (e.g. :func:`robustness_grid`).
    params : mapping, optional
        Overrides when ``problem`` is a name.

    Returns
    -------
    dict of ndarray, each of length n
        ``cost``, ``converged``, ``status``, ``energy``, ``t_final``, ``final_distance``,
        ``initial_distance``, plus ``attitudes_deg`` (n, 3) and ``q0`` (n, 4) (normalized,
        q0 ≥ 0).
    """
    if isinstance(problem, str):
        from penaltyrun import problems as registry

        problem = registry.module(problem).make_problem("rest_to_rest", dict(params or {}))
    return problem.evaluate_grid(mats, attitudes_deg)


# --------------------------------------------------------------------------- reference


def _rhs_numpy(G: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray,
               u_max: float) -> Callable[[float, np.ndarray], np.ndarray]:
    """Plain-numpy closed-loop right-hand side for scipy (independent of the kernel)."""

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        q, w = y[:4], y[4:7]
        u = np.clip(-G @ y[1:7], -u_max, u_max)
        omega = np.array([[0.0, -w[0], -w[1], -w[2]],
                          [w[0], 0.0, w[2], -w[1]],
                          [w[1], -w[2], 0.0, w[0]],
                          [w[2], w[1], -w[0], 0.0]])
        out = np.empty(8)
        out[:4] = 0.5 * omega @ q
        out[4:7] = inertia_inv @ (u - np.cross(w, inertia @ w))
        out[7] = 0.5 * float(u @ u)
        return out

    return rhs


def reference_run(G: Any, params: Params, y0: Any = None, method: str = "DOP853"
                  ) -> dict[str, Any]:
    """Independent scipy ``solve_ivp`` evaluation of one gain (slow; for tests and benches).

    Uses the same event definition, ``max_step`` and tolerances as the kernel; scipy
    checks the event sign at step ends only, which ``max_step`` makes safe.

    Parameters
    ----------
    G : array_like, shape (3, 6)
        Gain of u = −G (q_v, ω).
    params : Params
    y0 : array_like, shape (7,), optional
        Initial (q, ω); default from ``params``.
    method : str
        scipy integrator.

    Returns
    -------
    dict
        ``cost`` (graded, as the production path), ``energy``, ``t_final``, ``converged``,
        ``final_distance``.
    """
    from scipy.integrate import solve_ivp

    G = np.asarray(G, dtype=float)
    inertia = params.inertia_matrix()
    y_init = params.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    rhs = _rhs_numpy(G, inertia, np.linalg.inv(inertia), params.saturation())

    def hit(t: float, y: np.ndarray) -> float:
        return float(np.sqrt((y[0] - 1.0) ** 2 + np.sum(y[1:7] ** 2)) - params.tol)

    hit.terminal = True
    hit.direction = -1.0
    sol = solve_ivp(rhs, (0.0, params.t_max), np.concatenate([y_init, [0.0]]), events=hit,
                    rtol=params.rtol, atol=params.atol, method=method,
                    max_step=params.max_step)
    converged = bool(sol.t_events[0].size)
    y_end = sol.y_events[0][0] if converged else sol.y[:, -1]
    t_end = float(sol.t_events[0][0]) if converged else float(sol.t[-1])
    dist = float(np.sqrt((y_end[0] - 1.0) ** 2 + np.sum(y_end[1:7] ** 2)))
    d0 = float(np.sqrt((y_init[0] - 1.0) ** 2 + np.sum(y_init[1:7] ** 2)))
    status = np.array([integrate.EVENT if converged else integrate.HORIZON])
    if not converged and sol.status != 0:
        status[0] = integrate.STEP_FAILURE
    energy = float(y_end[7])
    cost = float(graded_cost(np.array([energy]), np.array([dist]), d0, status,
                             params.failure_penalty)[0])
    return {"cost": cost, "energy": energy, "t_final": t_end, "converged": converged,
            "final_distance": dist}


def trajectory(G: Any, params: Params, t_end: float, n_points: int = 500,
               y0: Any = None) -> dict[str, np.ndarray]:
    """Closed-loop histories on [0, t_end] by scipy DOP853 dense output.

    Returns
    -------
    dict
        ``t`` (n,) s, ``q`` (n, 4), ``w`` (n, 3) rad/s, ``u`` (n, 3) N·m, ``J`` (n,),
        ``dist`` (n,).
    """
    from scipy.integrate import solve_ivp

    G = np.asarray(G, dtype=float)
    inertia = params.inertia_matrix()
    y_init = params.initial_state() if y0 is None else np.asarray(y0, dtype=float)
    u_max = params.saturation()
    rhs = _rhs_numpy(G, inertia, np.linalg.inv(inertia), u_max)
    t = np.linspace(0.0, t_end, n_points)
    sol = solve_ivp(rhs, (0.0, max(t_end, 1e-12)), np.concatenate([y_init, [0.0]]), t_eval=t,
                    rtol=params.rtol, atol=params.atol, method="DOP853",
                    max_step=params.max_step)
    y = sol.y.T
    u = np.clip(-y[:, 1:7] @ G.T, -u_max, u_max)
    dist = np.sqrt((y[:, 0] - 1.0) ** 2 + np.sum(y[:, 1:7] ** 2, axis=1))
    return {"t": sol.t, "q": y[:, :4], "w": y[:, 4:7], "u": u, "J": y[:, 7], "dist": dist}


# --------------------------------------------------------------------------- plots

_STYLES = ("-", "--", ":", "-.")
_COLORS = ("C0", "C1", "C2", "C3")


def _plot_components(sims: Mapping[str, Mapping[str, np.ndarray]], key: str,
                     names: tuple[str, ...], ylabel: str, ax: Any) -> Any:
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3.5))
    for k, (label, sim) in enumerate(sims.items()):
        style = _STYLES[k % len(_STYLES)]
        data = np.asarray(sim[key])
        for i, comp in enumerate(names):
            ax.plot(sim["t"], data[:, i], style, color=_COLORS[i % len(_COLORS)],
                    label=f"{label}: {comp}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return ax


def plot_quaternions(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Quaternion histories; ``sims`` maps a label (e.g. "best diagonal") to a
    :meth:`AttitudeProblem.simulate` dict. Components by colour, candidates by line style."""
    return _plot_components(sims, "q", ("q0", "q1", "q2", "q3"), "quaternion", ax)


def plot_rates(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Body-rate histories (rad/s); see :func:`plot_quaternions`."""
    return _plot_components(sims, "w", ("ω1", "ω2", "ω3"), "body rate (rad/s)", ax)


def plot_torques(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Control torque histories (N·m); see :func:`plot_quaternions`."""
    return _plot_components(sims, "u", ("u1", "u2", "u3"), "torque (N·m)", ax)


def plot_histories(sims: Mapping[str, Mapping[str, np.ndarray]]) -> Any:
    """Figure with quaternion, rate and torque histories stacked (shared time axis).

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    plot_quaternions(sims, axes[0])
    plot_rates(sims, axes[1])
    plot_torques(sims, axes[2])
    for ax in axes[:2]:
        ax.set_xlabel("")
    fig.tight_layout()
    return fig


__all__ = [
    "ATTITUDE_TYPES",
    "CARE_FAILURE",
    "CASES",
    "CASE_PARAMS",
    "DEFAULT_CASE",
    "VARIANT_IGNORE",
    "AttitudeProblem",
    "Params",
    "attitude_to_quaternion",
    "build_params",
    "euler_to_quaternion",
    "evaluate_grid",
    "graded_cost",
    "mrp_to_quaternion",
    "normalize_quaternion",
    "plot_histories",
    "plot_quaternions",
    "plot_rates",
    "plot_torques",
    "reference_run",
    "robustness_grid",
    "trajectory",
    "validate",
]
