"""The shape every problem module shares.

A problem module (``penaltyrun/problems/<name>.py``) exposes

* ``CASES`` : tuple of case names, ``DEFAULT_CASE`` : str;
* a frozen parameters dataclass (``Params``) with units in its docstring;
* ``make_problem(case, params) -> Problem`` where ``params`` is a plain mapping of
  overrides (from the ``problem`` config group, already merged with the case's entry);
* plot helpers (``plot_*``) that take the dictionaries returned by ``Problem.simulate``;
* optionally ``VARIANT_IGNORE``: parameter names that do not change a run's result (e.g.
  the size of a held-out grid), so reports do not split cells by them.
* optionally ``CODE_PARAMS``: parameter names whose value names user code as
  ``module:attribute`` (e.g. a plant's dynamics), and ``FILE_PARAMS``: parameter names
  whose value is the path of a data file the problem reads. The runner hashes that code
  (with the local modules it imports) and those files into every job's identity
  (:mod:`penaltyrun.runner.usercode`), so an edited one is a new configuration. While results
  are read, a failure to build a problem whose stored parameters name a file is reported
  with its error's type only (:func:`penaltyrun.problems.make`): the message may quote a
  file the results named.
* optionally, on the problem object, the held-out interface used by the runner and the
  report: ``training_scenario()`` (the scenario the matrices are tuned on),
  ``holdout_scenarios()`` (the held-out set, disjoint from it) and
  ``holdout(mats, scalars)`` (per-scenario lists: ``scenario`` labels, ``cost``,
  ``converged``, ``status``, ...; ``None`` when the set is empty); and for multi-scenario
  tuning (:mod:`penaltyrun.problems.multiscenario`) ``scenario_key()``, ``holdout_keys()``
  and ``sample_training(n, seed)``, with ``Params`` deriving from ``TrainingParams``.
* optionally, on the problem object, ``closed_loop(mats, scalars) -> ClosedLoop | None``:
  the closed loop of one candidate linearized at the target (:class:`ClosedLoop`: its
  state matrix, continuous or discrete, the gain where there is one, state and input
  names); ``None`` when the candidate has no closed loop (e.g. no stabilizing Riccati
  solution). A law with no linearization at the target (e.g. a low-thrust steering law)
  leaves the hook out. The runner stores its eigenvalue diagnostics with each job
  (:mod:`penaltyrun.problems.diagnostics`) and the report shows them.
* optionally, on the problem object, ``gradient(mats, scalars) -> CostGradient``: the exact
  gradient of one candidate's cost with respect to its matrices and scalars
  (:class:`GradientProblem`); a point where it does not exist (a status change, a kink, a
  simulated cost) returns the reason instead of a number. Optimizers that need gradients
  check it with :func:`gradient_support`. A problem whose cost has no gradient anywhere
  may instead say why in a one-line ``no_gradient`` attribute (shown wherever a gradient
  is asked for).
* with the gradient, optionally ``gradient_cost() -> GradientCost | None``: the measured CPU
  time of one gradient in evaluations of one candidate, and where it was measured
  (:class:`PricedGradientProblem`); what ``optimizer=lbfgs`` and ``optimizer.polish=gradient``
  charge per gradient unless ``optimizer.grad_cost`` says otherwise.
* optionally, in the dict ``simulate`` returns, besides ``t`` and the time histories:
  ``channels`` ({history key: [one name per column]}) and ``limits`` ({history key:
  (lower, upper)}, scalars or one value per column, ``±inf`` for none), so the report
  draws each channel with its limits.

Exact cutoff (optional): a problem whose ``evaluate_batch`` takes a ``thresholds`` keyword
(one value per candidate, ``inf``: none) may stop a candidate as soon as the part of its cost
accumulated so far exceeds its threshold, and return status :data:`CUTOFF_STATUS` with a cost
``c`` such that threshold < c ≤ the uncut cost; a candidate it does not cut must get exactly
its uncut cost. An optimizer passes as threshold the value a candidate must beat to change
its state (PSO: the particle's personal best), so its path is the same with and without the
cutoff. A problem may ignore thresholds; problems without the keyword (user problems) are
called without them (:func:`accepts_thresholds`).

Report hooks (optional, module level; :mod:`penaltyrun.problems.report_hooks` has their
defaults): ``report_info(case, params) -> ReportInfo`` (cost name and unit, what the
held-out set is, the paper's values), ``report_plots(sims, case, params) -> {caption:
Figure}`` (figures from ``simulate`` dicts) and ``report_sections(jobs) -> [ReportSection]``
(extra sections from plain job dicts). They take plain Python / numpy data and return
Markdown text, declarative tables or matplotlib figures, so a user problem describes itself
to the report exactly as a built-in one does.

The layer below (``penaltyrun.dynamics``) holds the compiled kernels; this layer wraps them
into objects that know the problem's matrices, bounds and cost. Hydra and pandas stay out.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, Protocol, runtime_checkable

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_number

#: Status of a candidate stopped by the exact cutoff (its cost is a bound above its threshold).
CUTOFF_STATUS = "cutoff"


@dataclass(frozen=True)
class MatrixSpec:
    """One tunable symmetric positive-definite penalty matrix.

    Attributes
    ----------
    name : str
        Key used in configs and results, e.g. ``"K"``, ``"Kp"``, ``"Q"``.
    size : int
        Matrix dimension N (matrix is N × N).
    eig_bounds : tuple of float
        (lower, upper) bounds of the eigenvalues (or diagonal entries), lower > 0.
    """

    name: str
    size: int
    eig_bounds: tuple[float, float]


@dataclass(frozen=True)
class ScalarSpec:
    """An extra scalar decision variable (e.g. the Q-law coasting threshold η_cut)."""

    name: str
    bounds: tuple[float, float]


@dataclass
class BatchEvaluation:
    """Result of evaluating a batch of B candidate matrices.

    Attributes
    ----------
    cost : ndarray, shape (B,)
        Objective values; always finite (non-converged candidates get a graded penalty).
    converged : ndarray of bool, shape (B,)
        Whether the terminal condition was met.
    status : ndarray of str, shape (B,)
        Per-candidate status name (``"converged"`` or a problem-specific failure name).
    objective : ndarray, shape (B,), optional
        The values the optimizer minimizes when they differ from ``cost`` (a problem's
        objective form, e.g. −1/J); ``None``: ``cost``. Records keep ``cost``.
    """

    cost: np.ndarray
    converged: np.ndarray
    status: np.ndarray
    objective: np.ndarray | None = None


def checked_batch(result: Any, n: int, problem: Any) -> Any:
    """``result`` of ``problem.evaluate_batch`` on ``n`` candidates, checked against the
    protocol: a :class:`BatchEvaluation` (or any object with its ``cost``, ``converged``
    and ``status``) holding one entry per candidate.

    Raises
    ------
    TypeError
        In one line naming the problem and what it returned (a user module's bug: the
        job that met it is recorded ``failed`` with this message).
    """
    name = getattr(problem, "name", type(problem).__name__)
    missing = [a for a in ("cost", "converged", "status") if not hasattr(result, a)]
    if missing:
        raise TypeError(f"problem {name!r}: evaluate_batch must return a BatchEvaluation("
                        f"cost, converged, status) with one entry per candidate; it returned "
                        f"a {type(result).__name__} (without {', '.join(missing)})")
    for field_name in ("cost", "converged", "status"):
        shape = np.shape(getattr(result, field_name))
        if shape != (n,):
            raise TypeError(f"problem {name!r}: evaluate_batch returned {field_name} of "
                            f"shape {shape} for {n} candidates; it must hold one entry per "
                            f"candidate, shape ({n},)")
    return result


@runtime_checkable
class Problem(Protocol):
    """What the optimizer and runner layers need from a problem instance."""

    name: str
    case: str
    matrices: tuple[MatrixSpec, ...]
    scalars: tuple[ScalarSpec, ...]

    def evaluate_batch(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, np.ndarray] | None = None
    ) -> BatchEvaluation:
        """Evaluate B candidates; ``mats[name]`` has shape (B, N, N). Optionally a third
        keyword ``thresholds`` (shape (B,)) for the exact cutoff (module docstring)."""
        ...

    def evaluate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """Evaluate one candidate in detail; JSON-serializable dict with at least
        ``cost``, ``converged``, ``status`` and ``t_final``."""
        ...

    def simulate(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> dict[str, np.ndarray]:
        """Time histories of one candidate for plots (``t`` plus named arrays; optionally
        ``channels`` and ``limits``, see the module docstring)."""
        ...


@dataclass(frozen=True)
class CostGradient:
    """The gradient of one candidate's cost with respect to its tuned matrices and scalars
    (``gradient`` hook), or the reason it does not exist there.

    Attributes
    ----------
    cost : float
        The candidate's cost (as ``evaluate_batch`` returns it).
    status : str
        The candidate's status.
    matrices : mapping name → ndarray (N, N), or None
        d cost / d matrix as a symmetric matrix G: for every symmetric perturbation dM,
        d cost = Σ_ij G_ij dM_ij (cost unit per matrix unit). None when the gradient does
        not exist.
    scalars : mapping name → float
        d cost / d scalar (empty for a problem without scalars).
    reason : str
        Why there is no gradient (a status other than a smooth one, a simulated cost, a
        kink); empty when it exists.
    """

    cost: float
    status: str
    matrices: Mapping[str, np.ndarray] | None = None
    scalars: Mapping[str, float] = field(default_factory=dict)
    reason: str = ""

    @property
    def exists(self) -> bool:
        """Whether the cost is differentiable at this candidate (``matrices`` given)."""
        return self.matrices is not None


@runtime_checkable
class GradientProblem(Protocol):
    """Optional capability of a problem (built-in or user): the exact gradient of one
    candidate's cost. Optimizers that use gradients (``optimizer=lbfgs``,
    ``optimizer.polish=gradient``) and ``mode=evaluate +gradient=true`` need it."""

    def gradient(
        self, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float] | None = None
    ) -> CostGradient:
        """The cost of one candidate and its gradient (:class:`CostGradient`); a point where
        the gradient does not exist gives ``matrices=None`` and a ``reason``."""
        ...


@dataclass(frozen=True)
class GradientCost:
    """What one exact gradient costs, in evaluations of one candidate (``gradient_cost``
    hook): the budget of a gradient optimizer counts each gradient as this many
    evaluations, so its ``n_evals`` compare with the other optimizers' at equal CPU.

    Attributes
    ----------
    evaluations : float
        CPU time of one gradient d cost / d z (the hook plus the map's VJP) over the CPU
        time of one single-candidate evaluation (dimensionless, > 0).
    source : str
        Where the number was measured: the benchmark script and its table in
        ``bench/README.md``.

    Raises
    ------
    ValueError
        ``evaluations`` not a finite positive number.
    """

    evaluations: float
    source: str = ""

    def __post_init__(self) -> None:
        value = self.evaluations
        if not (is_number(value, any_real=True) and 0.0 < float(value) < float("inf")):
            raise ValueError(f"a gradient's cost must be a positive number of evaluations, "
                             f"got {value!r}")
        object.__setattr__(self, "evaluations", float(value))


@runtime_checkable
class PricedGradientProblem(Protocol):
    """Optional capability of a problem with a gradient: the measured cost of one gradient
    in evaluations (:class:`GradientCost`), the default charge per gradient of
    ``optimizer=lbfgs`` and ``optimizer.polish=gradient``. It may depend on the instance
    (criterion, plant size)."""

    def gradient_cost(self) -> GradientCost | None:
        """Evaluations one gradient of this instance costs, and where that was measured
        (None: not measured; a gradient optimizer then needs ``optimizer.grad_cost``)."""
        ...


def gradient_support(problem: Any) -> str:
    """Empty when ``problem`` has the ``gradient`` hook, else the one-line reason: the
    problem's own ``no_gradient`` text (a cost that is never differentiable says why), or
    that it defines no ``gradient`` method."""
    if callable(getattr(problem, "gradient", None)):
        return ""
    name = getattr(problem, "name", type(problem).__name__)
    own = getattr(problem, "no_gradient", "")
    if isinstance(own, str) and own:
        return f"problem {name!r} has no gradient: {own}"
    return (f"problem {name!r} has no gradient (its object defines no gradient(mats, "
            "scalars) method)")


@dataclass(frozen=True)
class ClosedLoop:
    """The closed loop of one candidate, linearized at the target (``closed_loop`` hook).

    Attributes
    ----------
    matrix : ndarray, shape (n, n)
        Closed-loop state matrix: ẋ = matrix · x (``time="continuous"``) or
        x_{k+1} = matrix · x_k (``time="discrete"``), x the deviation from the target.
    time : str
        ``"continuous"`` or ``"discrete"``.
    dt : float or None
        Sample time of a discrete loop (the problem's time unit); None when continuous.
    gain : ndarray, shape (m, n), or None
        The feedback gain of u = −gain · x where the law has one (linearized at the target).
    state_names : tuple of str
        One name per state (n).
    input_names : tuple of str
        One name per input (m; empty without a gain).
    """

    matrix: np.ndarray
    time: str = "continuous"
    dt: float | None = None
    gain: np.ndarray | None = None
    state_names: tuple[str, ...] = ()
    input_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        matrix = np.asarray(self.matrix, dtype=float)
        if matrix.ndim != 2 or matrix.shape[0] != matrix.shape[1]:
            raise ValueError(f"closed-loop matrix must be square, got shape {matrix.shape}")
        if self.time not in ("continuous", "discrete"):
            raise ValueError(f"time must be 'continuous' or 'discrete', got {self.time!r}")
        if self.time == "discrete" and not (self.dt is not None and self.dt > 0):
            raise ValueError("a discrete closed loop needs a sample time dt > 0")
        object.__setattr__(self, "matrix", matrix)
        if self.gain is not None:
            gain = np.atleast_2d(np.asarray(self.gain, dtype=float))
            if gain.shape[1] != matrix.shape[0]:
                raise ValueError(f"gain of shape {gain.shape} does not act on "
                                 f"{matrix.shape[0]} states")
            object.__setattr__(self, "gain", gain)


@dataclass(frozen=True)
class PaperValues:
    """Published numbers of one problem case, for the report to set beside its own.

    Keys of the mappings are map names: ``"diagonal"``, ``"full"`` (any orthogonal map) or
    a specific map (``"givens"``, ...), which takes precedence over ``"full"``.

    Attributes
    ----------
    source : str
        Where the numbers come from (e.g. ``"paper, Table 1"``).
    mean_cost, median_cost : mapping map → float
        Published mean / median cost (the problem's cost unit).
    summaries : mapping map → (best, median, mean, worst)
        Published four-number summaries.
    runs : int or None
        Number of runs behind the published numbers (a median test needs it).
    evaluations : mapping map → (min, median, max)
        Published objective-function evaluations per run (where the source gives them).
    matrices : mapping map → {matrix name: ndarray}
        Published best matrices (the report evaluates them and measures the distance).
    claim : str
        A published statement without numbers per case (e.g. "full better in all cases").
    """

    source: str = "paper"
    mean_cost: Mapping[str, float] = field(default_factory=dict)
    median_cost: Mapping[str, float] = field(default_factory=dict)
    summaries: Mapping[str, tuple[float, float, float, float]] = field(default_factory=dict)
    runs: int | None = None
    evaluations: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    matrices: Mapping[str, Mapping[str, np.ndarray]] = field(default_factory=dict)
    claim: str = ""


@dataclass(frozen=True)
class ReportInfo:
    """How one problem case describes itself to the report (all fields optional).

    Attributes
    ----------
    cost_name : str
        What a converged start's cost is, e.g. ``"J = ∫½‖u‖² dt"`` or ``"time of flight"``.
    cost_unit : str
        Its unit, e.g. ``"N²·m²·s"``, ``"days"``; ``"1"`` for a nondimensional cost; ``""``
        when the problem does not say.
    holdout_description : str
        What the held-out scenarios are (one sentence), shown beside the held-out results.
    discretization_kinds : tuple of str
        Held-out scenario ``kind`` values that re-run the training scenario at another
        discretization (not a new scenario): they give the discretization check and are
        left out of the held-out comparison.
    paper : PaperValues or None
        Published values of this case.
    """

    cost_name: str = "cost"
    cost_unit: str = ""
    holdout_description: str = ""
    discretization_kinds: tuple[str, ...] = ()
    paper: PaperValues | None = None

    @property
    def cost_label(self) -> str:
        """``"<name> (<unit>)"``, the unit ``nondimensional`` for ``"1"``, or ``"<name>
        (unit not declared)"``."""
        unit = {"": "unit not declared", "1": "nondimensional"}.get(self.cost_unit,
                                                                     self.cost_unit)
        return f"{self.cost_name} ({unit})"


@dataclass
class ReportSection:
    """An extra report section contributed by a problem (:func:`report_sections` hook).

    Attributes
    ----------
    title : str
        Heading of the section.
    text : str
        Markdown paragraphs shown under the heading.
    tables : list of (caption, rows)
        Tables as lists of dicts (one dict per row, equal keys; at most 10 keys); the
        report formats them.
    figures : list of (caption, matplotlib Figure)
        Figures the report saves (and closes) under the tables.
    """

    title: str
    text: str = ""
    tables: list[tuple[str, list[dict[str, Any]]]] = field(default_factory=list)
    figures: list[tuple[str, Any]] = field(default_factory=list)


class ParamsMixin:
    """Helpers for problem parameter dataclasses built from config mappings (plain mixin,
    usable by frozen dataclasses)."""

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], prefix: str = "problem.params") -> Any:
        """Build from defaults plus ``mapping`` overrides, rejecting unknown keys."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(mapping) - names)
        if unknown:
            raise ConfigError(
                f"{prefix}.{unknown[0]}", "unknown parameter", allowed=sorted(names)
            )
        values = {key: _like_default(f"{prefix}.{key}", getattr(cls(), key), value)
                  for key, value in mapping.items()}
        return replace(cls(), **values)


def _numeric(value: Any, depth: int = 3) -> bool:
    """A number, or a list (tuple, array) of numbers nested at most ``depth`` deep."""
    if is_number(value, any_real=True):
        return True
    return depth > 0 and isinstance(value, (list, tuple, np.ndarray)) and \
        all(_numeric(v, depth - 1) for v in value)


def _like_default(key: str, default: Any, value: Any) -> Any:
    """``value`` for a parameter whose default is ``default``: a list for a tuple default
    (as a tuple; of numbers, or lists of them, where the default's entries are), a number
    for a number, a bool for a bool; None kept. The problem's own checks (ranges, shapes)
    come after.

    Raises
    ------
    ConfigError
        ``value`` is of another kind (e.g. text where numbers are expected).
    """
    if value is None:
        return value
    if isinstance(default, tuple):
        if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, Iterable):
            raise ConfigError(key, f"expected a list, got {type(value).__name__} "
                              f"{str(value)[:40]!r}")
        value = tuple(value)
        numbers = bool(default) and all(_numeric(d) for d in default)
        if numbers and not all(_numeric(v) for v in value):
            raise ConfigError(key, f"expected a list of numbers, got {str(value)[:60]}")
        return value
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(key, f"expected true or false, got {str(value)[:40]!r}")
    elif is_number(default, any_real=True) and not is_number(value, any_real=True):
        raise ConfigError(key, f"expected a number, got {str(value)[:40]!r}")
    return value


def check_spd(name: str, matrix: Any, size: int) -> np.ndarray:
    """Validate a user-given matrix: shape (size, size), symmetric, positive definite.

    Parameters
    ----------
    name : str
        Config key used in error messages (e.g. ``"matrices.K"``).
    matrix : array_like
        Candidate matrix.
    size : int
        Required dimension.

    Returns
    -------
    ndarray, shape (size, size)

    Raises
    ------
    ConfigError
        If the matrix is malformed, of the wrong size, non-symmetric or not PD.
    """
    return spd_spectrum(name, matrix, size)[0]


def spd_spectrum(name: str, matrix: Any, size: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`check_spd`'s matrix and its eigenvalues (ascending, shape (size,)), computed
    once for the check and the caller.

    Raises
    ------
    ConfigError
        As :func:`check_spd`.
    """
    try:
        arr = np.asarray(matrix, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(name, f"not a numeric matrix ({exc})") from None
    if arr.shape != (size, size):
        raise ConfigError(name, f"expected a {size}x{size} matrix, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(name, "matrix has non-finite entries")
    scale = max(1.0, float(np.max(np.abs(arr))))
    if np.max(np.abs(arr - arr.T)) > 1e-12 * scale:  # np.allclose(rtol=0), at a third the cost
        raise ConfigError(name, "matrix is not symmetric")
    eig = np.linalg.eigvalsh(arr)
    if eig[0] <= 0.0:
        raise ConfigError(name, "matrix is not positive definite "
                          f"(smallest eigenvalue {eig[0]:.3g})")
    return arr, eig


def accepts_thresholds(problem: Any) -> bool:
    """Whether ``problem.evaluate_batch`` takes the ``thresholds`` keyword (exact cutoff)."""
    method = getattr(problem, "evaluate_batch", None)
    if method is None:
        return False
    try:
        params = inspect.signature(method).parameters
    except (TypeError, ValueError):
        return False
    param = params.get("thresholds")
    return param is not None and param.kind in (inspect.Parameter.POSITIONAL_OR_KEYWORD,
                                                inspect.Parameter.KEYWORD_ONLY)


def status_names(codes: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """Map integer kernel status codes to their names (array of str)."""
    return np.asarray([names[int(c)] for c in codes], dtype=object)


__all__ = [
    "CUTOFF_STATUS",
    "BatchEvaluation",
    "ClosedLoop",
    "CostGradient",
    "GradientCost",
    "PricedGradientProblem",
    "GradientProblem",
    "MatrixSpec",
    "ParamsMixin",
    "PaperValues",
    "Problem",
    "ReportInfo",
    "ReportSection",
    "ScalarSpec",
    "accepts_thresholds",
    "check_spd",
    "gradient_support",
    "spd_spectrum",
    "status_names",
]
