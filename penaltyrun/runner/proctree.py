"""Every process a worker's jobs started, wherever it went (Linux).

A worker is a process group of its own, and killing the group ends what its job started
with ``subprocess`` or ``fork`` (:mod:`penaltyrun.runner.pool`). Two kinds of process
escape a group: one that made a session of its own (``os.setsid``,
``subprocess.Popen(..., start_new_session=True)``) and one whose parent exited (a daemon's
double fork), which the kernel hands to another process. On Linux a worker therefore makes
itself a child subreaper (:func:`become_subreaper`, ``prctl(PR_SET_CHILD_SUBREAPER)``), so
such orphans are handed to the worker rather than to ``init``; every process below the
worker is then found through the parent ids of ``/proc``. :func:`freeze_descendants`
stops them all (SIGSTOP, read again until no new one appears, so none forks meanwhile) and
keeps a pidfd of each, through which :func:`kill` ends them after the worker: a process
that ended and whose number was given to another is never signalled. Elsewhere both are
no-ops (the process group is what ends with the worker).
"""

from __future__ import annotations

import ctypes
import logging
import os
import signal
import sys

logger = logging.getLogger(__name__)

#: ``prctl`` option making the calling process a child subreaper (linux/prctl.h).
PR_SET_CHILD_SUBREAPER = 36
#: Most rounds of reading the tree and stopping new processes (one fork per round at most
#: escapes being stopped before the next reads it).
ROUNDS = 50


def become_subreaper() -> None:
    """Make the calling process the subreaper of its descendants (Linux; no-op
    elsewhere or where refused)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def stat_fields(pid: int) -> list[str] | None:
    """The fields of ``/proc/PID/stat`` after the command name (state, parent id, ...;
    ``man 5 proc`` numbers them from 3), None when the process is gone or unreadable."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def _parent(pid: int) -> int | None:
    """Parent id of process ``pid`` (``/proc``), None when it is gone or unreadable."""
    fields = stat_fields(pid)
    try:
        return int(fields[1]) if fields else None
    except (IndexError, ValueError):
        return None


def descendants(pid: int) -> list[int]:
    """Ids of every process below ``pid`` (children, theirs, ...), read from ``/proc``;
    empty where there is no ``/proc``."""
    children: dict[int, list[int]] = {}
    try:
        entries = os.listdir("/proc")
    except OSError:
        return []
    for entry in entries:
        if entry.isdigit():
            parent = _parent(int(entry))
            if parent is not None:
                children.setdefault(parent, []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), ()):
            found.append(child)
            todo.append(child)
    return found


def freeze_descendants(pid: int) -> list[int]:
    """Stop every process below ``pid`` (SIGSTOP) and return a pidfd of each for
    :func:`kill`; empty where pidfds or ``/proc`` are missing."""
    if not hasattr(os, "pidfd_open") or not hasattr(signal, "pidfd_send_signal"):
        return []
    frozen: dict[int, int] = {}
    for _ in range(ROUNDS):
        new = [p for p in descendants(pid) if p not in frozen]
        if not new:
            break
        for child in new:
            try:
                fd = os.pidfd_open(child)
            except OSError:  # ended meanwhile
                continue
            if _parent(child) not in {pid, *frozen}:  # ended, and the number reused
                os.close(fd)
                continue
            try:
                signal.pidfd_send_signal(fd, signal.SIGSTOP)
            except OSError:
                os.close(fd)
                continue
            frozen[child] = fd
    return list(frozen.values())


def kill(pidfds: list[int]) -> None:
    """SIGKILL each process of ``pidfds`` (:func:`freeze_descendants`) and close them."""
    for fd in pidfds:
        try:
            signal.pidfd_send_signal(fd, signal.SIGKILL)
        except OSError:  # already ended
            pass
        finally:
            os.close(fd)


__all__ = ["PR_SET_CHILD_SUBREAPER", "ROUNDS", "become_subreaper", "descendants",
           "freeze_descendants", "kill", "stat_fields"]
