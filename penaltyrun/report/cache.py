"""A cache of the report's case sections: each distinct section is drawn once.

Nearly all of a report's time goes into its case sections (figures, reference
integrations, basin maps, cliff probes); the rest (reading, statistics, tables) takes
seconds. A section is a pure function of its inputs: the rows of its problem case, the
shared tables' rows of that case, the report's options and the code that draws it. This
module keys each bundle of sections (one problem case, :mod:`penaltyrun.report.cases`) by
a SHA-256 digest of exactly that, and keeps what the bundle produced (its Markdown lines
and the files it wrote) under the key. A later report with the same inputs copies those
files instead of drawing them again, so it is the same report file for file.

What goes into a key:

* the code: every file of the installed ``penaltyrun`` package and the versions of Python
  and of the libraries that compute or draw (:func:`code_fingerprint`); any change of
  either is a new key;
* the bundle: each section's rows (every column, every value) and its file stem, the
  ``paper`` flag;
* the shared tables' rows of the bundle's problem case (cell summaries, map-vs-map tests,
  best-known values, held-out rows and ratios, paper rows, probes stored beside the
  results) and the basin-map and probe settings.

Not cached (drawn every time): a lazily read report (its rows are read inside the
sections), and a problem case whose code or data lies outside penaltyrun: a user problem,
a built-in problem the user named another module for (``--problem-module``, a problem
object held in the process), and rows that name user code or a data file (the problem's
``CODE_PARAMS`` and ``FILE_PARAMS``, e.g. an LQR ``plant`` module or ``plant_file``, which
may change under the same rows).

The cache is a folder of plain files the user owns (default ``$PENALTYRUN_CACHE_DIR``, else
``$XDG_CACHE_HOME/penaltyrun``, else ``~/.cache/penaltyrun``); an entry is written in a
temporary folder and renamed into place, and read back only if every file is a regular
file with the size and digest its manifest records; anything else is a miss. Entries of
the :data:`KEEP_CODE_VERSIONS` code versions used last are kept, older ones removed. A
cache that cannot be read or written costs time, never the report.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import logging
import os
import platform
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.report.outdir import plain_name
from penaltyrun.runner.records import read_regular_bytes

logger = logging.getLogger(__name__)

#: Libraries whose version is part of every key (they compute or draw the sections).
LIBRARIES = ("numpy", "scipy", "pandas", "pyarrow", "matplotlib", "numba")
#: Code versions (folders of entries) kept; the least recently used beyond them are removed.
KEEP_CODE_VERSIONS = 3
#: Environment variable naming the cache folder.
ENV_DIR = "PENALTYRUN_CACHE_DIR"
#: Sub-folder of the cache folder holding report sections.
SECTIONS = "report-sections"
MANIFEST = "manifest.json"
#: Prefix of an entry being written; one older than :data:`STALE_S` seconds was left by a
#: report that was killed, and is removed.
TMP_PREFIX = ".tmp-"
STALE_S = 86_400.0


def default_dir() -> Path:
    """``$PENALTYRUN_CACHE_DIR``, else ``$XDG_CACHE_HOME/penaltyrun``, else
    ``~/.cache/penaltyrun``."""
    if os.environ.get(ENV_DIR):
        return Path(os.environ[ENV_DIR])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "penaltyrun"


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 of every file of the ``penaltyrun`` package (byte for byte, by relative
    path; compiled caches left out) and of the versions of Python and :data:`LIBRARIES`."""
    import penaltyrun

    versions = [platform.python_version()]
    for name in LIBRARIES:
        try:
            versions.append(f"{name}={metadata.version(name)}")
        except metadata.PackageNotFoundError:
            versions.append(f"{name}=none")
    digest = hashlib.sha256(tree_digest(Path(penaltyrun.__file__).resolve().parent).encode())
    digest.update("\n".join(versions).encode())
    return digest.hexdigest()


def tree_digest(root: Path) -> str:
    """SHA-256 of every file under ``root`` (relative path and bytes, in sorted order),
    compiled caches (``__pycache__``, numba's ``.nbi`` / ``.nbc``) left out."""
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if "__pycache__" in path.parts or path.suffix in (".pyc", ".nbi", ".nbc") \
                or not path.is_file():
            continue
        digest.update(path.relative_to(root).as_posix().encode() + b"\0")
        digest.update(path.read_bytes() + b"\0")
    return digest.hexdigest()


