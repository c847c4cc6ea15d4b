"""Provenance of a result: the versions of the packages that produced it.

Every record carries a ``packages`` entry (JSON text in the results): Python, the numerical
packages penaltyrun computes with, the storage packages, dask where it was used, penaltyrun's
own version and the git commit of its source.
"""

from __future__ import annotations

import functools
import json
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

from penaltyrun import __version__

#: Distributions always listed (``null`` when not installed).
PACKAGES = ("numpy", "scipy", "numba", "pyswarms", "pandas", "pyarrow")
#: Distributions listed only when their module was imported by this process.
IF_USED = {"dask": "dask", "distributed": "distributed"}


@functools.cache
def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def git_commit() -> str:
    """Commit of penaltyrun's source (with ``-dirty`` if modified), or ``unknown`` outside
    a git checkout (or without git)."""
    src = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=src, capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=src, capture_output=True, text=True, timeout=5).stdout
        return sha + ("-dirty" if dirty.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def packages(git_commit: str | None = None) -> dict[str, str | None]:
    """Versions of the packages of this process.

    Parameters
    ----------
    git_commit : str, optional
        Commit of penaltyrun's source (as the run recorded it); ``None``: ``"unknown"``.

    Returns
    -------
    dict
        ``python``, each of :data:`PACKAGES`, ``dask`` / ``distributed`` when imported,
        ``penaltyrun`` and ``git_commit``.
    """
    out: dict[str, str | None] = {
        "python": f"{platform.python_implementation()} {platform.python_version()}"}
    out.update({name: _version(name) for name in PACKAGES})
    out.update({dist: _version(dist) for dist, module in IF_USED.items()
                if module in sys.modules})
    out["penaltyrun"] = __version__
    out["git_commit"] = git_commit or "unknown"
    return out


def packages_json(git_commit: str | None = None) -> str:
    """:func:`packages` as JSON text (sorted keys), the form stored in the results."""
    return json.dumps(packages(git_commit), sort_keys=True)
