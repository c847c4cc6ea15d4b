"""One run per run directory: an exclusive lock on ``<run_dir>/.penaltyrun.lock``.

The lock is ``fcntl.flock`` on an open file, so the operating system releases it when the
process ends however it ends (exit, signal, ``kill -9``): the lock file of a dead run may
stay behind but never blocks a resume. A second ``penaltyrun`` into a directory in use is
refused with one line naming the process that holds it (pid, host, start time).

A process holds the lock of a run directory from the first job until its results are
written (:func:`penaltyrun.io.schema.collect` releases it); taking it again in the same
process is a no-op.

The lock file is opened with ``O_NOFOLLOW`` and must be a regular file: a symbolic link (or
a FIFO, a folder) in its place is refused with one line, never written through; so is a
``jobs`` folder that is a symbolic link (job records would land outside the run directory).
"""

from __future__ import annotations

import json
import logging
import os
import socket
import stat
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from penaltyrun.errors import ConfigError, EnvironmentProblemError, describe_os_error
from penaltyrun.runner.records import JOBS_DIR

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


#: Flags of every open of the lock file: never through a link, never blocking on a FIFO.
_OPEN_FLAGS = (getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
               | getattr(os, "O_CLOEXEC", 0))


def _not_a_file(path: Path) -> ConfigError:
    return ConfigError("hydra.run.dir", f"{path} is not a regular file (a symbolic link, "
                       "FIFO or folder in place of the run lock is never written through): "
                       "remove it, then run again")


def _open(path: Path, flags: int) -> Any:
    """``path`` opened as a regular file (binary), never following a link.

    Raises
    ------
    ConfigError
        ``path`` is a symbolic link, a FIFO, a folder or any other non-regular file.
    OSError
        It cannot be opened for another reason (missing, permissions, ...).
    """
    try:
        fd = os.open(path, flags | _OPEN_FLAGS, 0o644)
    except OSError as exc:
        if path.is_symlink() or (path.exists() and not path.is_file()):
            raise _not_a_file(path) from None
        raise exc
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise _not_a_file(path)
    if hasattr(os, "set_blocking"):
        os.set_blocking(fd, True)
    return os.fdopen(fd, "r+b" if flags & os.O_RDWR else "rb")


def holder(run_dir: Path) -> dict[str, Any]:
    """What the lock file says about the process that wrote it (may be empty)."""
    try:
        with _open(Path(run_dir) / LOCK_FILE, os.O_RDONLY) as fh:
            return json.loads(fh.read(65536).decode("utf-8"))
    except (OSError, ValueError, ConfigError):
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
    if fcntl is None or _key(run_dir) in _HELD or not path.is_file() or path.is_symlink():
        return False
    try:
        with _open(path, os.O_RDONLY) as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                return True
            fcntl.flock(fh, fcntl.LOCK_UN)
    except OSError:
        return False
    return False


#: Folders and files a run (and Hydra) writes into its directory: never symbolic links,
#: and the files regular files (a FIFO would block the write).
OWN_DIRS = (JOBS_DIR, ".hydra")
OWN_FILES = (LOCK_FILE, ".hydra/config.yaml", ".hydra/hydra.yaml", ".hydra/overrides.yaml",
             "multirun.yaml")


def check_not_locked(run_dir: Path, key: str = "hydra.run.dir") -> None:
    """Refuse a run directory that another run holds, or in which a file the run writes
    (:data:`OWN_DIRS`, :data:`OWN_FILES`, Hydra's log ``*.log``) is a symbolic link that
    writing would follow out of the directory, or a file is a FIFO, device or folder that
    writing would block on (preflight, before Hydra writes; takes nothing).

    Raises
    ------
    ConfigError
        Naming the other process (pid, start time), or the link and the fix.
    """
    run_dir = Path(run_dir)
    files = [run_dir / name for name in OWN_FILES] + sorted(run_dir.glob("*.log"))
    bad = [p for p in [run_dir / name for name in OWN_DIRS] + files if p.is_symlink()]
    bad += [p for p in files if p.exists() and not p.is_symlink() and not p.is_file()]
    if bad:
        what = "a symbolic link" if bad[0].is_symlink() else "not a regular file"
        raise ConfigError(key, f"{bad[0]} is {what}; a run writes its own files only inside "
                          "its directory and only as regular files: remove it, then run "
                          "again")
    if is_locked(run_dir):
        raise _busy_error(run_dir, key)


def check_sweep_dir(sweep_dir: Path, key: str = "hydra.sweep.dir") -> None:
    """:func:`check_not_locked` of a sweep's directory and of each run directory already in
    it (a resumed sweep writes into them); a run directory that is a symbolic link is
    refused as well.

    Raises
    ------
    ConfigError
        As :func:`check_not_locked`, naming the first offending path.
    """
    sweep_dir = Path(sweep_dir)
    check_not_locked(sweep_dir, key)
    if not sweep_dir.is_dir():
        return
    for child in sorted(sweep_dir.iterdir()):
        if child.is_symlink():
            raise ConfigError(key, f"{child} is a symbolic link; a sweep writes its runs only "
                              "inside its directory: remove it, then run again")
        if child.is_dir() and not child.name.startswith("."):
            check_not_locked(child, key)


def acquire(run_dir: Path) -> None:
    """Take the lock of ``run_dir`` for this process (no-op if it holds it already).

    Raises
    ------
    ConfigError
        Another process holds it (one line naming its pid and start time; exit 2), or the
        lock file is a symbolic link, a FIFO or a folder.
    EnvironmentProblemError
        The lock file cannot be created (e.g. a read-only or full file system).
    """
    key = _key(run_dir)
    if fcntl is None or key in _HELD:
        return
    run_dir = Path(run_dir)
    if (run_dir / JOBS_DIR).is_symlink():
        raise ConfigError("hydra.run.dir", f"{run_dir / JOBS_DIR} is a symbolic link; job "
                          "records are written only into a real folder of the run "
                          "directory: remove the link (or move the folder in its place), "
                          "then run again")
    path = run_dir / LOCK_FILE
    try:
        run_dir.mkdir(parents=True, exist_ok=True)
        fh = _open(path, os.O_RDWR | os.O_CREAT)
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
                             .isoformat(timespec="seconds")}).encode("utf-8"))
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
