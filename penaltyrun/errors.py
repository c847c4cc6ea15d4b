"""Exceptions shared by every layer (no dependencies), and the exit codes of the command
line that end them (:data:`EXIT_CODES`, re-exported as ``penaltyrun.cli.EXIT_CODES``)."""

from __future__ import annotations

import signal
from collections.abc import Iterable
from typing import Any


class ConfigError(ValueError):
    """A user-facing configuration error naming the offending key.

    Parameters
    ----------
    key : str
        Dotted config key, e.g. ``"problem"`` or ``"optimizer.n_particles"``.
    message : str
        What is wrong with the value.
    allowed : iterable of str, optional
        The allowed values, listed in the message when given.
    """

    def __init__(self, key: str, message: str, allowed: Iterable[str] | None = None) -> None:
        self.key = key
        self.message = message
        self.allowed = tuple(allowed) if allowed is not None else None
        text = f"{key}: {message}"
        if self.allowed:
            text += f" (allowed: {', '.join(self.allowed)})"
        super().__init__(text)


class SignalInterrupt(KeyboardInterrupt):
    """SIGTERM or SIGHUP received: handled exactly like Ctrl-C (SIGINT).

    Parameters
    ----------
    signum : int
        The signal number.
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(f"signal {signum}")


def exit_exception_in(exc: BaseException) -> BaseException | None:
    """The ``KeyboardInterrupt`` or ``SystemExit`` that ``exc`` was raised from, if any
    (``exc`` itself, or along its chain of causes and contexts). A signal's exception
    raised while compiled code held the interpreter can come back wrapped in an ordinary
    one, e.g. ``SystemError: CPUDispatcher(...) returned a result with an exception set``
    with the ``KeyboardInterrupt`` as its cause."""
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, (KeyboardInterrupt, SystemExit)):
            return link
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    return None


def raise_wrapped_exit(exc: BaseException) -> None:
    """Raise the ``KeyboardInterrupt`` or ``SystemExit`` wrapped in the ordinary exception
    ``exc`` (:func:`exit_exception_in`), if any: code that turns a failing evaluation into a
    status calls it first, so that a Ctrl-C reaching compiled code still ends the job the
    way an unwrapped one does."""
    inner = exit_exception_in(exc)
    if inner is not None and inner is not exc:
        raise inner


class RunInterruptedError(Exception):
    """A run stopped by the user (Ctrl-C / SIGINT, SIGTERM, SIGHUP); its finished jobs stay
    on disk.

    Parameters
    ----------
    run_dir : str
        Run directory holding ``jobs/<job_id>.json``.
    n_done, n_todo : int
        Jobs finished in this call and jobs this call had to run.
    signum : int, optional
        The signal that stopped the run (default SIGINT = 2).
    """

    def __init__(self, run_dir: str, n_done: int, n_todo: int, signum: int = 2) -> None:
        self.run_dir = run_dir
        self.n_done = n_done
        self.n_todo = n_todo
        self.signum = int(signum)
        how = "interrupted" if self.signum == 2 else f"stopped by {signal_name(self.signum)}"
        super().__init__(
            f"{how} after {n_done} of {n_todo} jobs; finished jobs are kept in "
            f"{run_dir}/jobs; rerun the same command with runner.resume=true to run the rest")


class RunAbortedError(Exception):
    """A run that cannot go on for a reason outside the jobs (e.g. every dask worker lost);
    its finished jobs stay on disk for ``runner.resume=true``."""


class ResultsUnreadableError(ValueError):
    """No readable results file was found where results were expected."""


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15 etc. (``signal N`` if unknown)."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


class EnvironmentProblemError(OSError):
    """The machine refused an operation the run needs (disk full, no permission, a
    read-only file system, a path of the wrong kind): one line naming the path; records
    already written stay on disk for ``runner.resume=true``.

    Parameters
    ----------
    message : str
        The whole line (see :func:`describe_os_error`).
    """


def free_space(path: Any) -> str:
    """Free space of the file system holding ``path`` (or its first existing parent),
    e.g. ``"12.3 MB free"``; ``"no free inodes (12.3 MB free)"`` when the file system has
    room but no file can be created on it; ``"free space unknown"`` when it cannot be read."""
    import os
    from pathlib import Path

    here = Path(path)
    while not here.exists() and here != here.parent:
        here = here.parent
    try:
        fs = os.statvfs(here)
    except OSError:
        return "free space unknown"
    free = fs.f_bavail * fs.f_frsize
    text = f"{free} bytes free"
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if free >= size:
            text = f"{free / size:.1f} {unit} free"
            break
    if fs.f_files > 0 and fs.f_favail == 0:  # out of inodes (0 files: not counted)
        return f"no free inodes ({text})"
    return text


def describe_os_error(exc: OSError, path: Any = None, doing: str = "write") -> str:
    """One line for an OSError: what could not be done to which path, and why.

    A full disk (``ENOSPC``, ``EDQUOT``) also names the free space left; a permission or
    read-only error says so.

    Parameters
    ----------
    exc : OSError
    path : path-like, optional
        The path concerned (default the error's own ``filename``).
    doing : str
        Verb of the failed operation (``write``, ``read``, ``create``).
    """
    import errno

    where = path if path is not None else exc.filename
    reason = exc.strerror or str(exc) or type(exc).__name__
    line = f"cannot {doing} {where if where is not None else 'a file'}: {reason}"
    if exc.errno in (errno.ENOSPC, errno.EDQUOT):
        # the free space of the failed path's own file system; with no path known, none
        # (the current folder may be on another disk)
        space = f" ({free_space(where)})" if where is not None else ""
        line += f"{space}; free some space and rerun with runner.resume=true " \
                f"(finished jobs are kept)"
    return line


EXIT_OK = 0
EXIT_USAGE = 2
EXIT_JOBS_FAILED = 3
EXIT_ABORTED = 4
EXIT_INTERRUPTED = 130
#: A file operation the machine refused (disk full, no permission, a closed pipe).
EXIT_ENVIRONMENT = 5
#: Exit code → meaning (also in README "Errors and exit codes").
EXIT_CODES = {
    EXIT_OK: "success (every job recorded ok or diverged)",
    1: "internal error (a bug: please report the traceback)",
    EXIT_USAGE: "bad command line or config, a run directory in use by another run, or no "
                "readable results (one line on stderr)",
    EXIT_JOBS_FAILED: "the run finished but at least one job is recorded `failed` or "
                      "`timeout`",
    EXIT_ABORTED: "the run could not go on (dask: scheduler lost or no worker for "
                  "runner.worker_timeout s); finished jobs are kept",
    EXIT_ENVIRONMENT: "the machine refused a file operation (disk full, no permission, "
                      "read-only file system, output not writable): one line naming the "
                      "path; finished jobs are kept",
    128 + signal.SIGINT: "stopped by Ctrl-C (SIGINT); finished jobs are kept",
    128 + signal.SIGTERM: "stopped by SIGTERM; finished jobs are kept",
    128 + signal.SIGHUP: "stopped by SIGHUP; finished jobs are kept",
}
