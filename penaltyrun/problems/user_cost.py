"""A problem from a user's cost function (:func:`from_cost`).

The cost is any Python callable of the penalty matrices (and scalars). It becomes an object
that follows the problem protocol of :mod:`penaltyrun.problems.base`, so the optimizers,
the runner, the records and the report treat it exactly as a built-in problem. A cost that
raises, or returns a value that is not a finite number, gives that candidate the status
``"error"`` or ``"nonfinite"`` and the finite cost :data:`FAILURE_COST`, so the search goes
on; the job's record keeps the status of its best candidate (and the error text).

Such a problem lives in the memory of one process: the runner passes it to its workers as
an in-process object (:func:`penaltyrun.problems.hold`), not by name.
"""

from __future__ import annotations

import logging
import math
import types
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError, raise_wrapped_exit
from penaltyrun.problems.base import (
    BatchEvaluation,
    CostGradient,
    GradientCost,
    MatrixSpec,
    ScalarSpec,
)
from penaltyrun.typed import is_int

logger = logging.getLogger(__name__)

#: Cost given to a candidate whose cost raised or was not finite (finite, so that every
#: optimizer ranks it last but keeps going).
FAILURE_COST = 1e12
#: Per-candidate statuses of a cost-function problem.
STATUSES = ("converged", "error", "nonfinite")
#: The single case of a cost-function problem.
CASE = "default"


