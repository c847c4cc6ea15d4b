"""Provenance of a study's merged data: ``provenance.json`` beside its ``results.parquet``.

It records the machines the records ran on, the installed versions and the lock file's
hash, the git commits and package versions the records carry, the job counts by status and
the commands that ran (their sweep directories relative to the repository), so a reader
can tell what produced the committed data and how to produce it again.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
import platform
from pathlib import Path
from typing import Any

PROVENANCE = "provenance.json"
LOCK_FILE = "requirements.lock"
#: Packages whose versions the provenance file records.
PACKAGES = ("numpy", "scipy", "numba", "pyswarms", "pandas", "pyarrow", "hydra-core",
            "omegaconf", "matplotlib", "dask", "distributed")


def display_path(path: Path, root: Path) -> str:
    """``path`` relative to the repository ``root`` when it lies inside it, else as given."""
    try:
        return Path(path).resolve().relative_to(Path(root).resolve()).as_posix()
    except ValueError:
        return str(path)


def machine() -> dict[str, Any]:
    """The machine a study ran on: CPU model, cores, OS, Python."""
    model = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    from penaltyrun.runner.options import available_cores
    return {"cpu": model, "cores": available_cores(), "os": platform.platform(),
            "python": platform.python_version()}


def package_versions() -> dict[str, str]:
    """Installed versions of :data:`PACKAGES` (absent ones left out) and penaltyrun's."""
    out = {}
    for name in ("penaltyrun", *PACKAGES):
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            continue
    return out


def write_provenance(root: Path, dest: Path, frame: Any,
                     commands: list[list[str]] | None,
                     machines: list[dict[str, Any]] | None = None, *,
                     rewritten: bool = False) -> None:
    """``provenance.json``: machines, versions, lock-file hash, commits in the data, counts.

    ``machines`` are those the records ran on, for an extended merge (default: this one);
    ``machine`` is the first of them. ``rewritten``: the records are those merged before
    (nothing run), so the recorded versions and lock-file hash are kept.
    """
    lock = Path(root) / LOCK_FILE
    machines = machines or [machine()]
    info = {"machine": machines[0], "machines": machines, "packages": package_versions(),
            "lock_sha256": hashlib.sha256(lock.read_bytes()).hexdigest()
            if lock.is_file() else None,
            "git_commits": sorted({str(c) for c in frame["git_commit"].dropna()}),
            # the versions each record carries, where the schema has a packages column
            "packages_in_records": sorted({str(p) for p in frame["packages"].dropna()})
            if "packages" in frame else [],
            "jobs": int(len(frame)),
            "status": {str(k): int(v) for k, v in frame["status"].value_counts().items()},
            "commands": commands}
    if commands is None:
        info["commands"] = previous_commands(dest) or None
    if rewritten:
        before = recorded(dest)
        info.update({k: before[k] for k in ("packages", "lock_sha256") if k in before})
    (dest / PROVENANCE).write_text(json.dumps(info, indent=2, sort_keys=True) + "\n")


def recorded(dest: Path) -> dict[str, Any]:
    """``<dest>/provenance.json`` as written (empty without one)."""
    path = dest / PROVENANCE
    return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else {}


def previous_commands(dest: Path) -> list[list[str]]:
    """The commands recorded in ``<dest>/provenance.json`` (none without one)."""
    return list(recorded(dest).get("commands") or [])


def previous_machines(dest: Path) -> list[dict[str, Any]]:
    """The machines recorded in ``<dest>/provenance.json`` (none without one)."""
    info = recorded(dest)
    return list(info.get("machines") or ([info["machine"]] if info.get("machine") else []))


def extended_machines(previous: list[dict[str, Any]], *,
                       ran_here: bool) -> list[dict[str, Any]]:
    """The machines of an extended merge's records: those recorded before, and this one
    where records were run here (a machine counted once by CPU model and cores)."""
    here = machine()
    known = {(m.get("cpu"), m.get("cores")) for m in previous}
    if not previous or (ran_here and (here["cpu"], here["cores"]) not in known):
        return [*previous, here]
    return previous


def portable(argv: list[str], root: Path) -> list[str]:
    """``argv`` with its ``hydra.sweep.dir`` relative to ``root`` where it lies inside it."""
    return [f"hydra.sweep.dir={display_path(Path(a.split('=', 1)[1]), root)}"
            if a.startswith("hydra.sweep.dir=") else a for a in argv]


def command_subdir(argv: list[str]) -> str:
    """The subdir a recorded command ran into (the last part of its ``hydra.sweep.dir``)."""
    for arg in argv:
        if arg.startswith("hydra.sweep.dir="):
            return Path(arg.split("=", 1)[1]).name
    return ""


def extended_commands(previous: list[list[str]], ran: list[list[str]] | None,
                      subdirs: list[str]) -> list[list[str]]:
    """The recorded commands with each of ``ran`` in place of the one of its subdir, in the
    order of the study's command ``subdirs`` (commands of subdirs it no longer has last)."""
    by_subdir = {command_subdir(c): c for c in previous}
    by_subdir.update({command_subdir(c): c for c in ran or []})
    order = {subdir: k for k, subdir in enumerate(subdirs)}
    return [by_subdir[s] for s in sorted(by_subdir, key=lambda s: order.get(s, len(order)))]
