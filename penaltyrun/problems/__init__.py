"""Problem registry: name → module (imported lazily so that numba compiles only what is
used).

Four routes, first match wins:

0. an in-memory problem object held for a run (:func:`hold`), named by the module path
   ``object:<name>`` (e.g. a :func:`~penaltyrun.problems.user_cost.from_cost` problem);
1. a module path given with the name (a problem config's ``module:`` key), for problems
   that live outside penaltyrun (e.g. ``mylab.problems.cartpole`` on ``PYTHONPATH``);
2. penaltyrun's own problems (:data:`REGISTRY`);
3. installed packages that register a module under the entry-point group
   ``penaltyrun.problems`` (:data:`ENTRY_POINT_GROUP`), e.g. in their ``pyproject.toml``::

       [project.entry-points."penaltyrun.problems"]
       cartpole = "mylab.problems.cartpole"

Each module follows :mod:`penaltyrun.problems.base`; one that does not is rejected with one
line saying what it lacks (:func:`check_module`, :func:`check_problem`).

While results are read (:func:`penaltyrun.problems.trust.reading_results`), route 1 is closed
to names from the data: only penaltyrun's own problems, entry points and modules the user
named (:func:`register`) are imported; and a problem whose stored parameters name a data
file (its module's ``FILE_PARAMS``) that fails to build says so without its error's
message, which may quote the file (:func:`make`).
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import importlib.util
import threading
from collections.abc import Iterator, Mapping
from types import ModuleType
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.problems import multiscenario, trust
from penaltyrun.problems.base import Problem

REGISTRY: dict[str, str] = {
    "zermelo": "penaltyrun.problems.zermelo",
    "attitude_lyapunov": "penaltyrun.problems.attitude.lyapunov",
    "attitude_lqr": "penaltyrun.problems.attitude.lqr",
    "lyapunov_transfer": "penaltyrun.problems.lowthrust.lyapunov_transfer",
    "qlaw": "penaltyrun.problems.lowthrust.qlaw",
    "mpc_rendezvous": "penaltyrun.problems.mpc.rendezvous",
    "lqr": "penaltyrun.problems.lqr",
}
ENTRY_POINT_GROUP = "penaltyrun.problems"
#: What a problem module must define (see :mod:`penaltyrun.problems.base`).
MODULE_MEMBERS = ("CASES", "DEFAULT_CASE", "make_problem")
#: What the object returned by ``make_problem`` must have (:class:`~.base.Problem`).
PROBLEM_MEMBERS = ("name", "case", "matrices", "scalars", "evaluate_batch", "evaluate",
                   "simulate")

#: Module path prefix of an in-memory problem object (:func:`hold`).
OBJECT_PREFIX = "object:"
#: In-memory problems held by a run of this process: module path → (problem, module).
_OBJECTS: dict[str, tuple[Any, ModuleType]] = {}
_OBJECTS_LOCK = threading.Lock()


@contextlib.contextmanager
def hold(problem: Any) -> Iterator[str]:
    """Make the in-memory ``problem`` importable as module path ``object:<name>`` while
    the block runs (worker processes forked meanwhile inherit it); yields that path.

    Raises
    ------
    ConfigError
        Another problem object of the same name is held already (two runs at once in one
        process): give one of them another name.
    """
    from penaltyrun.problems.user_cost import as_module

    check_problem(problem, "the problem object")
    path = f"{OBJECT_PREFIX}{problem.name}"
    with _OBJECTS_LOCK:
        held = _OBJECTS.get(path)
        if held is not None and held[0] is not problem:
            raise ConfigError("problem", f"another in-memory problem named {problem.name!r} "
                              "is running in this process; give this one another name")
        _OBJECTS[path] = (problem, as_module(problem))
        if held is None:
            trust.name_held(problem.name, path)  # its report may run the object's hooks
    try:
        yield path
    finally:
        with _OBJECTS_LOCK:
            if held is None:
                _OBJECTS.pop(path, None)
                trust.unname(problem.name, path)


def install(path: str, problem: Any) -> None:
    """Hold ``problem`` under module path ``path`` for the life of this process (a dask
    worker receiving a pickled in-memory problem; see :mod:`penaltyrun.runner.objects`)."""
    from penaltyrun.problems.user_cost import as_module

    if not path.startswith(OBJECT_PREFIX):
        raise ValueError(f"not an in-memory problem path: {path!r}")
    with _OBJECTS_LOCK:
        _OBJECTS[path] = (problem, as_module(problem))


def _held(path: str) -> tuple[Any, ModuleType]:
    with _OBJECTS_LOCK:
        entry = _OBJECTS.get(path)
    if entry is None:
        raise ConfigError("problem.module", f"{path}: an in-memory problem exists only in "
                          "the Python process that created it (pass the object itself, or "
                          "write it as a problem module)")
    return entry


def held_object(path: str) -> Any:
    """The problem object held under module path ``object:<name>`` (:func:`hold`).

    Raises
    ------
    ConfigError
        Nothing is held under ``path`` in this process.
    """
    return _held(path)[0]


def _entry_points() -> dict[str, importlib.metadata.EntryPoint]:
    return {ep.name: ep for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)}


def register(name: str, module_path: str) -> None:
    """Use ``module_path`` for problem ``name`` in this process, also while results are read
    (the user names it, e.g. ``penaltyrun-report PATH --problem-module NAME=MODULE``; never
    call this with a name read from results)."""
    trust.name_module(name, module_path)


def builtin_name_refused(name: str, key: str, fix: str) -> None:
    """Refuse a user problem (a module, an in-memory object) named like one of penaltyrun's
    own problems: its records would read as the built-in problem's and be pooled with them,
    and naming it would replace the built-in for the rest of the process.

    Raises
    ------
    ConfigError
        ``name`` is a key of :data:`REGISTRY`; the message ends with ``fix``.
    """
    if name in REGISTRY:
        raise ConfigError(key, f"{name!r} is the name of a built-in problem; a problem of "
                          f"your own needs another name: {fix}")


def available() -> tuple[str, ...]:
    """Names of the problems this installation knows (own, registered, entry points)."""
    own = [name for name, mod in REGISTRY.items() if importlib.util.find_spec(mod)]
    extra = sorted((set(trust.named()) | set(_entry_points())) - set(own))
    return tuple(own + extra)


def check_module(mod: Any, label: str) -> Any:
    """Reject a module that does not follow the problem protocol.

    Raises
    ------
    ConfigError
        ``problem.module: <label> lacks CASES, make_problem (...)``.
    """
    missing = [m for m in MODULE_MEMBERS if not hasattr(mod, m)]
    if "make_problem" not in missing and not callable(mod.make_problem):
        missing.append("make_problem (not callable)")
    if not missing:
        cases = mod.CASES
        if isinstance(cases, str) or not all(isinstance(c, str) for c in cases) or not cases:
            missing.append("CASES as a non-empty tuple of case names")
        elif mod.DEFAULT_CASE not in cases:
            missing.append(f"DEFAULT_CASE among CASES (got {mod.DEFAULT_CASE!r})")
    if missing:
        raise ConfigError("problem.module", f"{label} lacks {', '.join(missing)} "
                          "(a problem module follows penaltyrun/problems/base.py)")
    return mod


def check_problem(prob: Any, label: str) -> Problem:
    """Reject an object from ``make_problem`` that is not a :class:`~.base.Problem`."""
    missing = [m for m in PROBLEM_MEMBERS if not hasattr(prob, m)]
    missing += [m for m in ("evaluate_batch", "evaluate", "simulate")
                if m not in missing and not callable(getattr(prob, m))]
    if missing:
        raise ConfigError("problem.module", f"{label}.make_problem returned a "
                          f"{type(prob).__name__} that lacks {', '.join(missing)} "
                          "(see penaltyrun/problems/base.py: Problem)")
    return prob


def _import(path: str, key: str) -> ModuleType:
    if path.startswith(OBJECT_PREFIX):
        return _held(path)[1]
    try:
        return importlib.import_module(path)
    except ModuleNotFoundError as exc:
        raise ConfigError(key, f"cannot import {path!r}: {exc} (is its folder on "
                          "PYTHONPATH?)") from None
    except ImportError as exc:
        raise ConfigError(key, f"cannot import {path!r}: {exc}") from None


def module(name: str, module_path: str | None = None) -> ModuleType:
    """Import and return the module of problem ``name``.

    Parameters
    ----------
    name : str
        Problem name.
    module_path : str, optional
        Dotted module path (a problem config's ``module:``); takes precedence.

    Raises
    ------
    ConfigError
        If ``name`` is not a known problem, or its module cannot be imported or does not
        follow the protocol.
    trust.NotImportedError
        While results are read: ``module_path``, or a problem that is neither penaltyrun's
        own, an entry point, nor named by the user (see :mod:`.trust`).
    """
    if module_path and not trust.is_reading():  # the config being run names it: it wins
        return check_module(_import(str(module_path), "problem.module"), str(module_path))
    if not isinstance(name, str) or not all(part.isidentifier() for part in name.split(".")):
        raise ConfigError("problem", f"unknown problem {name!r}", allowed=available())
    user = trust.named()
    if name in user:
        return check_module(_import(user[name], "problem.module"), user[name])
    if name in REGISTRY and importlib.util.find_spec(REGISTRY[name]):
        return importlib.import_module(REGISTRY[name])
    eps = _entry_points()
    if name in eps:
        try:
            mod = eps[name].load()
        except ImportError as exc:
            raise ConfigError("problem", f"entry point {name} = {eps[name].value!r} "
                              f"cannot be imported: {exc}") from None
        return check_module(mod, f"{eps[name].value} (entry point {name!r})")
    if trust.is_reading():
        raise trust.refuse("problem", f"the module of problem {name!r}"
                           + (f" ({module_path!r})" if module_path else ""))
    raise ConfigError("problem", f"unknown problem {name!r}", allowed=available())


def user_code_params(name: str, module_path: str | None = None
                     ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """``(CODE_PARAMS, FILE_PARAMS)`` of the module of problem ``name``: the parameters
    whose values name user code (``module:attribute``) and data files (see
    :mod:`penaltyrun.problems.base`); empty tuples when the module declares none.

    Raises
    ------
    ConfigError
        As :func:`module`; or a declaration that is not a tuple of parameter names.
    """
    mod = module(name, module_path)
    return _declared(mod, "CODE_PARAMS"), _declared(mod, "FILE_PARAMS")


def _declared(mod: ModuleType, member: str) -> tuple[str, ...]:
    """The parameter names of ``mod.<member>`` (``CODE_PARAMS`` or ``FILE_PARAMS``).

    Raises
    ------
    ConfigError
        The declaration is not a tuple of names.
    """
    names = getattr(mod, member, ())
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise ConfigError("problem.module", f"{mod.__name__}.{member} must be a tuple of "
                          f"parameter names, got {names!r}")
    return tuple(names)


def make(name: str, case: str | None, params: Mapping[str, Any] | None = None,
         module_path: str | None = None) -> Problem:
    """Build problem ``name`` for ``case`` (``None`` → the module's default case).

    Parameters
    ----------
    name : str
        Problem name.
    case : str or None
        Case name; must be one of the module's ``CASES``.
    params : mapping, optional
        Parameter overrides (already merged with the case entry by the caller);
        ``train_scenarios`` / ``train_aggregate`` make a multi-scenario problem (see
        :mod:`penaltyrun.problems.multiscenario`).
    module_path : str, optional
        Module implementing the problem (outside penaltyrun); see :func:`module`.

    Raises
    ------
    ConfigError
        Unknown case, or a module or problem that does not follow the protocol. While
        results are read, also any error building a problem whose ``params`` name a data
        file (the module's ``FILE_PARAMS``): keyed ``problem.params.<name>``, with the
        error's type but not its message (a parser's message may quote the file, and the
        results named it, not the user).
    """
    mod = module(name, module_path)
    case = mod.DEFAULT_CASE if case in (None, "", "default") else str(case)
    if case not in mod.CASES:
        raise ConfigError("case", f"unknown case {case!r} for problem {name!r}", allowed=mod.CASES)
    params = dict(params or {})
    files = [key for key in _declared(mod, "FILE_PARAMS") if params.get(key)]
    try:
        built = multiscenario.build(mod, case, params)
    except Exception as exc:
        if not (files and trust.is_reading()):
            raise
        named = ", ".join(f"{key}={params[key]!s}" for key in files)
        raise ConfigError(f"problem.params.{files[0]}", f"problem {name!r} cannot be built "
                          f"from the stored parameters, which name a file ({named}): "
                          f"{type(exc).__name__} (its message is not shown: it may quote "
                          "the file, which the results named, not you)") from None
    return check_problem(built, mod.__name__)
