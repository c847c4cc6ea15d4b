"""Q-law has no gradient, and says why: the reason reaches gradient_support (so gradient
methods are refused with it), mode=evaluate +gradient=true (one line, exit 2) and every
job's gradient_note, without running a transfer."""

from __future__ import annotations

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.optim.gradient import first_order
from penaltyrun.problems.base import gradient_support
from penaltyrun.problems.lowthrust import lyapunov_transfer, qlaw
from penaltyrun.runner.setup import build_layout


@pytest.mark.parametrize("objective", ["min_time", "min_fuel"])
def test_the_reason_reaches_every_user_of_the_gradient(objective):
    prob = qlaw.make_problem(qlaw.DEFAULT_CASE, {"objective": objective})
    reason = gradient_support(prob)
    assert qlaw.NO_GRADIENT in reason and "effectivity gate" in reason and "\n" not in reason
    layout = build_layout(prob, "diagonal", {})
    lb, ub = layout.bounds()
    rec = first_order(prob, layout, 0.5 * (lb + ub))
    assert np.isnan(rec["grad_norm"]) and rec["gradient_note"] == reason


def test_evaluate_with_gradient_is_refused_with_the_reason():
    with pytest.raises(ConfigError, match="piecewise in K"):
        penaltyrun.evaluate("qlaw", z=[1.0] * 5, param="diagonal", gradient=True)


def test_the_generic_law_keeps_the_plain_reason():
    prob = lyapunov_transfer.make_problem(lyapunov_transfer.DEFAULT_CASE, {})
    assert "defines no gradient" in gradient_support(prob)
