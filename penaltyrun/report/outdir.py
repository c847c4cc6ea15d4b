"""The folder a report or an export writes into: nothing outside it, nothing mixed.

* The folder itself must not be a symbolic link (a received results folder may hold a
  ``report`` link pointing anywhere): :func:`prepare` refuses it with one line.
* Every file is written into a fresh temporary folder inside it and renamed into place
  (:func:`publish`); a rename replaces a link of the same name instead of writing through it.
* A temporary folder left by a report that was killed (``<prefix><pid>-XXXX`` of a process
  that no longer runs) is removed by the next report into the same folder.
* Files a previous report (or export) in the same folder wrote and the new one does not are
  removed, so tables of two reports never stand side by side. Only files the previous one
  owned go: its known table names, the figures its ``report.md`` shows (or the files its
  ``index.csv`` lists), each a plain name inside the folder.
"""

from __future__ import annotations

import csv
import logging
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

from penaltyrun.errors import ConfigError, EnvironmentProblemError, describe_os_error
from penaltyrun.runner.records import read_regular_bytes

logger = logging.getLogger(__name__)

_FIGURE = re.compile(r"^!\[[^\]]*\]\(([^)]+)\)\s*$")


def plain_name(name: str, suffixes: Iterable[str]) -> bool:
    """Whether ``name`` is a file name inside a folder (no separator, not hidden) with one
    of ``suffixes``."""
    return (bool(name) and "/" not in name and "\\" not in name and "\0" not in name
            and not name.startswith(".") and name.lower().endswith(tuple(suffixes)))


def link_inside(out: Path, source: Path) -> Path | None:
    """The first part of the path ``out`` (as given, before ``..`` is resolved) that is a
    symbolic link placed inside the folder ``source`` (a received results folder, which
    may hold links pointing anywhere), or None."""
    source = Path(source)
    folder = Path(os.path.realpath(source if source.is_dir() else source.parent))
    out = Path(out)
    path = Path(out.anchor) if out.is_absolute() else Path.cwd()
    for part in out.parts[1:] if out.is_absolute() else out.parts:
        path = path / part
        if part != ".." and path.is_symlink():
            where = Path(os.path.realpath(path.parent))
            if where == folder or folder in where.parents:
                return path
    return None


def prepare(out: Path, key: str, source: Path | None = None) -> Path:
    """Create the output folder ``out`` after :func:`check`.

    Raises
    ------
    ConfigError
        As :func:`check`.
    """
    out = check(out, key, source)
    out.mkdir(parents=True, exist_ok=True)
    return out


def check(out: Path, key: str, source: Path | None = None) -> Path:
    """Refuse the output folder ``out`` (nothing created) when it is a symbolic link or a
    file, or a path through a symbolic link inside the results folder ``source``
    (:func:`link_inside`).

    Raises
    ------
    ConfigError
        ``out`` is a symbolic link or not a folder, or leads through a link inside
        ``source`` (one line with the fix).
    """
    out = Path(out)
    if out.is_symlink():
        raise ConfigError(key, f"{out} is a symbolic link; reports and exports are written "
                          "only into a real folder: remove the link or choose another folder")
    link = link_inside(out, source) if source is not None else None
    if link is not None:
        raise ConfigError(key, f"{out} leads through {link}, a symbolic link inside the "
                          f"results folder {source}; reports and exports are written only "
                          "into real folders: choose another folder")
    if out.exists() and not out.is_dir():
        raise ConfigError(key, f"{out} is a file; pass a folder path")
    return out


def _read_own(path: Path) -> str:
    """Text of a regular file inside the folder ('' for a link, a FIFO, a missing file)."""
    try:
        return read_regular_bytes(path).decode("utf-8", errors="replace")
    except OSError:
        return ""