def _feed(digest: Any, value: Any) -> None:
    """Add ``value`` (numbers, text, arrays, lists, dicts, tables, as read from results)
    to ``digest`` by type and content, the same in every process."""
    if isinstance(value, pd.DataFrame):
        digest.update(b"F%d:" % len(value))
        for name in value.columns:
            _feed(digest, str(name))
            _feed(digest, value[name].to_numpy())
    elif isinstance(value, np.ndarray) and value.dtype != object:
        array = np.ascontiguousarray(value)
        digest.update(f"A{array.dtype.str}{array.shape}:".encode())
        digest.update(array.tobytes())
    elif isinstance(value, (np.ndarray, list, tuple)):
        digest.update(b"L%d:" % len(value))
        for item in value:
            _feed(digest, item)
    elif isinstance(value, dict):
        digest.update(b"D%d:" % len(value))
        for k in sorted(value, key=repr):
            _feed(digest, k)
            _feed(digest, value[k])
    elif isinstance(value, (bytes, str)):
        data = value if isinstance(value, bytes) else value.encode("utf-8", "surrogatepass")
        digest.update(b"%s%d:" % (b"B" if isinstance(value, bytes) else b"S", len(data)))
        digest.update(data)
    elif isinstance(value, (bool, np.bool_)):
        digest.update(b"T" if value else b"N")
    elif isinstance(value, (int, np.integer)):
        digest.update(b"I%d;" % int(value))
    elif isinstance(value, (float, np.floating)):
        digest.update(b"R" + np.float64(value).tobytes())
    elif value is None or value is pd.NaT or value is pd.NA:
        digest.update(b"0")
    elif isinstance(value, pd.Timestamp):  # by its count in its own unit: the text of a
        _feed(digest, f"Timestamp:{value.unit}:{int(value.asm8.view('i8'))}:{value.tz}")
    else:  # other timestamps and the like: their exact text
        _feed(digest, f"{type(value).__name__}:{value!r}")


def _case_rows(table: Any, problem: str, case: str) -> Any:
    """The rows of a shared table that belong to one problem case (the whole value when it
    is not a table of problem cases)."""
    if isinstance(table, pd.DataFrame) and {"problem", "case"} <= set(table.columns):
        return table[(table["problem"] == problem) & (table["case"] == case)]
    if isinstance(table, dict) and all(isinstance(k, tuple) for k in table):  # by case
        return {k: v for k, v in table.items() if k[:2] == (problem, case)}
    return table


