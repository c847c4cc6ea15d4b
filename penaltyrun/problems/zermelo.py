"""Problem 1: the Zermelo navigation variation (2 states, minimum control energy).

Ẋ = U + d(X), d(X) = (−x cos y sin x, −y cos y sin x), U = −d(X) − KᵀX, so the closed loop
is Ẋ = −KᵀX and V = ½XᵀX decreases for every PD K. Cost J = ∫½UᵀU dt up to the first time
‖X‖ = ``event_radius``; a run whose event does not fire before ``t_max`` fails and gets
the graded penalty ``J(t_max) + failure_penalty · (1 + ‖X(t_max)‖ / ‖X0‖)``, at most
:data:`GRADED_CEILING` (which a run whose state blows up also costs), so the penalty never
decreases as the failure grows.

Exact cutoff (``evaluate_batch(..., thresholds=...)``, status ``cutoff``): a run stops at the
end of the first integration step where J exceeds its threshold by the relative margin
:data:`CUT_MARGIN` and costs that J, a bound above the threshold (J̇ = ½UᵀU ≥ 0, so J at the
event, or J plus the failure penalty, is never below it up to the integrator's round-off).
Thresholds at or above ``10 · failure_penalty`` (the flat cost of a NaN cost) cut nothing.

Evaluation: in closed form (:mod:`penaltyrun.dynamics.zermelo_closed`: X(t) = e^{−Kt}X0 from
the eigen-decomposition of K, the event time a scalar root, J a Gauss–Kronrod quadrature)
for every symmetric positive-definite K — every decoded candidate; the compiled DOP853
integrator (:mod:`penaltyrun.dynamics.zermelo`, tolerances ``rtol``/``atol``, ``max_step``,
``max_steps``) for the gains it does not cover (K not symmetric beyond round-off, not
positive definite, a start inside the event radius). Both give the same statuses; their
costs agree to the integrator's accuracy (about 1e-10 relative; where they differ more, the
closed form is the one that agrees with a tighter ``solve_ivp``). With thresholds the closed
form computes J exactly and reports status ``cutoff`` with that J when it exceeds the
threshold by :data:`CUT_MARGIN`, as the integrator would have stopped.

Gradient (``gradient`` hook): d J / d K of a converged gain from the closed form, by
:mod:`penaltyrun.problems.zermelo_gradient`; none (with the reason) where the cost is not
differentiable.

Training scenario: the start ``x0``. Held-out set: starts on circles around the origin
(``holdout_radii`` × ``holdout_n_angles`` equally spaced angles), any start equal to ``x0``
left out.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any, ClassVar

import numpy as np

from penaltyrun.dynamics import integrate
from penaltyrun.dynamics.zermelo import drift, simulate_batch
from penaltyrun.dynamics.zermelo_closed import QUAD_RTOL, closed_batch
from penaltyrun.errors import ConfigError
from penaltyrun.problems import gradient_costs, horizon
from penaltyrun.problems.base import (
    BatchEvaluation,
    ClosedLoop,
    CostGradient,
    GradientCost,
    MatrixSpec,
    PaperValues,
    ParamsMixin,
    ReportInfo,
    ScalarSpec,
    check_spd,
)
from penaltyrun.problems.basins import BasinAxes, arrival_times
from penaltyrun.problems.multiscenario import TrainingParams

logger = logging.getLogger(__name__)

CASES = ("default",)
DEFAULT_CASE = "default"
CASE_PARAMS: dict[str, dict[str, Any]] = {"default": {}}
#: Parameters that do not change a run's result (reports do not split cells by them).
VARIANT_IGNORE = ("holdout_radii", "holdout_n_angles", "holdout_angle_offset_deg",
                  "holdout_horizon_factor", "holdout_t_max_cap")

#: Relative margin by which J must exceed a threshold before a run is cut.
CUT_MARGIN = 1e-9
#: Cost multiple of ``failure_penalty`` for runs whose graded cost is not finite.
HARD_FAILURE_FACTOR = 10.0
#: Largest graded penalty: failures whose penalty would exceed it (or overflow) cost this.
GRADED_CEILING = 1e300

#: The paper's best matrices (diagonal K1, full K2).
PAPER_K_DIAGONAL = np.diag([0.8094, 0.1611])
PAPER_K_FULL = np.array([[1.7421, 0.9560], [0.9560, 1.1414]])


@dataclass(frozen=True)
class Params(ParamsMixin, TrainingParams):
    """Zermelo problem parameters (nondimensional units).

    Attributes
    ----------
    x0 : tuple of float
        Initial position (x, y).
    event_radius : float
        Terminal event ‖X‖ = event_radius.
    t_max : float
        Horizon cap; the event must fire before it.
    rtol, atol : float
        Integration tolerances (paper: 1e-10) of the integrator, which evaluates the gains
        the closed form does not cover (K not symmetric) and computes the plotted paths.
    max_step : float
        Largest integration step (``inf``: unbounded); integrator only.
    max_steps : int
        Step cap per run (a run hitting it fails); integrator only.
    eig_bounds : tuple of float
        Eigenvalue / diagonal-entry bounds of K.
    failure_penalty : float
        Penalty scale for runs whose event does not fire.
    holdout_radii : tuple of float
        Radii of the held-out circles of starts (empty: no held-out set).
    holdout_n_angles : int
        Starts per circle, at angles offset + 360°·k / n.
    holdout_angle_offset_deg : float
        Angle of the first start on each circle (degrees from the +x axis).
    holdout_horizon_factor, holdout_t_max_cap : float
        Held-out horizon T = min(factor · t_max, cap), never below ``t_max``: the held-out
        starts are judged at T (a gain still not converged there gets the graded penalty
        at T) and at ``t_max`` (see :mod:`penaltyrun.problems.horizon`). Defaults 10 and
        10 000: the closed loop Ẋ = −KᵀX from ‖X0‖ = 10 to the event radius takes
        ln(10⁴)/λ_min(K_sym), under 1 000 for every λ_min above 0.01.
    train_scenarios, train_aggregate
        Multi-scenario tuning (see :mod:`penaltyrun.problems.multiscenario`).
    """

    HOLDOUT_OFF: ClassVar[Mapping[str, Any]] = MappingProxyType({"holdout_radii": ()})
    x0: tuple[float, float] = (-8.0, 6.0)
    event_radius: float = 1e-3
    t_max: float = 1000.0
    rtol: float = 1e-10
    atol: float = 1e-10
    max_step: float = float("inf")
    max_steps: int = 1_000_000
    eig_bounds: tuple[float, float] = (1e-8, 10.0)
    failure_penalty: float = 1e3
    holdout_radii: tuple[float, ...] = (2.0, 5.0, 10.0)
    holdout_n_angles: int = 8
    holdout_angle_offset_deg: float = 0.0
    holdout_horizon_factor: float = 10.0
    holdout_t_max_cap: float = 10_000.0


class Zermelo:
    """Zermelo closed-loop problem with one 2×2 penalty matrix ``K``."""

    name = "zermelo"

    def __init__(self, case: str, params: Params) -> None:
        self.case = case
        self.params = params
        self.matrices = (MatrixSpec("K", 2, tuple(float(b) for b in params.eig_bounds)),)
        self.scalars: tuple[ScalarSpec, ...] = ()

    def _run(self, K: np.ndarray, x0: Any = None, cutoff: np.ndarray | None = None
             ) -> tuple[np.ndarray, ...]:
        """Runs of gains ``K`` (B, 2, 2) from ``x0`` ((2,) or (B, 2); default the training
        start): the closed form where it applies, the integrator for the rest.

        Returns ``t_end``, ``cost`` (J), ``dist`` (‖X‖ at ``t_end``), ``status`` (codes of
        :mod:`penaltyrun.dynamics.integrate`), each of shape (B,).
        """
        p = self.params
        K = np.ascontiguousarray(K, dtype=float)
        B = K.shape[0]
        X0 = np.ascontiguousarray(np.broadcast_to(
            np.asarray(p.x0 if x0 is None else x0, dtype=float), (B, 2)))
        cut = np.full(B, np.inf) if cutoff is None else np.asarray(cutoff, dtype=float)
        t_end, cost, dist, status, covered = closed_batch(
            K, X0, float(p.t_max), float(p.event_radius), cut, QUAD_RTOL)
        for i in np.flatnonzero(~covered):
            res = simulate_batch(K[i:i + 1], X0[i], float(p.t_max), float(p.event_radius),
                                 float(p.rtol), float(p.atol), float(p.max_step),
                                 int(p.max_steps), None if cutoff is None else cut[i:i + 1])
            for out, value in zip((t_end, cost, dist, status), res):
                out[i] = value[0]
        return t_end, cost, dist, status

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None,
        thresholds: np.ndarray | None = None,
    ) -> BatchEvaluation:
        """Costs of a batch of gains ``mats["K"]``, shape (B, 2, 2).

        ``thresholds`` (shape (B,), optional): exact cutoff per candidate (``inf``: none);
        see the module docstring.
        """
        K = mats["K"]
        cutoff = None
        if thresholds is not None:
            thr = np.asarray(thresholds, dtype=float).reshape(np.shape(K)[0])
            allowed = thr < HARD_FAILURE_FACTOR * self.params.failure_penalty  # NaN: False
            cutoff = np.where(allowed, thr + CUT_MARGIN * np.abs(thr), np.inf)
        return self._graded(*self._run(K, None, cutoff), float(np.hypot(*self.params.x0)))

    def _graded(self, t_end: np.ndarray, cost: np.ndarray, dist: np.ndarray,
                status: np.ndarray, d0: float | np.ndarray) -> BatchEvaluation:
        """Graded costs; ``d0``: the start's distance ‖x0‖ (one, or one per run)."""
        converged = status == integrate.EVENT
        with np.errstate(over="ignore", invalid="ignore"):
            penalty = cost + self.params.failure_penalty * (1.0 + dist / d0)
        # monotone in the failure's size: a failure too large for a float, or a run whose
        # state blew up, costs the ceiling, never less than a smaller failure
        penalty = np.where(np.isposinf(penalty) | (status == integrate.NONFINITE),
                           GRADED_CEILING, np.minimum(penalty, GRADED_CEILING))
        graded = np.where(converged | (status == integrate.CUTOFF), cost, penalty)
        graded = np.where(np.isfinite(graded), graded,
                          HARD_FAILURE_FACTOR * self.params.failure_penalty)
        names = np.asarray(["converged" if c else integrate.STATUS_NAMES[int(s)]
                            for c, s in zip(converged, status)], dtype=object)
        return BatchEvaluation(cost=graded, converged=converged, status=names)

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Detailed evaluation of one gain; JSON-serializable."""
        K = check_spd("matrices.K", mats["K"], 2)
        t_end, cost, dist, status = self._run(K[None])
        batch = self.evaluate_batch({"K": K[None]})
        return {
            "problem": self.name,
            "case": self.case,
            "cost": float(batch.cost[0]),
            "energy": float(cost[0]),
            "converged": bool(batch.converged[0]),
            "status": str(batch.status[0]),
            "t_final": float(t_end[0]),
            "final_distance": float(dist[0]),
        }

    def gradient(self, mats: Mapping[str, np.ndarray],
                 scalars: Mapping[str, float] | None = None) -> CostGradient:
        """Cost of one gain and its exact gradient d J / d K from the closed form
        (:mod:`~penaltyrun.problems.zermelo_gradient`), or the reason there is none."""
        from penaltyrun.problems.zermelo_gradient import zermelo_gradient

        return zermelo_gradient(self, check_spd("matrices.K", mats["K"], 2))

    def gradient_cost(self) -> GradientCost:
        """What one gradient costs in evaluations: measured by
        ``bench/gradient_cost_zermelo_mpc.py``, table in ``bench/README.md``
        (:func:`~penaltyrun.problems.gradient_costs.zermelo_cost`)."""
        return gradient_costs.zermelo_cost()

    def training_scenario(self) -> dict[str, Any]:
        """The scenario K is tuned on: the start ``x0``."""
        return {"scenario": "x0", "x0": [float(v) for v in self.params.x0]}

    def scenario_key(self) -> tuple:
        """Hashable key of the training scenario (the start, rounded to 1e-9)."""
        return tuple(np.round(np.asarray(self.params.x0, float), 9).tolist())

    def sample_training(self, n: int, seed: int) -> list[dict[str, Any]]:
        """``n`` seeded training starts: angle uniform, radius uniform in [1, 10].

        Returns
        -------
        list of dict
            Overrides ``{"x0": (x, y)}``.
        """
        rng = np.random.default_rng(int(seed))
        r = rng.uniform(1.0, 10.0, n)
        a = rng.uniform(0.0, 2.0 * np.pi, n)
        return [{"x0": (float(ri * np.cos(ai)), float(ri * np.sin(ai)))} for ri, ai in zip(r, a)]

    def holdout_keys(self) -> set[tuple]:
        """Keys (as :meth:`scenario_key`) of the held-out scenarios."""
        return {tuple(np.round(x, 9).tolist()) for x in self.holdout_scenarios()["x0"]}

    def holdout_scenarios(self) -> dict[str, np.ndarray]:
        """Held-out starts on circles around the origin (the training start left out).

        Returns
        -------
        dict
            ``scenario`` (n,) labels ``r=<radius>,deg=<angle>``, ``x0`` (n, 2) starts.
        """
        p = self.params
        ang = np.radians(p.holdout_angle_offset_deg) + \
            2.0 * np.pi * np.arange(p.holdout_n_angles) / max(p.holdout_n_angles, 1)
        starts, labels = [], []
        for r in p.holdout_radii:
            for a in ang:
                x = np.array([r * np.cos(a), r * np.sin(a)])
                if np.allclose(x, p.x0, rtol=0.0, atol=1e-9):
                    continue
                starts.append(x)
                labels.append(f"r={r:g},deg={np.degrees(a):g}")
        return {"scenario": np.asarray(labels, dtype=object),
                "x0": np.asarray(starts, dtype=float).reshape(-1, 2)}

    def holdout(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                ) -> dict[str, np.ndarray] | None:
        """Evaluate one K on the held-out starts (runner hook) at the training deadline
        ``t_max`` and at the held-out horizon (see :mod:`penaltyrun.problems.horizon`).

        Returns
        -------
        dict of ndarray or None
            Per scenario, at the held-out horizon: ``scenario``, ``x0`` (n, 2), ``cost``
            (graded), ``energy``, ``converged``, ``status``, ``t_final``,
            ``arrival_time``, ``final_distance``; at the training deadline the fields of
            :data:`~penaltyrun.problems.horizon.DEADLINE_FIELDS`; ``horizon`` and
            ``training_horizon``. ``None`` when the held-out set is empty.
        """
        sc = self.holdout_scenarios()
        if not len(sc["scenario"]):
            return None
        p = self.params
        long_t = horizon.holdout_horizon(p.t_max, p.holdout_horizon_factor,
                                         p.holdout_t_max_cap)
        short = self._holdout_runs(mats, sc)
        long = horizon.at_horizon(self, long_t)._holdout_runs(mats, sc) \
            if long_t > p.t_max else short
        res = horizon.combine(short, long, p.t_max, long_t)
        res.update(sc)
        return res

    def _holdout_runs(self, mats: Mapping[str, Any], sc: Mapping[str, np.ndarray]
                      ) -> dict[str, np.ndarray]:
        """Per-scenario results of one K at this problem's ``t_max``."""
        K = check_spd("matrices.K", mats["K"], 2)
        x0 = np.asarray(sc["x0"], dtype=float)
        t_end, energy, dist, status = self._run(np.repeat(K[None], len(x0), axis=0), x0)
        be = self._graded(t_end, energy, dist, status, np.hypot(x0[:, 0], x0[:, 1]))
        return {"cost": be.cost, "energy": energy, "converged": be.converged,
                "status": be.status, "t_final": t_end, "final_distance": dist}

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None,
        n_points: int = 400,
    ) -> dict[str, np.ndarray]:
        """Closed-loop path of one gain, sampled with scipy's dense output for plots.

        Returns ``t``, ``x``, ``y``, ``u1``, ``u2`` (arrays of length ``n_points``) and
        ``limits`` (none: the control is unbounded).
        """
        from scipy.integrate import solve_ivp

        K = check_spd("matrices.K", mats["K"], 2)
        t_end = float(self._run(K[None])[0][0])
        p = self.params

        def rhs(t: float, X: np.ndarray) -> np.ndarray:
            return -K.T @ X

        t = np.linspace(0.0, t_end, n_points)
        sol = solve_ivp(rhs, (0.0, t_end), np.asarray(p.x0, float), t_eval=t,
                        rtol=p.rtol, atol=p.atol, method="DOP853")
        x, y = sol.y
        dx, dy = drift(x, y)
        u1 = -dx - (K[0, 0] * x + K[1, 0] * y)
        u2 = -dy - (K[0, 1] * x + K[1, 1] * y)
        return {"t": sol.t, "x": x, "y": y, "u1": u1, "u2": u2, "limits": {}}

    def closed_loop(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None = None
                    ) -> ClosedLoop:
        """The closed loop Ẋ = −Kᵀ X (exact: the law cancels the current). The current's
        Jacobian at the origin is zero, so the linearized law is U = −Kᵀ X: gain Kᵀ."""
        K = check_spd("matrices.K", mats["K"], 2)
        return ClosedLoop(-K.T, "continuous", gain=K.T.copy(), state_names=("x", "y"),
                          input_names=("u1", "u2"))

    def basin_axes(self) -> BasinAxes:
        """Start positions (x, y) in a square around the target that holds the training
        start and every held-out circle (1.2 times the largest radius)."""
        p = self.params
        radius = 1.2 * max([float(np.hypot(*p.x0)), *(float(r) for r in p.holdout_radii)])
        return BasinAxes(("x", "y"), (-radius, -radius), (radius, radius), "",
                         (float(p.x0[0]), float(p.x0[1])))

    def basin_runs(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                   points: np.ndarray) -> dict[str, Any]:
        """One K from the start positions ``points`` (P, 2) at the held-out horizon."""
        p = self.params
        long_t = horizon.holdout_horizon(p.t_max, p.holdout_horizon_factor,
                                         p.holdout_t_max_cap)
        runs = horizon.at_horizon(self, long_t)._holdout_runs(mats, {"x0": points})
        return {"converged": runs["converged"], "cost": runs["cost"], "horizon": long_t,
                "arrival_time": arrival_times(runs["converged"], runs["t_final"])}


