"""Tell a Ctrl-C of the run from a ``KeyboardInterrupt`` or ``SystemExit`` raised by the
code a job runs.

A user problem may raise ``KeyboardInterrupt`` or call ``sys.exit``. That ends its job,
never the run: the job is recorded ``failed`` with one line naming what was raised. A real
Ctrl-C must still stop the run. The two are told apart by where the exception can come from:

* a worker process of the local pool ignores SIGINT (the main process stops it), so every
  ``KeyboardInterrupt`` in it comes from the job's code (:func:`mark_worker`);
* in the main thread, while :func:`sigint_marked` is active, a Ctrl-C raises
  :class:`~penaltyrun.errors.SignalInterrupt` (``signum`` 2), so a plain
  ``KeyboardInterrupt`` comes from the job's code;
* any other thread never receives a signal's exception (Python runs signal handlers in the
  main thread), so its ``KeyboardInterrupt`` comes from the job's code too.

Where none of these holds (the main thread with a SIGINT handler of the caller's own), a
``KeyboardInterrupt`` is taken for a Ctrl-C.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from typing import Any

from penaltyrun.errors import SignalInterrupt, exit_exception_in

_state = {"worker": False, "marked": False}


def mark_worker() -> None:
    """Declare this process a pool worker that ignores SIGINT (called once it does)."""
    _state["worker"] = True


def _raise_marked(signum: int, frame: Any) -> None:
    raise SignalInterrupt(signum)


@contextlib.contextmanager
def sigint_marked() -> Iterator[None]:
    """Within the block, a Ctrl-C raises :class:`~penaltyrun.errors.SignalInterrupt`
    instead of a plain ``KeyboardInterrupt`` (main thread, Python's default SIGINT handler
    only; otherwise a no-op). The previous handler is restored afterwards."""
    if (threading.current_thread() is not threading.main_thread()
            or signal.getsignal(signal.SIGINT) is not signal.default_int_handler):
        yield
        return
    signal.signal(signal.SIGINT, _raise_marked)
    _state["marked"] = True
    try:
        yield
    finally:
        _state["marked"] = False
        signal.signal(signal.SIGINT, signal.default_int_handler)


def raised_by_job(exc: BaseException) -> bool:
    """Whether ``exc`` (a ``KeyboardInterrupt`` or ``SystemExit`` caught around a job) was
    raised by the job's code rather than by a signal sent to the run."""
    if isinstance(exc, SignalInterrupt):
        return False
    if isinstance(exc, SystemExit):
        return True
    if isinstance(exc, KeyboardInterrupt):
        return (_state["worker"] or _state["marked"]
                or threading.current_thread() is not threading.main_thread())
    return False


def reraise_run_signal(exc: BaseException) -> None:
    """Raise the Ctrl-C or SIGTERM of the run that ``exc`` (caught as an ordinary
    exception around a job's code) wraps, if it wraps one: a signal to the run stops it
    and is never recorded as the job's failure."""
    inner = exit_exception_in(exc)
    if inner is not None and inner is not exc and not raised_by_job(inner):
        raise inner


def describe_exit_exception(exc: BaseException) -> str:
    """One line for a ``KeyboardInterrupt`` / ``SystemExit`` raised by a job's code, e.g.
    ``SystemExit: the job's code called sys.exit(3)``."""
    if isinstance(exc, SystemExit):
        return (f"SystemExit: the job's code called sys.exit({exc.code!r}) "
                "(the job ended; the run goes on)")
    text = f": {exc}" if str(exc) else ""
    return (f"{type(exc).__name__}{text}: raised by the job's code, not a Ctrl-C of the run "
            "(the job ended; the run goes on)")
