"""Call a function in a forked process of its own, under a wall-clock limit.

Used for work that runs a user problem's code outside the jobs, such as the forecast's
sample evaluations before a run: with ``runner.job_timeout`` set, a problem that hangs, or
ends its process (``os._exit``, a segmentation fault), must not stop the run there either.
The child is forked like a pool worker (:mod:`penaltyrun.runner.pool`): SIGINT ignored,
the parent's SIGTERM / SIGHUP handlers dropped, killed with the parent.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any

from penaltyrun.runner import interrupts
from penaltyrun.runner.pool import (
    FORK_BLOCKED,
    describe_exit,
    die_with_parent,
    own_fault_handler,
    signals_blocked,
)


class IsolatedCallError(RuntimeError):
    """The isolated call raised, its process ended, or it ran past its limit (one line)."""


def can_isolate() -> bool:
    """Whether this platform can fork (elsewhere :func:`call_isolated` is not used)."""
    return "fork" in mp.get_all_start_methods()


def _child(conn: Connection, parent_pid: int, func: Callable[..., Any],
           args: tuple[Any, ...]) -> None:
    own_fault_handler()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the parent stops us
    interrupts.mark_worker()
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, FORK_BLOCKED)
    die_with_parent(parent_pid)
    try:
        reply = ("ok", func(*args))
    except BaseException as exc:  # the caller gets one line, whatever was raised
        reply = ("error", f"{type(exc).__name__}: {exc}")
    conn.send(reply)
    conn.close()


def call_isolated(func: Callable[..., Any], args: tuple[Any, ...], time_limit_s: float,
                  what: str) -> Any:
    """``func(*args)`` in a forked child process; its (picklable) result.

    Parameters
    ----------
    func : callable
    args : tuple
    time_limit_s : float
        Wall-clock seconds the call may take (s); the child is then killed.
    what : str
        Name of the limit for the message, e.g. ``"runner.job_timeout"``.

    Raises
    ------
    IsolatedCallError
        The call raised (its type and message), the child ended without an answer, or it
        ran longer than ``time_limit_s``.
    """
    ctx = mp.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, os.getpid(), func, args), daemon=True,
                       name="penaltyrun-isolated")
    with signals_blocked(FORK_BLOCKED):
        proc.start()
    send.close()
    answered = False
    try:
        if not receive.poll(time_limit_s):
            raise IsolatedCallError(f"ran longer than {what}={time_limit_s:g} s; its "
                                    f"process (pid {proc.pid}) was killed")
        try:
            kind, value = receive.recv()
        except (EOFError, OSError):
            proc.join(timeout=5)
            raise IsolatedCallError(describe_exit(proc.exitcode)) from None
        answered = True
    finally:
        if answered:
            proc.join(timeout=5)  # it ends by itself after its answer
        if proc.is_alive():
            proc.kill()
        proc.join(timeout=5)
        receive.close()
    if kind != "ok":
        raise IsolatedCallError(value)
    return value