def _bounds(label: str, value: Any) -> tuple[float, float]:
    try:
        low, high = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(label, f"expected (low, high), got {value!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise ConfigError(label, f"expected finite low < high, got ({low}, {high})")
    return low, high


class CostProblem:
    """A problem whose cost is a user's function of the penalty matrices.

    Parameters
    ----------
    cost : callable
        ``cost(**mats, **scalars)``: one array per matrix name, shape (n, n) (or (B, n, n)
        with ``batched``), and one float (or array of shape (B,)) per scalar; returns a
        float (or B floats).
    matrices : tuple of MatrixSpec
    scalars : tuple of ScalarSpec
    batched : bool
        Whether ``cost`` takes a whole batch of candidates at once.
    name : str
        Problem name in records and reports.
    """

    case = CASE

    def __init__(self, cost: Callable[..., Any], matrices: tuple[MatrixSpec, ...],
                 scalars: tuple[ScalarSpec, ...], batched: bool, name: str) -> None:
        self.cost = cost
        self.matrices = matrices
        self.scalars = scalars
        self.batched = bool(batched)
        self.name = name
        self._warned = False

    def __repr__(self) -> str:
        mats = ", ".join(f"{m.name}: {m.size}x{m.size}" for m in self.matrices)
        return f"<cost problem {self.name!r} ({mats}{', batched' if self.batched else ''})>"

    def _one(self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float]
             ) -> tuple[float, str, str]:
        """(cost, status, error text) of one candidate."""
        try:
            value = float(np.asarray(self.cost(**mats, **scalars), dtype=float).reshape(()))
        except Exception as exc:  # a failing cost is a status, never a crash
            raise_wrapped_exit(exc)
            error = f"{type(exc).__name__}: {exc}"
            if not self._warned:  # once: a cost that always raises must not pass unseen
                self._warned = True
                logger.warning("the cost of problem %r raised %s; such candidates get "
                               "status 'error' and cost %g (said once per problem)",
                               self.name, " ".join(error.split())[:300], FAILURE_COST)
            return FAILURE_COST, "error", error
        if not math.isfinite(value):
            return FAILURE_COST, "nonfinite", f"the cost returned {value}"
        return value, "converged", ""

    def _rows(self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray],
              n: int) -> list[tuple[float, str, str]]:
        """(cost, status, error) of each of ``n`` candidates, one call per candidate (a
        batched cost gets batches of one)."""
        out = []
        for i in range(n):
            sl = slice(i, i + 1) if self.batched else i
            one_m = {k: np.asarray(v)[sl] for k, v in mats.items()}
            one_s = {k: np.asarray(v, float)[sl] if self.batched else float(np.asarray(v)[i])
                     for k, v in scalars.items()}
            out.append(self._one(one_m, one_s))
        return out

    def _batch(self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray],
               n: int) -> list[tuple[float, str, str]]:
        """Whole-batch call of a batched cost; a raising call or a wrong shape falls back to
        one call per candidate, so the failures are found candidate by candidate."""
        try:
            values = np.asarray(self.cost(**mats, **scalars), dtype=float)
        except Exception as exc:
            raise_wrapped_exit(exc)
            return self._rows(mats, scalars, n)
        if values.shape != (n,):
            return self._rows(mats, scalars, n)
        return [(float(v), "converged", "") if math.isfinite(v) else
                (FAILURE_COST, "nonfinite", f"the cost returned {v}") for v in values]

    def evaluate_batch(self, mats: Mapping[str, np.ndarray],
                       scalars: Mapping[str, np.ndarray] | None = None) -> BatchEvaluation:
        """Costs of B candidates; ``mats[name]`` has shape (B, n, n).

        Returns
        -------
        BatchEvaluation
            ``cost`` (B,) finite (:data:`FAILURE_COST` for a failed candidate),
            ``converged`` (B,) and ``status`` (B,) from :data:`STATUSES`.
        """
        mats = {k: np.asarray(v, float) for k, v in mats.items()}
        scalars = {k: np.asarray(v, float) for k, v in (scalars or {}).items()}
        n = len(next(iter(mats.values())))
        rows = self._batch(mats, scalars, n) if self.batched else self._rows(mats, scalars, n)
        cost = np.array([r[0] for r in rows], dtype=float)
        status = np.array([r[1] for r in rows], dtype=object)
        return BatchEvaluation(cost=cost, converged=status == "converged", status=status)

    def evaluate(self, mats: Mapping[str, np.ndarray],
                 scalars: Mapping[str, float] | None = None) -> dict[str, Any]:
        """One candidate: ``cost``, ``converged``, ``status``, ``error`` (the exception text
        of a raising cost, else ``""``) and ``t_final`` (NaN: a cost has no horizon)."""
        batch = {k: np.asarray(v, float)[None] for k, v in mats.items()}
        sc = {k: np.asarray([float(v)]) for k, v in (scalars or {}).items()}
        cost, status, error = self._rows(batch, sc, 1)[0]
        return {"cost": cost, "converged": status == "converged", "status": status,
                "error": error, "t_final": float("nan")}

    def simulate(self, mats: Mapping[str, np.ndarray],
                 scalars: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """No time histories: a cost function has no trajectory to plot (empty dict)."""
        return {}


class GradientCostProblem(CostProblem):
    """A :class:`CostProblem` with the user's exact gradient (the ``gradient`` hook).

    Parameters
    ----------
    cost, matrices, scalars, batched, name
        As :class:`CostProblem`.
    grad : callable
        ``grad(**mats, **scalars)`` of one candidate (never batched): {matrix name: d cost /
        d entry, shape (n, n)} plus {scalar name: d cost / d scalar}.
    price : GradientCost or None
        What one call of ``grad`` costs in evaluations of ``cost`` (the ``gradient_cost``
        hook); None: not measured.
    """

    def __init__(self, cost: Callable[..., Any], matrices: tuple[MatrixSpec, ...],
                 scalars: tuple[ScalarSpec, ...], batched: bool, name: str,
                 grad: Callable[..., Any], price: GradientCost | None = None) -> None:
        super().__init__(cost, matrices, scalars, batched, name)
        self.grad = grad
        self.price = price

    def gradient_cost(self) -> GradientCost | None:
        """What one gradient costs in evaluations, as given to :func:`from_cost` (None: not
        given)."""
        return self.price

    def gradient(self, mats: Mapping[str, np.ndarray],
                 scalars: Mapping[str, float] | None = None) -> CostGradient:
        """The candidate's cost and the user's gradient; a failed candidate, or a gradient
        that raises or is malformed, gives the reason instead."""
        ev = self.evaluate(mats, scalars)
        cost, status = float(ev["cost"]), str(ev["status"])
        if status != "converged":
            return CostGradient(cost, status, None, {}, f"status {status}: no gradient")
        one = {k: np.asarray(v, float) for k, v in mats.items()}
        sc = {k: float(v) for k, v in (scalars or {}).items()}
        try:
            out = self.grad(**one, **sc)
            by_matrix = {}
            for spec in self.matrices:
                G = np.asarray(out[spec.name], dtype=float)
                if G.shape != (spec.size, spec.size) or not np.all(np.isfinite(G)):
                    return CostGradient(cost, status, None, {}, f"the gradient of "
                                        f"{spec.name} is not a finite {spec.size}x{spec.size} "
                                        "array")
                by_matrix[spec.name] = 0.5 * (G + G.T)
            by_scalar = {spec.name: float(out[spec.name]) for spec in self.scalars}
        except Exception as exc:  # a failing gradient is a reason, never a crash
            raise_wrapped_exit(exc)
            return CostGradient(cost, status, None, {},
                                f"the gradient raised {type(exc).__name__}: {exc}")
        return CostGradient(cost, status, by_matrix, by_scalar, "")


def from_cost(cost: Callable[..., Any],
              matrices: Mapping[str, tuple[int, tuple[float, float]]], *,
              scalars: Mapping[str, tuple[float, float]] | None = None,
              batched: bool = False, name: str = "user",
              gradient: Callable[..., Any] | None = None,
              gradient_cost: float | None = None) -> CostProblem:
    """A problem that tunes the matrices of your own cost function.

    Parameters
    ----------
    cost : callable
        Called as ``cost(**mats)`` (plus one keyword per scalar): one symmetric positive-
        definite ``numpy`` array per matrix, shape (n, n), or (B, n, n) with ``batched``
        (scalars then have shape (B,)). Returns a float (or B floats). A cost that raises
        or returns NaN / inf marks that candidate ``"error"`` / ``"nonfinite"`` (see
        :data:`FAILURE_COST`) instead of stopping the run.
    matrices : mapping
        Matrix name → ``(size, (low, high))``: the matrix is size × size, its eigenvalues
        (diagonal entries for the diagonal map) lie in [low, high], 0 < low < high.
    scalars : mapping, optional
        Scalar name → ``(low, high)``: extra scalar decision variables.
    batched : bool
        Whether ``cost`` evaluates a whole batch at once (faster for vectorized costs).
    name : str
        Problem name in records and reports.
    gradient : callable, optional
        The exact gradient of one candidate: ``gradient(**mats, **scalars)`` (single
        candidate, also for a batched cost) returns {matrix name: ∂cost/∂K_ij, shape
        (n, n)} and {scalar name: ∂cost/∂scalar}. Enables ``optimizer=lbfgs``,
        ``polish=gradient`` and ``evaluate(..., gradient=True)``.
    gradient_cost : float, optional
        What one call of ``gradient`` costs, in calls of ``cost`` (CPU time of one gradient
        over that of one evaluation, measured by you): ``optimizer=lbfgs`` and
        ``polish=gradient`` count each gradient as this many evaluations of the budget.
        Without it those need ``optimizer.grad_cost``.

    Returns
    -------
    CostProblem
        An object following :class:`penaltyrun.problems.base.Problem`; pass it to
        :func:`penaltyrun.tune` or :func:`penaltyrun.evaluate`.

    Raises
    ------
    ConfigError
        A cost that is not callable, no matrix, a bad size or bounds, or a name that is
        not an identifier.
    """
    if not callable(cost):
        raise ConfigError("cost", f"must be callable, got {type(cost).__name__}")
    if not isinstance(name, str) or not name.isidentifier():
        raise ConfigError("name", f"must be an identifier, got {name!r}")
    from penaltyrun.problems import builtin_name_refused

    builtin_name_refused(name, "name", "pass another name=")
    for key, value in (("matrices", matrices), ("scalars", scalars)):
        if value is not None and not isinstance(value, Mapping):
            raise ConfigError(key, f"must be a mapping {{name: ...}}, got "
                                   f"{type(value).__name__}")
    if not matrices:
        raise ConfigError("matrices", "give at least one matrix: {name: (size, (low, high))}")
    specs = []
    for key, value in matrices.items():
        label = f"matrices.{key}"
        if not str(key).isidentifier():
            raise ConfigError(label, "a matrix name must be an identifier")
        try:
            size, bounds = value
        except (TypeError, ValueError):
            raise ConfigError(label, f"expected (size, (low, high)), got {value!r}") from None
        if not is_int(size, any_integral=True) or size < 1:
            raise ConfigError(label, f"size must be a positive integer, got {size!r}")
        low, high = _bounds(label, bounds)
        if low <= 0:
            raise ConfigError(label, f"eigenvalue bounds must be positive, got low={low}")
        specs.append(MatrixSpec(str(key), int(size), (low, high)))
    scalar_specs = tuple(ScalarSpec(str(k), _bounds(f"scalars.{k}", v))
                         for k, v in (scalars or {}).items())
    clash = {m.name for m in specs} & {s.name for s in scalar_specs}
    if clash:
        raise ConfigError(f"scalars.{sorted(clash)[0]}", "is also a matrix name")
    price = None
    if gradient_cost is not None:
        try:
            price = GradientCost(gradient_cost, "from_cost(gradient_cost=...)")
        except ValueError as exc:
            raise ConfigError("gradient_cost", str(exc)) from None
        if gradient is None:
            raise ConfigError("gradient_cost", "needs gradient (the cost of which gradient?)")
    if gradient is not None:
        if not callable(gradient):
            raise ConfigError("gradient", f"must be callable, got {type(gradient).__name__}")
        return GradientCostProblem(cost, tuple(specs), scalar_specs, batched, name, gradient,
                                   price)
    return CostProblem(cost, tuple(specs), scalar_specs, batched, name)


def as_module(problem: Any) -> types.ModuleType:
    """A problem module (``CASES``, ``DEFAULT_CASE``, ``make_problem``) around one problem
    object, so the registry can serve an in-memory problem like a module's.

    ``make_problem(case, params)`` returns the object itself and refuses parameters: an
    in-memory problem has none to override.
    """
    mod = types.ModuleType(f"penaltyrun.problems.user_cost.<{problem.name}>")
    mod.CASES = (str(problem.case),)
    mod.DEFAULT_CASE = str(problem.case)

    def make_problem(case: str, params: Mapping[str, Any]) -> Any:
        if params:
            raise ConfigError(f"problem.params.{sorted(params)[0]}", "an in-memory problem "
                              "takes no parameters (build another one instead)")
        return problem

    mod.make_problem = make_problem
    return mod


__all__ = ["CASE", "FAILURE_COST", "STATUSES", "CostProblem", "GradientCostProblem",
           "as_module", "from_cost"]
