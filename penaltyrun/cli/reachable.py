"""The YAML files a config's defaults lists reach, wherever they lie in a config directory.

Hydra follows a defaults list (``- /problem: mine``, ``- /.hidden@problem: x``,
``- g1/g2/g3: deep``, a group folder that is a symbolic link) to files the command line
does not name, and reads them without bounds. :func:`follow_defaults` walks those lists
from the files penaltyrun checks anyway, so that every file Hydra may read passes the
limits of :mod:`penaltyrun.yamlsafe` first, hidden, deep or linked alike.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

#: Most files followed from the defaults lists of one command (a bound on the work).
MAX_FOLLOWED = 1000


def _names(value: Any) -> list[str]:
    """Option names of a defaults entry's value (one, a list, or none)."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, list):
        return [v for v in value if isinstance(v, str)]
    return []


def candidates(entry: Any, group: str, dirs: Iterable[Path]) -> list[Path]:
    """Files of the search folders ``dirs`` that one defaults-list ``entry`` of a file in
    config group ``group`` ("" at the top) may name: ``{key: option}`` (key with its
    ``override`` / ``optional`` keywords and ``@package`` dropped, absolute with a leading
    ``/``, else relative to ``group`` or to the top) or a plain config name."""
    pairs: list[tuple[str, str]] = []
    if isinstance(entry, dict):
        for key, value in entry.items():
            words = str(key).split()
            name = words[-1].split("@")[0] if words else ""
            pairs += [(name, option) for option in _names(value)]
    elif isinstance(entry, str) and entry != "_self_":
        path, _, option = entry.split("@")[0].rpartition("/")
        pairs.append((path or ".", option))
    out = []
    for name, option in pairs:
        if name.startswith("/"):
            groups = [name.lstrip("/")]
        else:
            groups = [f"{group}/{name}".strip("/"), name]
        for folder in dirs:
            for g in groups:
                path = folder / g / f"{option}.yaml" if g not in ("", ".") else \
                    folder / f"{option}.yaml"
                if path.is_file() and path not in out:
                    out.append(path)
    return out


def follow_defaults(start: Iterable[tuple[Path, Path]], dirs: list[Path],
                    load: Callable[[Path, Path], Any]) -> list[Path]:
    """Read, with ``load``, every file of ``start`` ((file, its search folder) pairs) and
    every file their defaults lists reach, transitively, each once (at most
    :data:`MAX_FOLLOWED` beyond ``start``); returns the files reached beyond ``start``.

    ``load(path, folder)`` reads a file (found in search folder ``folder``) within the
    limits and returns its data (None for a file it cannot use); it raises for a file
    beyond a limit, which ends the walk.
    """
    todo = list(start)
    seen = {path for path, _ in todo}
    reached: list[Path] = []
    while todo and len(reached) <= MAX_FOLLOWED:
        path, folder = todo.pop()
        data = load(path, folder)
        defaults = data.get("defaults") if isinstance(data, dict) else None
        if not isinstance(defaults, list):
            continue
        try:
            group = path.parent.relative_to(folder).as_posix().strip(".")
        except ValueError:
            group = ""
        for entry in defaults:
            for found in candidates(entry, group, dirs):
                if found not in seen:
                    seen.add(found)
                    reached.append(found)
                    home = next((d for d in dirs if d in found.parents), folder)
                    todo.append((found, home))
    return reached
