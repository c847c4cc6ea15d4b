"""Structure and constraints of ``problem=lqr`` beyond the plain (Q, R) design.

* **Integral action** (``integral_outputs`` = C_I, q × n): the plant is augmented by
  integrator states z, ż = C_I x (discrete: z[k+1] = z[k] + dt C_I x[k]), so the gain
  K = [K_x, K_z] acts on x and on the integral of the chosen outputs (:func:`augment`).
  Initial states and weights given for the plant's n states get z(0) = 0 and zero
  weight on z (:func:`pad`, :func:`pad_weight`).
* **Semi-definite Q** (``q_output`` = C_q, p × n; ``q_fixed`` = Q₀, n × n PSD): the tuned
  matrix Q̃ (p × p, positive definite) enters the Riccati equation as
  Q = C_qᵀ Q̃ C_q + Q₀ (:func:`q_structure`); (A, Q^½) must be detectable, checked once by
  the PBH test since ker Q = ker C_q ∩ ker Q₀ for every Q̃.
* **Constraints** (:class:`Limits`): ``settling_time_max``, ``overshoot_max`` (of the
  outputs ``outputs`` from every start) and ``disk_margin_min`` (at the plant input; or
  ``gain_margin_min`` / ``phase_margin_min``, the disk-based margins it implies), with
  the measures of :mod:`~penaltyrun.problems.lqr.margins`. A start of a candidate that
  violates any has status ``constraint`` and the graded penalty of
  :mod:`~penaltyrun.problems.lqr.problem` on v = the summed relative excesses
  (settling: (T_s − max) / max; overshoot: (OS − max) / max(max, 1 %); margin:
  (min − α) / min).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from penaltyrun.dynamics.linear import sampled_loop
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import check_spd
from penaltyrun.problems.lqr import margins
from penaltyrun.problems.lqr import params as pm
from penaltyrun.problems.lqr.plant import Plant, check_detectable, check_stabilizable


def augment(plant: Plant, integral_outputs: Any) -> Plant:
    """The plant with integrator states of the outputs C_I x appended (unchanged when
    ``integral_outputs`` is None).

    Raises
    ------
    ConfigError
        A malformed C_I, or one whose integrators no gain can stabilize (a plant zero at
        s = 0 / z = 1 in those outputs, or dependent rows).
    """
    if integral_outputs is None:
        return plant
    key = f"{pm.PREFIX}.integral_outputs"
    n, m = plant.n_states, plant.n_inputs
    C = pm.matrix("integral_outputs", integral_outputs, n, "one row per integrated output")
    q = C.shape[0]
    dt = plant.dt
    A = np.zeros((n + q, n + q))
    A[:n, :n] = plant.A
    A[n:, :n] = C * (dt if dt else 1.0)
    if dt:
        A[n:, n:] = np.eye(q)
    B = np.vstack([plant.B, np.zeros((q, m))])
    try:
        check_stabilizable(A, B, key, dt)
    except ConfigError:
        raise ConfigError(key, "the integrators of these outputs cannot be stabilized: the "
                          "plant has a zero at s = 0 (z = 1) in them or the rows are "
                          "dependent; integrate fewer or other outputs") from None
    f_plant = plant.f

    def f_aug(X: np.ndarray, U: np.ndarray) -> np.ndarray:
        x = X[:, :n]
        z_dot = x @ C.T
        return np.hstack([np.asarray(f_plant(x, U), dtype=float),
                          X[:, n:] + dt * z_dot if dt else z_dot])

    return replace(plant, A=A, B=B, f=f_aug)


def pad(states: np.ndarray, n: int) -> np.ndarray:
    """States (k, n_plant) with zeros appended up to n columns."""
    return np.hstack([states, np.zeros((states.shape[0], n - states.shape[1]))])


def includes_integrators(states: Any, n: int) -> bool:
    """Whether given states (a list of states, or one flat state) have all n entries,
    integrator states included."""
    if states is None:
        return False
    first = states[0] if len(states) and isinstance(states[0], (tuple, list)) else states
    return len(first) == n


def pad_weight(value: Any, n_plant: int, n: int) -> np.ndarray:
    """``state_weight`` for the (augmented) n states: given for n states, or for the plant's
    n_plant states (zero weight on the integrators)."""
    size = n if value is not None and np.size(value) in (n, n * n) else n_plant
    W = pm.weight("state_weight", value, size, definite=False)
    out = np.zeros((n, n))
    out[:size, :size] = W
    return out


def q_structure(plant: Plant, q_output: Any, q_fixed: Any) -> tuple[np.ndarray, np.ndarray]:
    """C_q (p × n) and Q₀ (n × n) of Q = C_qᵀ Q̃ C_q + Q₀, checked for detectability.

    Raises
    ------
    ConfigError
        Malformed matrices, or (A, Q^½) not detectable (naming the mode and the fix).
    """
    n = plant.n_states
    C = np.eye(n) if q_output is None else \
        pm.matrix("q_output", q_output, n, "Q = C_q^T Q~ C_q, one row per weighted "
                  "output, one column per state including integrator states")
    Q0 = np.zeros((n, n)) if q_fixed is None else \
        pm.weight("q_fixed", q_fixed, n, definite=False)
    if q_output is not None or q_fixed is not None:
        lam, V = np.linalg.eigh(Q0)
        root = (V * np.sqrt(np.clip(lam, 0.0, None))).T
        key = f"{pm.PREFIX}.{'q_output' if q_output is not None else 'q_fixed'}"
        check_detectable(plant.A, np.vstack([C, root]), key, plant.dt)
    return C, Q0


def given_q(value: Any, size: int, plant: Plant, C: np.ndarray, Q0: np.ndarray
            ) -> np.ndarray:
    """A Q̃ given by the user (``mode=evaluate``, ``matrices.Q``): symmetric positive
    semi-definite — e.g. python-control's Q = CᵀC with zeros on the diagonal — as long as
    the Riccati equation's Q = C_qᵀ Q̃ C_q + Q₀ keeps (A, Q^½) detectable.

    Raises
    ------
    ConfigError
        Under ``matrices.Q``: malformed, not symmetric, indefinite or undetectable (naming
        the mode).
    """
    try:
        return check_spd("matrices.Q", value, size)
    except ConfigError as err:
        if "positive definite" not in err.message:
            raise
    arr = np.asarray(value, dtype=float)
    low = float(np.linalg.eigvalsh(arr)[0])
    if low < -1e-12 * max(1.0, float(np.abs(arr).max())):
        raise ConfigError("matrices.Q", f"matrix is not positive semi-definite (smallest "
                          f"eigenvalue {low:.3g})")
    lam, V = np.linalg.eigh(C.T @ arr @ C + Q0)
    root = (V * np.sqrt(np.clip(lam, 0.0, None))).T
    check_detectable(plant.A, root, "matrices.Q", plant.dt,
                     fix="weight one of these states in matrices.Q")
    return arr


@dataclass(frozen=True)
class Limits:
    """The constraints of one problem and how to measure them.

    Attributes
    ----------
    settling_time_max, overshoot_max, disk_margin_min : float or None
        Limits (time unit, percent, dimensionless); ``None``: not constrained.
        ``disk_margin_min`` is the largest α of ``disk_margin_min``, ``gain_margin_min``
        and ``phase_margin_min`` (:func:`~penaltyrun.problems.lqr.margins.alpha_for`).
    band : float
        Settling band (fraction of |y_i(0)|).
    outputs : ndarray, shape (p, n)
        C_y on the (augmented) state: the outputs of the settling and overshoot measures.
    omega : ndarray
        Frequencies of the disk margin.
    A, B : ndarray
        The (augmented) linear model; ``dt`` its sampling time or None.
    points : int
        Samples of a continuous-time response.
    responses : bool
        Whether time responses can be measured (discrete loops, or continuous ones in
        closed form).
    """

    settling_time_max: float | None
    overshoot_max: float | None
    disk_margin_min: float | None
    band: float
    outputs: np.ndarray
    omega: np.ndarray
    A: np.ndarray
    B: np.ndarray
    dt: float | None
    points: int
    responses: bool

    @classmethod
    def build(cls, p: pm.Params, plant: Plant, n_plant: int, closed_form: bool) -> Limits:
        """From the parameters; a response constraint on a loop that is neither discrete
        nor in closed form (input limits, nonlinear dynamics) is a ConfigError."""
        responses = plant.dt is not None or closed_form
        for key in ("settling_time_max", "overshoot_max"):
            if getattr(p, key) is not None and not responses:
                raise ConfigError(f"{pm.PREFIX}.{key}", "needs a linear loop without input "
                                  "limits in continuous time (or a discrete-time plant, dt); "
                                  "drop u_max / dynamics or this constraint")
        C = np.eye(n_plant) if p.outputs is None else \
            pm.matrix("outputs", p.outputs, n_plant, "one row per constrained output")
        C = np.hstack([C, np.zeros((C.shape[0], plant.n_states - n_plant))])
        alpha = max(p.disk_margin_min or 0.0,
                    margins.alpha_for(p.gain_margin_min, p.phase_margin_min))
        return cls(p.settling_time_max, p.overshoot_max, alpha if alpha > 0 else None,
                   float(p.settling_band), C,
                   margins.frequency_grid(plant.A, plant.dt, int(p.margin_points)),
                   plant.A, plant.B, plant.dt, int(p.response_points), responses)

    def _wants_response(self, metrics: bool) -> bool:
        limited = self.settling_time_max is not None or self.overshoot_max is not None
        return self.responses and (limited or metrics)

    def needs_history(self, metrics: bool) -> bool:
        """Whether a discrete simulation must keep its states."""
        return self.dt is not None and self._wants_response(metrics)

    def measure(self, K: np.ndarray, ok: np.ndarray, X0: np.ndarray, t_max: float,
                steps: Mapping[str, np.ndarray] | None, metrics: bool = False
                ) -> dict[str, np.ndarray]:
        """Measures and the summed relative violation of C candidates from k starts.

        Parameters
        ----------
        K : ndarray, shape (C, m, n)
        ok : ndarray of bool, shape (C,)
            Stabilizing gains (the others get NaN measures and no violation).
        X0 : ndarray, shape (k, n)
        t_max : float
        steps : dict or None
            The discrete simulation of the ``ok`` candidates (with ``x``), if any.
        metrics : bool
            Compute every measure, constrained or not.

        Returns
        -------
        dict
            ``disk_margin`` (C,), ``settling_time`` (C, k), ``overshoot`` (C, k) and
            ``violation`` (C, k), ≥ 0, ``inf`` for a response that never settles.
        """
        n_c, n_k = K.shape[0], X0.shape[0]
        good = np.flatnonzero(ok)
        alpha = np.full(n_c, np.nan)
        settle = np.full((n_c, n_k), np.nan)
        over = np.full((n_c, n_k), np.nan)
        excess = np.zeros((n_c, n_k))
        if good.size and (self.disk_margin_min is not None or metrics):
            alpha[good] = margins.disk_margin(self.A, self.B, K[good], self.omega, self.dt)
        if good.size and self._wants_response(metrics):
            if self.dt is not None and steps is not None:
                t = np.arange(steps["x"].shape[0]) * self.dt
                x = np.swapaxes(steps["x"], 0, 1).reshape(good.size, n_k, t.size, -1)
            else:
                t = np.linspace(0.0, t_max, self.points)
                x, _ = sampled_loop(self.A - self.B @ K[good], X0, t)
            settle[good], over[good] = margins.settling_overshoot(t, x @ self.outputs.T,
                                                                  self.band)
        with np.errstate(invalid="ignore"):
            if self.disk_margin_min is not None:
                lack = (self.disk_margin_min - alpha) / self.disk_margin_min
                excess += np.where(ok, np.maximum(lack, 0.0), 0.0)[:, None]
            if self.settling_time_max is not None:
                late = (settle - self.settling_time_max) / self.settling_time_max
                excess += np.where(ok[:, None], np.maximum(late, 0.0), 0.0)
            if self.overshoot_max is not None:
                high = (over - self.overshoot_max) / max(self.overshoot_max, 1.0)
                excess += np.where(ok[:, None], np.maximum(high, 0.0), 0.0)
        return {"disk_margin": alpha, "settling_time": settle, "overshoot": over,
                "violation": excess}

    def report(self, res: Mapping[str, np.ndarray]) -> dict[str, Any]:
        """The measures of candidate 0 of :meth:`measure`'s output, JSON-serializable:
        ``disk_margin`` (α, gain margin in dB — null when unbounded — and phase margin in
        degrees), per start
        ``settling_time`` and ``overshoot`` (null where not measurable), and ``limits``."""
        alpha = float(res["disk_margin"][0])
        gain, phase = margins.disk_gain_phase(alpha) if np.isfinite(alpha) else (None, None)
        gain = gain if gain is None or np.isfinite(gain) else None  # α ≥ 2: unbounded

        def listed(values: np.ndarray) -> list[float | None]:
            return [None if np.isnan(v) else float(v) for v in values]

        return {"disk_margin": {"alpha": None if np.isnan(alpha) else alpha,
                                "gain_margin_db": gain, "phase_margin_deg": phase},
                "settling_time": listed(res["settling_time"][0]),
                "overshoot_percent": listed(res["overshoot"][0]),
                "limits": {"settling_time_max": self.settling_time_max,
                           "overshoot_max": self.overshoot_max,
                           "disk_margin_min": self.disk_margin_min,
                           "settling_band": self.band}}


__all__ = ["Limits", "augment", "given_q", "includes_integrators", "pad", "pad_weight",
           "q_structure"]
