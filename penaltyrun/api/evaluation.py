"""Evaluate given matrices in detail: :func:`evaluate` (``penaltyrun mode=evaluate``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import check_spd


def evaluate_matrices(prob: Any, matrices: Mapping[str, Any],
                      scalars: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Check the matrices (and scalars) of one candidate, then ``prob.evaluate`` them.

    Parameters
    ----------
    prob : Problem
    matrices : mapping
        Matrix name → array-like (n, n), symmetric positive definite; ``None`` values
        count as not given.
    scalars : mapping, optional
        Scalar name → value, for problems with extra scalars.

    Returns
    -------
    dict
        ``prob.evaluate``: at least ``cost``, ``converged``, ``status``, ``t_final``.

    Raises
    ------
    ConfigError
        A matrix the problem does not have, a missing, malformed, non-symmetric or
        indefinite matrix, or a missing scalar (naming ``matrices.<name>`` /
        ``scalars.<name>``).
    """
    given = {k: v for k, v in (matrices or {}).items() if v is not None}
    wanted = [spec.name for spec in prob.matrices]
    extra = sorted(set(given) - set(wanted))
    if extra:
        raise ConfigError(f"matrices.{extra[0]}", f"not a matrix of problem {prob.name!r}",
                          allowed=wanted)
    for spec in prob.matrices:
        if spec.name not in given:
            raise ConfigError(f"matrices.{spec.name}", f"missing; pass "
                              f"'matrices.{spec.name}=[[...], ...]' ({spec.size}x{spec.size})")
        check_spd(f"matrices.{spec.name}", given[spec.name], spec.size)
    scalars_given = {k: v for k, v in (scalars or {}).items() if v is not None}
    values = {}
    for spec in prob.scalars:
        if spec.name not in scalars_given:
            raise ConfigError(f"scalars.{spec.name}", "missing; pass "
                              f"'scalars.{spec.name}=<value>' in {list(spec.bounds)}")
        values[spec.name] = float(scalars_given[spec.name])
    return prob.evaluate(given, values or None)


def evaluate(problem: Any, matrices: Mapping[str, Any], *, case: str | None = None,
             params: Mapping[str, Any] | None = None,
             scalars: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Evaluate one candidate's matrices in detail: the dict ``penaltyrun mode=evaluate``
    prints for the same problem, case, parameters and matrices.

    Parameters
    ----------
    problem : str or problem object
        As for :func:`penaltyrun.tune`: a problem name, a module path or a
        :func:`~penaltyrun.from_cost` problem.
    matrices : mapping
        Matrix name → nested lists or array (n, n), symmetric positive definite.
    case : str, optional
        Problem case (``None``: the default case).
    params : mapping, optional
        Problem parameter overrides.
    scalars : mapping, optional
        Extra scalars of the problem (e.g. ``eta_cut`` of ``qlaw``).

    Returns
    -------
    dict
        ``cost``, ``converged``, ``status``, ``t_final`` and the problem's own entries.
    """
    from penaltyrun.api.compose import problem_node
    from penaltyrun.api.tuning import held, resolve_problem

    name, module, obj = resolve_problem(problem)
    node = problem_node(name, module)
    merged = {**(node.get("params") or {}), **dict(params or {})}
    with held(obj):
        prob = problems.make(name, case, {k: v for k, v in merged.items() if v is not None},
                             module)
        return evaluate_matrices(prob, matrices, scalars)


__all__ = ["evaluate", "evaluate_matrices"]
