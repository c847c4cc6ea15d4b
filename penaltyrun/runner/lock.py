"""One run per run directory: an exclusive lock on ``<run_dir>/.penaltyrun.lock``.

The lock is ``fcntl.flock`` on an open file, so the operating system releases it when the
process ends however it ends (exit, signal, ``kill -9``): the lock file of a dead run may
stay behind but never blocks a resume. A second ``penaltyrun`` into a directory in use is
refused with one line naming the process that holds it (pid, host, start time).

A process holds the lock of a run directory from the first job until its results are
written (:func:`penaltyrun.io.schema.collect` releases it); taking it again in the same
process is a no-op.
"""

from __future__ import annotations

import json
import logging
import os
import socket
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from penaltyrun.errors import ConfigError, EnvironmentProblemError, describe_os_error

try:
    import fcntl
except ImportError:  # Windows: no flock; runs are not protected from each other there
    fcntl = None  # type: ignore[assignment]

logger = logging.getLogger(__name__)

LOCK_FILE = ".penaltyrun.lock"
#: Run directory (resolved) → open lock file of this process.
_HELD: dict[str, Any] = {}


def _key(run_dir: Path) -> str:
    return str(Path(run_dir).resolve())


def holder(run_dir: Path) -> dict[str, Any]:
    """What the lock file says about the process that wrote it (may be empty)."""
    try:
        return json.loads((Path(run_dir) / LOCK_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


def _busy_error(run_dir: Path, key: str = "hydra.run.dir") -> ConfigError:
    info = holder(run_dir)
    who = f"pid {info.get('pid', '?')}"
    if info.get("host") and info.get("host") != socket.gethostname():
        who += f" on {info['host']}"
    return ConfigError(key, f"{run_dir} is in use by another penaltyrun run ({who}, started "
                       f"{info.get('started_at', 'at an unknown time')}); wait for it to end "
                       "or choose another run directory")


def is_locked(run_dir: Path) -> bool:
    """Whether another process holds the lock of ``run_dir`` now (does not take it)."""
    path = Path(run_dir) / LOCK_FILE
    if fcntl is None or _key(run_dir) in _HELD or not path.is_file():
        return False
    try:
        with open(path, "rb") as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            fcntl.flock(fh, fcntl.LOCK_UN)
    except OSError:
        return False
    return False


def check_not_locked(run_dir: Path, key: str = "hydra.run.dir") -> None:
    """Refuse a run directory that another run holds (preflight; takes nothing).

    Raises
    ------
    ConfigError
        Naming the other process (pid, start time).
    """
    if is_locked(run_dir):
        raise _busy_error(Path(run_dir), key)


def acquire(run_dir: Path) -> None:
    """Take the lock of ``run_dir`` for this process (no-op if it holds it already).

    Raises
    ------
    ConfigError
        Another process holds it (one line naming its pid and start time; exit 2).
    EnvironmentProblemError
        The lock file cannot be created (e.g. a read-only or full file system).
    """
    key = _key(run_dir)
    if fcntl is None or key in _HELD:
        return
    run_dir = Path(run_dir)
    path = run_dir / LOCK_FILE
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        fh = open(path, "a+", encoding="utf-8")
    except OSError as exc:
        raise EnvironmentProblemError(describe_os_error(exc, path, "create")) from None
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        fh.close()
        raise _busy_error(run_dir) from None
    try:
        fh.seek(0)
        fh.truncate()
        fh.write(json.dumps({"pid": os.getpid(), "host": socket.gethostname(),
                             "started_at": datetime.now(timezone.utc)
                             .isoformat(timespec="seconds")}))
        fh.flush()
    except OSError as exc:
        fh.close()
        raise EnvironmentProblemError(describe_os_error(exc, path)) from None
    _HELD[key] = fh
    logger.debug("locked %s", path)


def release(run_dir: Path) -> None:
    """Release this process's lock of ``run_dir`` (no-op if it does not hold it). The lock
    file stays: a later run takes it over."""
    fh = _HELD.pop(_key(run_dir), None)
    if fh is not None:
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()