@dataclass(frozen=True)
class SectionCache:
    """The cache folder of report sections (picklable: sent to the report's workers).

    Parameters
    ----------
    root : Path
        The cache folder (created when first written).
    fingerprint : str
        :func:`code_fingerprint` of the code drawing the sections.
    """

    root: Path
    fingerprint: str

    @classmethod
    def at(cls, root: Path | str | None = None) -> SectionCache:
        """The cache in ``root`` (default :func:`default_dir`) for this code."""
        return cls(Path(root) if root is not None else default_dir(), code_fingerprint())

    @property
    def folder(self) -> Path:
        """Entries of this code version."""
        return self.root / SECTIONS / self.fingerprint[:32]

    def key(self, cases: list[tuple[pd.DataFrame, str]], paper: bool,
            ctx: dict[str, Any], shared: Iterable[str]) -> str:
        """SHA-256 key of a bundle: its sections' rows and stems, ``paper``, and the
        ``shared`` entries of ``ctx`` restricted to the bundle's problem case."""
        first = cases[0][0].iloc[0]
        problem, case = first["problem"], first["case"]
        digest = hashlib.sha256(self.fingerprint.encode())
        _feed(digest, [bool(paper), [stem for _, stem in cases]])
        for rows, _ in cases:
            _feed(digest, rows)
        held = _case_rows(ctx.get("held"), problem, case)
        for name in shared:
            value = _case_rows(ctx[name], problem, case)
            if name == "imps" and isinstance(held, pd.DataFrame) and "label" in held:
                value = {k: value[k] for k in set(held["label"]) & set(value)}
            _feed(digest, name)
            _feed(digest, value)
        return digest.hexdigest()

    def fetch(self, key: str, out: Path) -> list[list[str]] | None:
        """The sections' lines of entry ``key`` with its files copied into ``out``; None
        (nothing copied) when there is no intact entry."""
        entry = self.folder / key[:2] / key
        if not entry.exists():
            return None
        try:
            manifest = json.loads(read_regular_bytes(entry / MANIFEST))
            if not all(_entry_file(name) for name in manifest["files"]):
                raise ValueError("a file name is not a plain name")
            files = {name: read_regular_bytes(entry / name) for name in manifest["files"]}
            if any(len(data) != manifest["files"][name]["size"]
                   or hashlib.sha256(data).hexdigest() != manifest["files"][name]["sha256"]
                   for name, data in files.items()):
                raise ValueError("a file differs from its manifest")
            lines = manifest["lines"]
            if not (isinstance(lines, list) and all(
                    isinstance(s, list) and all(isinstance(x, str) for x in s)
                    for s in lines)):
                raise ValueError("lines are not lists of text")
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            logger.warning("report cache: entry %s is damaged (%s); removed and drawn again",
                           entry, exc)
            shutil.rmtree(entry, ignore_errors=True)
            return None
        for name, data in files.items():
            (out / name).write_bytes(data)
        with contextlib.suppress(OSError):  # marks this code version as used (pruning)
            os.utime(self.folder, None)
        return lines

    def store(self, key: str, lines: list[list[str]], staging: Path) -> None:
        """Keep ``lines`` and the files in ``staging`` as entry ``key`` (a failure is
        logged, never raised)."""
        entry = self.folder / key[:2] / key
        if not all(_entry_file(path.name) and path.is_file() for path in staging.iterdir()):
            return
        try:
            entry.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX, dir=entry.parent))
            files = {}
            for path in sorted(staging.iterdir()):
                data = path.read_bytes()
                (tmp / path.name).write_bytes(data)
                files[path.name] = {"size": len(data),
                                    "sha256": hashlib.sha256(data).hexdigest()}
            (tmp / MANIFEST).write_text(json.dumps({"files": files, "lines": lines}),
                                        encoding="utf-8")
            try:
                tmp.rename(entry)
            except OSError:  # another report stored the same entry first
                shutil.rmtree(tmp, ignore_errors=True)
        except OSError as exc:
            logger.warning("report cache: cannot write into %s (%s); the report is drawn "
                           "without it", self.root, exc)

    def prune(self, keep: int = KEEP_CODE_VERSIONS) -> None:
        """Remove the entries of all but the ``keep`` code versions used last, and the
        half-written entries of reports killed more than :data:`STALE_S` ago."""
        now = time.time()
        for tmp in self.folder.glob(f"*/{TMP_PREFIX}*"):
            try:
                if now - tmp.lstat().st_mtime > STALE_S:
                    shutil.rmtree(tmp, ignore_errors=True)
            except OSError:
                continue
        try:
            versions = sorted((p for p in (self.root / SECTIONS).iterdir()
                               if p.is_dir() and not p.is_symlink()),
                              key=lambda p: p.stat().st_mtime, reverse=True)
        except OSError:
            return
        for old in versions[keep:]:
            if old.name != self.folder.name:
                shutil.rmtree(old, ignore_errors=True)


def _entry_file(name: object) -> bool:
    """Whether ``name`` may be a file of an entry: a plain, visible name inside its folder
    (:func:`~penaltyrun.report.outdir.plain_name`), not the manifest."""
    return isinstance(name, str) and plain_name(name, ("",)) and name != MANIFEST


def cached(cache: SectionCache | None, cases: list[tuple[pd.DataFrame, str]], paper: bool,
           ctx: dict[str, Any], shared: Iterable[str], out: Path,
           draw: Callable[[Path], list[list[str]]]) -> list[list[str]]:
    """``draw(folder)`` of a bundle (its sections' lines, its files written into
    ``folder``), through ``cache``: copied from an intact entry, else drawn into a
    staging folder inside ``out``, kept, and moved into ``out``.

    ``cache`` None draws straight into ``out``.
    """
    if cache is None:
        return draw(out)
    key = cache.key(cases, paper, ctx, shared)
    lines = cache.fetch(key, out)
    if lines is not None:
        return lines
    staging = Path(tempfile.mkdtemp(prefix=".section-", dir=out))
    try:
        lines = draw(staging)
        cache.store(key, lines, staging)
        for path in staging.iterdir():
            os.replace(path, out / path.name)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return lines


__all__ = ["ENV_DIR", "KEEP_CODE_VERSIONS", "LIBRARIES", "SectionCache", "cached",
           "code_fingerprint", "default_dir", "tree_digest"]
