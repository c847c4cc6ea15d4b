"""penaltyrun: tune penalty matrices of feedback controllers, diagonal vs full K = Q Λ Qᵀ.

The public API (:mod:`penaltyrun.api`), imported on first use so that the command line
starts fast:

* :func:`from_cost` — a problem from your own cost function of the matrices;
* :func:`tune` — seeded multi-start tuning of one cell, as ``penaltyrun mode=optimize``;
* :class:`TuneResult` — records, best start, summary and report of a run;
* :func:`load` — the result of a run or study folder;
* :func:`evaluate` — one candidate's matrices in detail, as ``mode=evaluate``;
* :func:`compare` — the report's map-vs-map statistics of two results;
* the errors they raise: :class:`ConfigError` (bad input), :class:`RunInterruptedError`,
  :class:`RunAbortedError`, :class:`EnvironmentProblemError`,
  :class:`ResultsUnreadableError`.
"""

from __future__ import annotations

from penaltyrun import safepath

safepath.guard_report_cli()  # before any import a received folder could shadow

from penaltyrun import lazy  # noqa: E402

__version__ = "0.1.0"

_NAMES = {name: "api" for name in ("Best", "TuneResult", "compare", "evaluate",
                                   "from_cost", "load", "tune")}
_NAMES.update({name: "errors" for name in ("ConfigError", "EnvironmentProblemError",
                                           "ResultsUnreadableError", "RunAbortedError",
                                           "RunInterruptedError")})

__all__ = ["__version__", *sorted(_NAMES)]

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())
