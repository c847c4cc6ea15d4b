"""Reading results never runs code named in them.

Results files (a received folder, a Parquet file from someone else) hold names: the problem,
the ``problem.module`` of the stored config, a plant's ``dynamics: module:function``. While
results are read (:func:`reading_results`), none of these names is imported or called:

* penaltyrun's own problems (the fixed names of the registry) are imported as usual;
* a problem of an installed package's entry point (group ``penaltyrun.problems``) is
  imported: the user installed it;
* any other problem module is imported only when the user named it for this process
  (:func:`name_module`, e.g. ``penaltyrun-report PATH --problem-module NAME=MODULE``);
* a ``module:attribute`` inside stored problem parameters (the LQR plant's ``plant`` and
  ``dynamics``) is imported only when the user allowed its module for this process
  (:func:`allow_module`, e.g. ``penaltyrun-report PATH --plant-module MODULE``).

A refused name raises :class:`NotImportedError`; the report then works from the stored
columns alone and says so in one line. Outside :func:`reading_results` (running a study)
nothing changes: the config the user runs names the modules on purpose.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

from penaltyrun.errors import ConfigError

_READING: ContextVar[bool] = ContextVar("penaltyrun_reading_results", default=False)
#: Problem name → module the user named for this process (never read from results).
_NAMED: dict[str, str] = {}
#: Modules the user allowed for plants named in results (never read from results).
_ALLOWED: set[str] = set()


class NotImportedError(ConfigError):
    """A module named in results data that reading results does not import."""


@contextmanager
def reading_results() -> Iterator[None]:
    """Within this block, modules named in results data are not imported (nestable)."""
    token = _READING.set(True)
    try:
        yield
    finally:
        _READING.reset(token)


def is_reading() -> bool:
    """Whether the caller is reading results (see :func:`reading_results`)."""
    return _READING.get()


def name_module(problem: str, module_path: str) -> None:
    """The user names ``module_path`` as the module of ``problem`` for this process: its
    report hooks may run when results of ``problem`` are read.

    Raises
    ------
    ConfigError
        ``module_path`` is not a dotted Python module name.
    """
    _NAMED[str(problem)] = _checked(module_path, "--problem-module")


def name_held(problem: str, path: str) -> None:
    """An in-memory problem held for a run in this process (:func:`penaltyrun.problems.hold`,
    module path ``object:<name>``) is the module of ``problem`` while it is held."""
    _NAMED[str(problem)] = str(path)


def unname(problem: str, path: str) -> None:
    """Undo :func:`name_held` (nothing if ``problem`` has been named otherwise since)."""
    if _NAMED.get(str(problem)) == str(path):
        del _NAMED[str(problem)]


def allow_module(module_path: str) -> None:
    """The user allows ``module_path`` to be imported for a plant named in results (an LQR
    plant's ``plant:`` / ``dynamics:``) while results are read in this process.

    Raises
    ------
    ConfigError
        ``module_path`` is not a dotted Python module name.
    """
    _ALLOWED.add(_checked(module_path, "--plant-module"))


def allowed(module_path: str) -> bool:
    """Whether the user allowed ``module_path`` (:func:`allow_module`)."""
    return str(module_path) in _ALLOWED


def _checked(module_path: str, key: str) -> str:
    path = str(module_path).strip()
    if not path or not all(part.isidentifier() for part in path.split(".")):
        raise ConfigError(key, f"{module_path!r} is not a dotted module name (e.g. "
                          "mylab.plants)")
    return path


def named() -> dict[str, str]:
    """Problem name → module named by the user in this process."""
    return dict(_NAMED)


def snapshot() -> tuple[dict[str, str], frozenset[str]]:
    """What the user named and allowed in this process (:func:`name_module`,
    :func:`allow_module`), for :func:`restore` in a worker process of this one."""
    return dict(_NAMED), frozenset(_ALLOWED)


def restore(state: tuple[dict[str, str], frozenset[str]]) -> None:
    """Name and allow exactly what :func:`snapshot` recorded (in a worker process)."""
    named_modules, allowed_modules = state
    _NAMED.clear()
    _NAMED.update(named_modules)
    _ALLOWED.clear()
    _ALLOWED.update(allowed_modules)


def forget_named() -> None:
    """Forget every module named with :func:`name_module` or :func:`allow_module`."""
    _NAMED.clear()
    _ALLOWED.clear()


def refuse(key: str, what: str) -> NotImportedError:
    """The error for a module named in results data (one line, with the way out)."""
    return NotImportedError(key, f"{what} is named in the results data and is not imported "
                            "while results are read (reading results never runs code from "
                            "them)")


__all__ = ["NotImportedError", "allow_module", "allowed", "forget_named", "is_reading",
           "name_held", "name_module", "named", "reading_results", "refuse", "restore",
           "snapshot", "unname"]
