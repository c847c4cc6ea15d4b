"""The command line: a thin shell over penaltyrun's library, and the only package that
imports Hydra and OmegaConf.

* ``penaltyrun`` (:func:`main`, :mod:`penaltyrun.cli.app`): the Hydra app of the modes in
  :mod:`penaltyrun.cli.modes` (optimize / evaluate / report / plan);
* ``penaltyrun-report`` (:func:`report_main`, :mod:`penaltyrun.cli.report`);
* before Hydra runs: :mod:`~penaltyrun.cli.quickcheck` (plain values, before Hydra and numba
  load), :mod:`~penaltyrun.cli.args` (flags, sweeps, Hydra's errors),
  :mod:`~penaltyrun.cli.preflight` with :mod:`~penaltyrun.cli.checks` (the composed config,
  built as the runner builds it), :mod:`~penaltyrun.cli.userconf` (the user's config
  directories), :mod:`~penaltyrun.cli.helptext` (``--help``);
* :mod:`penaltyrun.cli.spec`: the one boundary from a composed config to the typed run
  specification (:class:`penaltyrun.runner.spec.RunSpec`) the runner takes.

``python -m penaltyrun.cli`` runs ``penaltyrun``. The names below are imported on first use,
so that ``import penaltyrun.cli`` stays cheap.
"""

from __future__ import annotations

from penaltyrun import lazy
from penaltyrun.errors import (  # noqa: F401 (the command line's exit codes)
    EXIT_ABORTED,
    EXIT_CODES,
    EXIT_ENVIRONMENT,
    EXIT_INTERRUPTED,
    EXIT_JOBS_FAILED,
    EXIT_OK,
    EXIT_USAGE,
)

_NAMES = {
    "main": "app", "install_signal_handlers": "app", "use_file_backend": "app",
    "report_main": "report", "MODES": "modes",
}

__all__ = sorted([*_NAMES, "EXIT_ABORTED", "EXIT_CODES", "EXIT_ENVIRONMENT", "EXIT_INTERRUPTED",
                  "EXIT_JOBS_FAILED", "EXIT_OK", "EXIT_USAGE"])

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())