def make_problem(case: str, overrides: Mapping[str, Any]) -> Zermelo:
    """Build the Zermelo problem: defaults → case entry → ``overrides``."""
    merged = {**CASE_PARAMS[case], **dict(overrides)}
    params = Params.from_mapping(merged)
    for key in ("t_max", "event_radius", "rtol", "atol", "max_step", "max_steps",
                "failure_penalty"):
        value = getattr(params, key)
        if not (value > 0 and (np.isfinite(value) or key == "max_step")):
            raise ConfigError(f"problem.params.{key}", f"must be a positive number, got "
                                                      f"{value!r}")
    if not all(np.isfinite(v) for v in params.x0):
        raise ConfigError("problem.params.x0", f"must be finite numbers, got {params.x0!r}")
    if any(not (np.isfinite(r) and r > 0) for r in params.holdout_radii):
        raise ConfigError("problem.params.holdout_radii", "radii must be positive numbers")
    if not (isinstance(params.holdout_n_angles, int) and params.holdout_n_angles >= 1):
        raise ConfigError("problem.params.holdout_n_angles", "must be a positive integer")
    horizon.check_settings(params, "problem.params")
    return Zermelo(case, params)


def reference_cost(K: np.ndarray, params: Params | None = None) -> tuple[float, float, bool]:
    """Independent scipy ``solve_ivp`` (DOP853) evaluation of one gain.

    Returns
    -------
    cost : float
        J at the event (or at ``t_max`` if it did not fire).
    t_final : float
        Event time or ``t_max``.
    converged : bool
        Whether the event fired.
    """
    from scipy.integrate import solve_ivp

    p = params or Params()
    K = np.asarray(K, float)

    def rhs(t: float, s: np.ndarray) -> list[float]:
        x, y = s[0], s[1]
        d = np.array([-x * np.cos(y) * np.sin(x), -y * np.cos(y) * np.sin(x)])
        u = -d - K.T @ s[:2]
        xdot = u + d
        return [xdot[0], xdot[1], 0.5 * float(u @ u)]

    def hit(t: float, s: np.ndarray) -> float:
        return float(np.hypot(s[0], s[1]) - p.event_radius)

    hit.terminal = True
    sol = solve_ivp(rhs, (0.0, p.t_max), [p.x0[0], p.x0[1], 0.0], events=hit,
                    rtol=p.rtol, atol=p.atol, method="DOP853")
    if sol.t_events[0].size:
        return float(sol.y_events[0][0][2]), float(sol.t_events[0][0]), True
    return float(sol.y[2, -1]), float(sol.t[-1]), False


