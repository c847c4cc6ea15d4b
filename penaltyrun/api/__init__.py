"""penaltyrun as a library: tune any cost function from Python.

:func:`from_cost` makes a problem of your own cost function; :func:`tune` runs seeded
starts of one cell through the same run core as the command line (:mod:`.core`) and
returns a :class:`TuneResult`; :func:`load` reads a run or a study; :func:`evaluate`
evaluates given matrices; :func:`compare` gives the report's map-vs-map statistics.

The names are imported on first use, so ``import penaltyrun`` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any

_NAMES = {
    "from_cost": "tuning", "tune": "tuning",
    "Best": "result", "TuneResult": "result", "compare": "result", "load": "result",
    "evaluate": "evaluation",
    "CellSpec": "core", "run_cell": "core",
}

__all__ = sorted(_NAMES)


def __getattr__(name: str) -> Any:
    module = _NAMES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_NAMES))
