"""The modes of ``penaltyrun`` (``mode=...``): one table, read by the checks, the help and
the Hydra app.

This module imports nothing, so that the quick check of a plain ``mode=`` value
(:mod:`penaltyrun.cli.quickcheck`) answers before Hydra or numba is imported.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Mode:
    """One mode of the command line.

    Attributes
    ----------
    name : str
        The value of ``mode=``.
    help : str
        Its line in ``penaltyrun --help``.
    plans_jobs : bool
        Whether it plans optimizer jobs (``optimizer.*`` and ``param.*`` are then read and
        checked, the grid of a cell built as a run builds it).
    run : str
        ``module:function`` of :mod:`penaltyrun.cli` that runs it on the composed config.
    """

    name: str
    help: str
    plans_jobs: bool
    run: str

    def runner(self) -> Callable[[Any], Any]:
        """The function that runs this mode on a composed config."""
        module, _, func = self.run.partition(":")
        return getattr(importlib.import_module(f"penaltyrun.cli.{module}"), func)


TABLE: tuple[Mode, ...] = (
    Mode("optimize", "run the cell's optimizer starts; write results.parquet, jobs/, report/",
         True, "app:run_optimize"),
    Mode("evaluate", "cost of the matrices given as matrices.K=[[...]] (or z=[...]; "
         "+gradient=true adds d cost / d z); one JSON line on stdout", False,
         "app:run_evaluate"),
    Mode("report", "tables and figures from results: report.input=<results.parquet or "
         "folder>", False, "app:run_report"),
    Mode("plan", "forecast jobs, evaluations and time of a cell or a sweep; runs nothing",
         True, "planmode:print_cell_plan"),
)
#: The names of the modes, in the order of :data:`TABLE`.
MODES: tuple[str, ...] = tuple(mode.name for mode in TABLE)
#: Modes that plan optimizer jobs (``plan`` forecasts them without running them).
JOB_MODES: tuple[str, ...] = tuple(mode.name for mode in TABLE if mode.plans_jobs)
BY_NAME: dict[str, Mode] = {mode.name: mode for mode in TABLE}
