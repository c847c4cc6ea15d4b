"""Compass-search polish: it reaches the minimum of a smooth bowl to its smallest step, stops
on the low side of a jump (where a gradient polish has nothing to follow), stays in the box,
respects the budget, and ends exactly where the cliff probe finds no lower single-variable
step."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.jobrecord import POLISH_CONVERGED
from penaltyrun.optim import make_settings, minimize
from penaltyrun.optim.base import CountingObjective
from penaltyrun.optim.pattern import compass_search
from penaltyrun.optim.probe import STEPS, probe

LB, UB = np.array([0.0, -1.0, 2.0]), np.array([4.0, 1.0, 6.0])
WIDTH = UB - LB


def bowl(center, scale=(1.0, 3.0, 0.5)):
    center, scale = np.asarray(center, float), np.asarray(scale, float)
    return lambda Z: 1.0 + (((Z - center) / WIDTH) ** 2 * scale).sum(axis=1)


def test_smooth_bowl_is_reached_to_the_smallest_step():
    center = np.array([1.234567, 0.3, 4.5])
    counted = CountingObjective(bowl(center))
    x0 = np.array([3.5, -0.8, 2.5])
    assert compass_search(counted, x0, LB, UB) == POLISH_CONVERGED
    # it stops where a step lowers J by less than NOISE · J: |Δz / width|² · scale ≲ 1e-8
    assert counted.best_cost - 1.0 <= 2e-8
    assert np.all(np.abs(counted.best_z - center) <= 3e-4 * WIDTH)


def test_ends_on_the_low_side_of_a_jump():
    edge = 2.9999                       # the bowl's minimum at 3.2 lies past a +10 jump

    def cliff(Z):
        return bowl([3.2, 0.0, 4.0])(Z) + 10.0 * (Z[:, 0] > edge)

    counted = CountingObjective(cliff)
    assert compass_search(counted, np.array([1.0, 0.5, 5.0]), LB, UB) == POLISH_CONVERGED
    assert edge - STEPS[0] * WIDTH[0] < counted.best_z[0] <= edge
    assert counted.best_cost < 2.0


def test_a_minimum_outside_the_box_ends_on_its_face():
    counted = CountingObjective(bowl([5.0, 0.0, 4.0]))
    assert compass_search(counted, np.array([1.0, 0.0, 4.0]), LB, UB) == POLISH_CONVERGED
    assert counted.best_z[0] == UB[0]


def test_the_run_budget_ends_it():
    counted = CountingObjective(bowl([1.0, 0.0, 4.0]), max_evals=25)
    assert compass_search(counted, np.array([3.9, 0.9, 5.9]), LB, UB) == "max_evals"
    assert counted.n_evals == 25


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(0.05, 0.95), min_size=3, max_size=3),
       st.lists(st.floats(0.05, 0.95), min_size=3, max_size=3))
def test_end_point_passes_the_probe_at_the_smallest_step(center, start):
    center, x0 = LB + WIDTH * np.asarray(center), LB + WIDTH * np.asarray(start)
    f = bowl(center)
    counted = CountingObjective(f)
    assert compass_search(counted, x0, LB, UB) == POLISH_CONVERGED
    check = probe(lambda Z: (f(Z), np.ones(len(Z), bool)), counted.best_z, LB, UB,
                  steps=(STEPS[0],))
    assert check.lowest() == (0.0, pytest.approx(float("nan"), nan_ok=True))


def test_polish_pattern_through_minimize_records_its_ending():
    f = bowl([1.0, 0.2, 3.0])
    res = minimize("cmaes", f, LB, UB,
                   make_settings("cmaes", {"max_evals": 3000, "polish": "pattern",
                                           "polish_share": 0.3}), seed=5)
    assert res.stop_reason.endswith("+polish") and 0 < res.polish_evals <= res.n_evals
    assert res.n_evals <= 3000 and res.best_cost < 1.0 + 1e-9


def test_grid_refuses_a_polish_only_method_as_its_local_search():
    from penaltyrun.errors import ConfigError
    for method in ("gradient", "pattern"):
        with pytest.raises(ConfigError, match="optimizer.local_method"):
            make_settings("grid", {"local_method": method})
