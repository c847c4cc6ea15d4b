"""The no-progress stop rule of the low-thrust problems (status ``no_progress``).

A transfer stops with status ``no_progress`` when the best Q (Q-law) or V (generic law) seen so
far has not fallen by the fraction ``no_progress_frac`` over the last ``no_progress_revs``
revolutions (checked every ``no_progress_revs`` revolutions; ``no_progress_revs = 0`` turns the
rule off). It is a failed evaluation with the usual graded penalty.

Defaults (20 revolutions, 1 %) cut none of the converging K = I transfers of cases A–C (both
laws), none of the converging transfers in the tests and none of the random full-K transfers of
cases D, E and E* that converge; see ``bench/README.md`` for the share of evaluations they
shorten (on D, E and E* the propellant-floor runs keep lowering Q by 20–40 % every 20 days, as
the converging ones do until their final descent, so no fraction/window pair separates them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.errors import ConfigError


@dataclass(frozen=True)
class NoProgressParams:
    """Parameters of the no-progress rule (mixed into the low-thrust ``Params``).

    Attributes
    ----------
    no_progress_revs : float
        Window in revolutions (0 disables the rule).
    no_progress_frac : float
        Fraction in [0, 1) by which the best Q (or V) must fall per window.
    """

    no_progress_revs: float = 20.0
    no_progress_frac: float = 0.01

    def check_no_progress(self) -> None:
        """Raise :class:`ConfigError` on an invalid window or fraction."""
        if not float(self.no_progress_revs) >= 0.0:
            raise ConfigError("problem.params.no_progress_revs", "must be >= 0 (0 disables)")
        if not 0.0 <= float(self.no_progress_frac) < 1.0:
            raise ConfigError("problem.params.no_progress_frac", "must be in [0, 1)")

    def apply_no_progress(self, prm: np.ndarray) -> np.ndarray:
        """Write the rule's settings into the kernel vector ``prm`` (shape (lt.N_PRM,))."""
        prm[lt.I_NPREVS] = float(self.no_progress_revs)
        prm[lt.I_NPFRAC] = float(self.no_progress_frac)
        return prm