def report_files(out: Path, tables: Iterable[str]) -> set[str]:
    """Files of the report already in ``out``: ``report.md``, ``report.html``, the tables
    (``<stem>.csv`` / ``.md``) and the figures ``report.md`` shows."""
    text = _read_own(out / "report.md")
    if not text:
        return set()
    names = {"report.md", "report.html"}
    names |= {f"{stem}{ext}" for stem in tables for ext in (".csv", ".md")}
    names |= {m.group(1) for m in map(_FIGURE.match, text.splitlines())
              if m and plain_name(m.group(1), (".png",))}
    return names


def export_files(out: Path) -> set[str]:
    """Files of an export already in ``out``: ``index.csv`` and the files it lists."""
    text = _read_own(out / "index.csv")
    if not text:
        return set()
    names = {"index.csv"}
    for row in csv.DictReader(text.splitlines()):
        names |= {row[k] for k in ("json", "mat")
                  if row.get(k) and plain_name(row[k], (".json", ".mat"))}
    return names


def _alive(pid: int) -> bool:
    """Whether a process ``pid`` runs (a process of another user counts as running)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # no permission: it exists
        return True
    return True


def remove_abandoned(out: Path, prefix: str) -> list[str]:
    """Remove the temporary folders ``<prefix><pid>-*`` in ``out`` whose process no longer
    runs (a report or export killed before it could clean up); their names."""
    pattern = re.compile(re.escape(prefix) + r"(\d+)-")
    removed = []
    for item in out.iterdir():
        match = pattern.match(item.name)
        if (match and item.is_dir() and not item.is_symlink()
                and not _alive(int(match.group(1)))):
            shutil.rmtree(item, ignore_errors=True)
            removed.append(item.name)
    if removed:
        logger.info("removed %d temporary folder(s) of killed reports in %s", len(removed), out)
    return removed


def write_into(out: Path, key: str, write: Callable[[Path], None],
               owned: Callable[[Path], set[str]], prefix: str = ".report-",
               source: Path | None = None) -> list[Path]:
    """Run ``write(tmp)`` in a fresh folder ``<prefix><pid>-XXXX`` inside ``out``, then move
    its files into ``out`` and remove the files ``owned(out)`` names that the new set does
    not (and the temporary folders of killed reports, :func:`remove_abandoned`); ``out``
    is checked by :func:`prepare` against the results folder ``source``.

    Returns
    -------
    list of Path
        The files now in ``out``, in name order.

    Raises
    ------
    EnvironmentProblemError
        Writing failed (e.g. a full disk): one line naming the folder (and the free space);
        nothing of the new output is left in ``out``.
    ConfigError
        A folder in ``out`` has the name of a file of the new output: nothing is moved.
    """
    out = prepare(out, key, source)
    remove_abandoned(out, prefix)
    tmp = Path(tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-", dir=out))
    try:
        try:
            write(tmp)
        except OSError as exc:  # a full disk or a failing device: one line naming the folder
            raise EnvironmentProblemError(describe_os_error(exc, exc.filename or out)) from None
        previous = owned(out)
        new = sorted(item.name for item in tmp.iterdir())
        for name in new:  # every file can take its place, or none is moved
            dest = out / name
            if not (tmp / name).is_dir() and dest.is_dir() and not dest.is_symlink():
                raise ConfigError(key, f"{dest} is a folder where the output writes a file "
                                  f"of that name; move it away or choose another folder "
                                  f"(nothing was changed in {out})")
        for name in new:
            dest = out / name
            if (tmp / name).is_dir() and dest.is_dir() and not dest.is_symlink():
                shutil.rmtree(dest)
            os.replace(tmp / name, dest)
        stale = sorted(previous - set(new))
        for name in stale:
            path = out / name
            if path.is_symlink() or path.is_file():
                path.unlink()
        if stale:
            logger.info("removed %d file(s) of the previous output in %s", len(stale), out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return [out / name for name in new]


__all__ = ["check", "export_files", "plain_name", "prepare", "remove_abandoned", "report_files",
           "write_into"]
