"""A problem's optional hooks as one typed object (no probing at the call sites)."""

from __future__ import annotations

import numpy as np

from penaltyrun import problems
from penaltyrun.problems.hooks import (
    ClosedLoopProblem,
    HeldOutProblem,
    ProblemHooks,
    ScenarioProblem,
    hooks,
)
from penaltyrun.runner import forecast


class _Bare:
    name = "bare"
    holdout = None  # an attribute that is not callable is no hook
    closed_loop = 3.0


def test_a_problem_without_hooks_has_none():
    found = hooks(_Bare())
    assert found == ProblemHooks()
    assert found.n_holdout() == 0
    assert forecast.extra_evals(_Bare(), holdout=True) == 1


def test_hooks_of_a_built_in_problem_match_its_protocols():
    prob = problems.make("zermelo", None, {}, None)
    found = hooks(prob)
    assert isinstance(prob, HeldOutProblem) and isinstance(prob, ClosedLoopProblem)
    assert isinstance(prob, ScenarioProblem)
    labels = prob.holdout_scenarios()["scenario"]
    assert found.n_holdout() == len(labels) > 0
    assert forecast.extra_evals(prob, holdout=True) == 1 + len(labels)
    assert forecast.extra_evals(prob, holdout=False) == 1
    mats = {spec.name: np.eye(spec.size) for spec in prob.matrices}
    got, want = found.holdout(mats, None), prob.holdout(mats, None)
    assert set(got) == set(want)
    np.testing.assert_array_equal(np.asarray(got["cost"], float), np.asarray(want["cost"], float))


def test_a_held_out_set_needs_both_hooks():
    class OnlyJudge:
        def holdout(self, mats, scalars=None):
            return {}

    found = hooks(OnlyJudge())
    assert found.holdout is not None and found.holdout_scenarios is None
    assert found.n_holdout() == 0
    assert not isinstance(OnlyJudge(), HeldOutProblem)
