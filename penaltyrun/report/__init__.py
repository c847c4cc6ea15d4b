"""Tables and figures from Parquet results only.

:func:`build_report` is imported on first use (it loads matplotlib and scipy.stats), so
that a light module of the package (:mod:`penaltyrun.report.outdir`, which a run uses to
check its report folder before any job) costs nothing more.
"""

from __future__ import annotations

from penaltyrun import lazy

_NAMES = {"build_report": "build"}

__all__ = sorted(_NAMES)

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())
