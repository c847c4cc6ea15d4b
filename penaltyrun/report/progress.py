"""Progress of a long report: a tqdm bar of its steps on stderr.

The bar is drawn on an interactive terminal (or when asked for: ``penaltyrun-report
--progress true``) and never otherwise (``--progress false``, a log file, a pipe), as for
runs (``runner.progress``). Each step names what the report is doing (cell statistics,
one case's figures, ...); the steps are counted, not timed.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from types import TracebackType
from typing import Any


class Steps:
    """A bar over ``total`` report steps (nothing when not ``enabled``).

    Parameters
    ----------
    total : int
        Steps the report will take.
    enabled : bool, optional
        Draw the bar; default: when stderr is a terminal.
    between : callable, optional
        Called between two steps (e.g. to give freed memory back to the system).
    """

    def __init__(self, total: int, enabled: bool | None = None,
                 between: Callable[[], None] | None | bool = None) -> None:
        self.between = between if callable(between) else None
        if enabled is None:
            enabled = bool(sys.stderr is not None and sys.stderr.isatty())
        self.bar: Any = None
        self.started = False
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="report", unit="step", file=sys.stderr,
                            dynamic_ncols=True)

    def step(self, name: str) -> None:
        """Start step ``name`` (the previous one is done)."""
        if self.between is not None and self.started:
            self.between()
        if self.bar is None:
            self.started = True
            return
        if self.started:
            self.bar.update(1)
        self.started = True
        self.bar.set_postfix_str(name[:60], refresh=True)

    def __enter__(self) -> Steps:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self.bar is None:
            return
        if kind is None and self.started:
            self.bar.update(1)
        self.bar.close()


__all__ = ["Steps"]
