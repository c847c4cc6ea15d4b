"""penaltyrun as a library: tune any cost function from Python.

:func:`from_cost` makes a problem of your own cost function; :func:`tune` runs seeded
starts of one cell through the same run core as the command line (:mod:`.core`) and
returns a :class:`TuneResult`; :func:`load` reads a run or a study; :func:`evaluate`
evaluates given matrices; :func:`compare` gives the report's map-vs-map statistics.

The names are imported on first use, so ``import penaltyrun`` stays light.
"""

from __future__ import annotations

from penaltyrun import lazy

_NAMES = {
    "from_cost": "tuning", "tune": "tuning",
    "Best": "result", "TuneResult": "result", "compare": "result", "load": "result",
    "evaluate": "evaluation",
    "run_cell": "core",
}

__all__ = sorted(_NAMES)

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())
