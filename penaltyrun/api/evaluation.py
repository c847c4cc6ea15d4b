"""Evaluate given matrices in detail: :func:`evaluate` (``penaltyrun mode=evaluate``).

A candidate is given as matrices (``matrices``) or as the optimizer's decision vector
(``z``, in the order of ``z_names`` of the parameterization ``param``); ``gradient`` adds
d cost / d z (:func:`with_gradient`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import check_spd, gradient_support
from penaltyrun.typed import is_number


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
    given = {k: v for k, v in _mapping(matrices, "matrices", prob).items() if v is not None}
    wanted = [spec.name for spec in prob.matrices]
    extra = sorted(set(given) - set(wanted))
    if extra:
        raise ConfigError(f"matrices.{extra[0]}", f"not a matrix of problem {prob.name!r}",
                          allowed=wanted)
    for spec in prob.matrices:
        if spec.name not in given:
            raise ConfigError(f"matrices.{spec.name}", f"missing: give the {spec.size}x"
                              f"{spec.size} matrix {spec.name} (nested lists or an array)")
        check_spd(f"matrices.{spec.name}", given[spec.name], spec.size)
    scalars_given = {k: v for k, v in _mapping(scalars, "scalars", prob).items()
                     if v is not None}
    extra = sorted(set(scalars_given) - {spec.name for spec in prob.scalars})
    if extra:
        raise ConfigError(f"scalars.{extra[0]}", f"not a scalar of problem {prob.name!r}",
                          allowed=[spec.name for spec in prob.scalars])
    values = {}
    for spec in prob.scalars:
        if spec.name not in scalars_given:
            raise ConfigError(f"scalars.{spec.name}", f"missing: give scalar {spec.name}, a "
                              f"number in {list(spec.bounds)}")
        value = scalars_given[spec.name]
        if not is_number(value, any_real=True):
            raise ConfigError(f"scalars.{spec.name}", f"must be a number in "
                              f"{list(spec.bounds)}, got {value!r}")
        values[spec.name] = float(value)
    return prob.evaluate(given, values or None)


def _mapping(values: Any, key: str, prob: Any) -> Mapping[str, Any]:
    """``values`` (``matrices`` or ``scalars``: name → value) as a mapping; ``{}`` for
    None.

    Raises
    ------
    ConfigError
        ``values`` is not a mapping (e.g. a bare array instead of ``{"K": array}``).
    """
    if values is None:
        return {}
    if not isinstance(values, Mapping):
        names = [spec.name for spec in getattr(prob, key, ())]
        example = ", ".join(f"{n!r}: ..." for n in names) or "name: value"
        raise ConfigError(key, f"must be a mapping {{{example}}} (name → value), got a "
                          f"{type(values).__name__}")
    return values


def decode_z(layout: Any, z: Any) -> tuple[dict[str, Any], dict[str, float]]:
    """Matrices and scalars of a decision vector ``z`` (list or 1-D array of numbers,
    ``z_names`` order).

    Raises
    ------
    ConfigError
        ``z`` not a list of numbers, of the wrong length or outside the box.
    """
    names = layout.names()
    if isinstance(z, np.ndarray) and z.ndim == 1:
        z = z.tolist()  # e.g. a result's best_z: its numbers, checked like a list's
    if not isinstance(z, Sequence) or isinstance(z, str) or \
            not all(is_number(v) for v in z):
        raise ConfigError("z", f"must be a list of {len(names)} numbers in the order "
                               f"{', '.join(names)}; got {z!r}")
    vec = np.asarray([float(v) for v in z])
    if vec.size != len(names):
        raise ConfigError("z", f"expected {len(names)} values ({', '.join(names)}), got "
                               f"{vec.size}")
    lb, ub = layout.bounds()
    outside = np.flatnonzero(~((vec >= lb) & (vec <= ub)))
    if outside.size:
        i = int(outside[0])
        raise ConfigError("z", f"{names[i]} = {vec[i]:g} is outside its bounds "
                               f"[{lb[i]:g}, {ub[i]:g}]")
    mats, scalars = layout.split(vec[None])
    return ({k: v[0].tolist() for k, v in mats.items()},
            {k: float(v[0]) for k, v in scalars.items()})


def with_gradient(prob: Any, layout: Any, result: dict[str, Any], z: Sequence[float]
                  ) -> dict[str, Any]:
    """``result`` plus ``z``, ``z_names`` and the gradient at z: ``grad`` (d cost / d z,
    ``z_names`` order; null where it does not exist), ``grad_matrices`` (d cost / d matrix,
    symmetric; null where the cost has no gradient, given also where only the map has no
    derivative) and ``gradient_note`` (why ``grad`` is null; empty otherwise)."""
    from penaltyrun.optim.gradient import chain

    vec = np.asarray(z, dtype=float)
    mats, scalars = layout.split(vec[None])
    detail = prob.gradient({k: v[0] for k, v in mats.items()},
                           {k: float(v[0]) for k, v in scalars.items()} or None)
    out = chain(layout, vec, detail)
    by_matrix = {k: np.asarray(v).tolist() for k, v in detail.matrices.items()} \
        if detail.exists else None
    return {**result, "z": vec.tolist(), "z_names": layout.names(),
            "grad": out.grad.tolist() if out.exists else None,
            "grad_matrices": by_matrix, "gradient_note": out.reason}


def evaluate_candidate(prob: Any, matrices: Mapping[str, Any] | None,
                       scalars: Mapping[str, Any] | None, z: Any, param: str,
                       param_options: Mapping[str, Any] | None, gradient: bool
                       ) -> dict[str, Any]:
    """The detailed evaluation of one candidate given as ``matrices`` (+ ``scalars``) or
    as ``z``; with ``gradient``, also d cost / d z (:func:`with_gradient`) — of the given
    matrices encoded in the map ``param``.

    Raises
    ------
    ConfigError
        Both or neither of ``matrices`` and ``z``; a bad ``z``; matrices the map cannot
        represent when a gradient is asked for; a problem without a gradient hook.
    """
    from penaltyrun.runner.setup import build_layout

    given = {k: v for k, v in _mapping(matrices, "matrices", prob).items() if v is not None}
    if z is None and not gradient:
        return evaluate_matrices(prob, given, scalars)
    if gradient:
        reason = gradient_support(prob)
        if reason:
            raise ConfigError("gradient", f"{reason}; ask for no gradient (drop "
                                          "+gradient=true; from Python, gradient=False)")
    layout = build_layout(prob, param, dict(param_options or {}))
    if z is not None:
        if given:
            raise ConfigError("z", f"give the candidate either as z or as matrices "
                                   f"({', '.join(sorted(given))}), not both")
        mats, z_scalars = decode_z(layout, z)
        result = evaluate_matrices(prob, mats, z_scalars)
        vec = list(z)
    else:
        result = evaluate_matrices(prob, given, scalars)
        try:
            vec = layout.join({k: np.asarray(v, dtype=float) for k, v in given.items()},
                              {k: float(v) for k, v in (scalars or {}).items()
                               if v is not None}).tolist()
        except ValueError as exc:
            raise ConfigError("param", f"the gradient is taken with respect to z of the "
                                       f"{param} map, which cannot represent these matrices "
                                       f"({exc}); pass param=<map> or z=[...]") from None
    if not gradient:
        return {**result, "z": [float(v) for v in vec], "z_names": layout.names()}
    return with_gradient(prob, layout, result, vec)


def evaluate(problem: Any, matrices: Mapping[str, Any] | None = None, *,
             case: str | None = None, params: Mapping[str, Any] | None = None,
             scalars: Mapping[str, Any] | None = None, z: Sequence[float] | None = None,
             param: str = "full", param_options: Mapping[str, Any] | None = None,
             gradient: bool = False) -> dict[str, Any]:
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
    z : sequence of float or ndarray (n_z,), optional
        The candidate as the optimizer's decision vector instead of ``matrices``, in the
        order of ``z_names`` of the map ``param``.
    param : str
        Parameterization of ``z`` and of the gradient (``diagonal``, ``full``, ...).
    param_options : mapping, optional
        Its options (``eig_bounds``, ``cayley_bound``).
    gradient : bool
        Add ``grad`` (d cost / d z, ``z_names`` order; null with ``gradient_note`` where
        the cost has no gradient), ``grad_matrices``, ``z`` and ``z_names``.

    Returns
    -------
    dict
        ``cost``, ``converged``, ``status``, ``t_final`` and the problem's own entries.
    """
    from penaltyrun.api.compose import checked_params, problem_node
    from penaltyrun.api.tuning import held, resolve_problem

    name, module, obj = resolve_problem(problem)
    node = problem_node(name, module)
    merged = checked_params(node, params or {})
    with held(obj):
        prob = problems.make(name, case, {k: v for k, v in merged.items() if v is not None},
                             module)
        return evaluate_candidate(prob, matrices, scalars, z, param, param_options, gradient)


__all__ = ["decode_z", "evaluate", "evaluate_candidate", "evaluate_matrices", "with_gradient"]