def plot_phase_plane(paths: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None,
                     extent: float = 10.0) -> Any:
    """Phase-plane plot of closed-loop paths over the current field.

    Parameters
    ----------
    paths : mapping label → dict from :meth:`Zermelo.simulate`
    ax : matplotlib Axes, optional
    extent : float
        Half-width of the plotted square [−extent, extent]².
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    g = np.linspace(-extent, extent, 25)
    X, Y = np.meshgrid(g, g)
    dx, dy = drift(X.ravel(), Y.ravel())
    ax.quiver(X, Y, dx.reshape(X.shape), dy.reshape(X.shape), color="0.7", angles="xy",
              label="current d(X)")
    for k, (label, path) in enumerate(paths.items()):
        style = "--" if label.startswith("paper") else "-"
        color = "C0" if "diagonal" in label else "C1" if "full" in label else f"C{k + 2}"
        ax.plot(path["x"], path["y"], style, lw=2, color=color, label=label)
    x0 = next(iter(paths.values())) if paths else None
    if x0 is not None:
        ax.plot(x0["x"][0], x0["y"][0], "ko", label="start")
    ax.plot(0.0, 0.0, "k*", ms=12, label="target")
    ax.set_xlim(-extent, extent)
    ax.set_ylim(-extent, extent)
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_aspect("equal")
    ax.legend(loc="upper right", fontsize=9)
    return ax


def report_info(case: str, params: Mapping[str, Any]) -> ReportInfo:
    """Report hook (:mod:`penaltyrun.problems.report_hooks`): cost, held-out set, paper K."""
    p = Params.from_mapping({**CASE_PARAMS.get(case, {}), **dict(params)})
    radii = ", ".join(f"{r:g}" for r in p.holdout_radii)
    holdout = (f"{len(p.holdout_radii) * p.holdout_n_angles} starts on circles of radius "
               f"{radii} around the origin, {p.holdout_n_angles} per circle at "
               f"{p.holdout_angle_offset_deg:g}° + k·{360 / max(p.holdout_n_angles, 1):g}° "
               f"(the training start x0 = ({p.x0[0]:g}, {p.x0[1]:g}) left out)"
               if p.holdout_radii else "")
    return ReportInfo(
        cost_name="J = ∫½‖u‖² dt", cost_unit="1", holdout_description=holdout,
        paper=PaperValues(source="paper (single run per map)",
                          matrices={"diagonal": {"K": PAPER_K_DIAGONAL},
                                    "full": {"K": PAPER_K_FULL}}))


def report_plots(sims: Mapping[str, Mapping[str, np.ndarray]], case: str,
                 params: Mapping[str, Any]) -> dict[str, Any]:
    """Report hook: the phase plane with every simulated path over the current."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 7))
    plot_phase_plane(sims, ax=ax)
    ax.set_title("Zermelo: closed-loop paths over the current d(X)")
    return {"phase plane": fig}
