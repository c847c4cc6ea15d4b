"""Build the problem, decision layout and optimizer settings of a job (validated)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from penaltyrun import optim, penalty, problems
from penaltyrun.errors import ConfigError
from penaltyrun.penalty.layout import DecisionLayout
from penaltyrun.problems.base import Problem

T = TypeVar("T")


#: Options of every parameterization (``param.*``).
PARAM_OPTIONS = ("eig_bounds", "cayley_bound")


def build_layout(problem: Problem, param: str, options: Mapping[str, Any]) -> DecisionLayout:
    """Decision layout: every matrix of ``problem`` parameterized by ``param``.

    ``options["eig_bounds"]`` (if not None) overrides the problem's eigenvalue bounds.

    Raises
    ------
    ConfigError
        An option other than :data:`PARAM_OPTIONS`, or invalid bounds.
    """
    unknown = sorted(set(options) - set(PARAM_OPTIONS) - {"name"})
    if unknown:
        raise ConfigError(f"param.{unknown[0]}", "not an option of the parameterizations",
                          allowed=list(PARAM_OPTIONS))
    specs = []
    for spec in problem.matrices:
        bounds = options.get("eig_bounds") or spec.eig_bounds
        if len(bounds) != 2:
            raise ConfigError("param.eig_bounds", "expected [lower, upper]")
        specs.append((spec.name, penalty.make(param, spec.size, tuple(bounds),
                                              options.get("cayley_bound", 100.0))))
    scalars = [(s.name, s.bounds) for s in problem.scalars]
    return DecisionLayout(tuple(specs), tuple(scalars))


def build(problem: str, case: str | None, problem_params: Mapping[str, Any], param: str,
          param_options: Mapping[str, Any], optimizer: str,
          optimizer_options: Mapping[str, Any], problem_module: str | None = None
          ) -> tuple[Problem, DecisionLayout, Any]:
    """Validate and build (problem instance, decision layout, optimizer settings).

    ``problem_module`` names the module of a problem outside penaltyrun (a problem
    config's ``module:``; see :func:`penaltyrun.problems.module`).

    The settings of an optimizer or polish that uses the exact gradient charge what the
    problem declares one gradient to cost unless ``optimizer.grad_cost`` is given
    (:func:`penaltyrun.optim.with_gradient_cost`).

    Raises
    ------
    ConfigError
        On any invalid name or value, naming the key; also a grid optimizer whose grid
        does not fit the decision dimension (:func:`penaltyrun.optim.check_dimension`), and
        a gradient charge neither given nor declared by the problem.
    """
    settings = optim.make_settings(optimizer, optimizer_options)
    if param not in penalty.KINDS:
        raise ConfigError("param", f"unknown parameterization {param!r}",
                          allowed=penalty.KINDS)
    prob = checked("problem.params", problems.make, problem, case, problem_params,
                   problem_module)
    layout = checked("param", build_layout, prob, param, param_options)
    optim.check_dimension(settings, layout.dim)
    if optimizer == "baseline":
        check_baseline_scale(prob, float(settings.scale))
    return prob, layout, optim.with_gradient_cost(settings, prob)


def check_baseline_scale(prob: Problem, scale: float) -> None:
    """Refuse a baseline ``scale`` outside a penalty matrix's eigenvalue bounds: its point
    K = scale · I lies outside every parameterization's box."""
    for spec in prob.matrices:
        lo, hi = spec.eig_bounds
        if not lo <= scale <= hi:
            raise ConfigError("optimizer.scale", f"{scale:g} · I lies outside the eigenvalue "
                              f"bounds [{lo:g}, {hi:g}] of {spec.name}; pick a scale inside "
                              "them")


def build_within(time_limit_s: float | None, problem: str, case: str | None,
                 problem_params: Mapping[str, Any], param: str,
                 param_options: Mapping[str, Any], optimizer: str,
                 optimizer_options: Mapping[str, Any], problem_module: str | None = None
                 ) -> tuple[Problem, DecisionLayout, Any]:
    """:func:`build` (the arguments after the first). A problem that is not one of
    penaltyrun's own (a problem module, an entry point or an in-memory problem) is first
    built in a forked process of its own under ``time_limit_s`` (``runner.job_timeout``):
    a construction that hangs, or ends its process (``os._exit``, a segmentation fault,
    ``SystemExit``), is then one :class:`ConfigError` instead of a run that never starts
    or a main process that ends without a word. An ordinary error is left to the build in
    this process, which raises it as usual; there a ``SystemExit`` or
    ``KeyboardInterrupt`` raised by the problem's code (not a Ctrl-C of the run) is one
    :class:`ConfigError` too. Without a limit, or where processes cannot be forked, only
    the build in this process.

    Raises
    ------
    ConfigError
        As :func:`build`; also ``problem.module`` for a construction that ran past the
        limit or ended its process.
    """
    from penaltyrun.runner import interrupts, isolated

    args = (problem, case, problem_params, param, param_options, optimizer,
            optimizer_options, problem_module)
    if problem in problems.REGISTRY and not problem_module:
        return build(*args)
    if time_limit_s is not None and isolated.can_isolate():
        try:
            isolated.call_isolated(_trial_build, args, float(time_limit_s),
                                   "runner.job_timeout")
        except isolated.IsolatedCallError as exc:
            raise ConfigError("problem.module", f"building problem {problem!r} in a process "
                              f"of its own: {exc}; fix its make_problem (or raise "
                              "runner.job_timeout)") from None
    with interrupts.sigint_marked():  # a Ctrl-C of the run is told apart while it holds
        try:
            return build(*args)
        except (KeyboardInterrupt, SystemExit) as exc:
            if not interrupts.raised_by_job(exc):
                raise
            raise ConfigError("problem.module", f"building problem {problem!r}: its code "
                              f"raised {type(exc).__name__}"
                              + (f" ({exc})" if str(exc) else "")
                              + "; fix its make_problem") from None


def _trial_build(*args: Any) -> None:
    try:
        build(*args)
    except Exception:  # an ordinary error: the build in the calling process raises it
        pass


def checked(key: str, func: Callable[..., T], *args: Any) -> T:
    """``func(*args)``; an error other than ConfigError (a problem's or a map's own
    ``TypeError``, ``ValueError``, ``KeyError``, ``IndexError`` on a bad value) becomes one
    ConfigError on ``key``."""
    try:
        return func(*args)
    except ConfigError:
        raise
    except (TypeError, ValueError, KeyError, IndexError) as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise ConfigError(key, f"invalid value: {text}") from None
