"""L-BFGS-B steps back from trial points without a gradient instead of ending the run.

The test cost is a quadratic bowl whose gradient is withheld on part of the box (as a
status change or a map's singular set withholds it): the minimum lies where the gradient
exists, but L-BFGS-B's first trial step from the start lands in the withheld part."""

from types import SimpleNamespace

import numpy as np
import pytest

from penaltyrun import optim
from penaltyrun.optim.base import CountingObjective
from penaltyrun.optim.lbfgs import (
    MAX_LOCAL_RUNS,
    NUDGES,
    LBFGSSettings,
    UnitCube,
    backtracking_run,
    local_run,
)

CENTRE = np.array([0.55, 0.5])
EDGE = 0.6  # no gradient where z[0] > EDGE


def _cost(Z):
    return np.sum((np.atleast_2d(Z) - CENTRE) ** 2, axis=1) + 1.0


def _gradient(z):
    if z[0] > EDGE:
        return SimpleNamespace(grad=None, reason="withheld")
    return SimpleNamespace(grad=2.0 * (np.asarray(z) - CENTRE), reason="")


def _counted(max_evals=10_000):
    return CountingObjective(_cost, max_evals=max_evals)


def test_the_first_trial_step_lands_where_no_gradient_exists():
    """The premise: one plain L-BFGS-B run from the corner ends at a withheld point."""
    cube = UnitCube(np.zeros(2), np.ones(2))
    run = local_run(_counted(), np.zeros(2), cube, _gradient, 1.0, LBFGSSettings())
    assert run.no_gradient and run.failed_at[0] > EDGE
    np.testing.assert_array_equal(run.anchor, np.zeros(2))


def test_backtracking_reaches_the_minimum_where_the_gradient_exists():
    cube = UnitCube(np.zeros(2), np.ones(2))
    counted = _counted()
    message, iterations = backtracking_run(counted, np.zeros(2), cube, _gradient, 1.0,
                                           LBFGSSettings())
    assert not message.startswith("no_gradient") and iterations > 0
    np.testing.assert_allclose(counted.best_z, CENTRE, atol=1e-7)
    assert counted.best_cost == pytest.approx(1.0, abs=1e-12)


def test_a_start_without_gradient_ends_after_its_nudges():
    cube = UnitCube(np.zeros(2), np.ones(2))
    counted = _counted()
    message, iterations = backtracking_run(counted, np.array([0.99, 0.5]), cube, _gradient,
                                           1.0, LBFGSSettings())
    assert message == "no_gradient: withheld" and iterations == 0
    tries = 1 + len(NUDGES)  # the start and each nudge: one value and one gradient each
    assert counted.n_evals == 2 * tries and counted.n_gradients == tries


def test_a_start_on_a_singular_edge_is_nudged_into_the_smooth_part():
    """The minimum lies next to the withheld part; a start just inside it is moved towards
    the centre (x: 0.605 → 0.5945 at the last nudge) and polished from there."""
    cube = UnitCube(np.zeros(2), np.ones(2))
    counted = _counted()
    message, _ = backtracking_run(counted, np.array([0.605, 0.5]), cube, _gradient, 1.0,
                                  LBFGSSettings())
    assert not message.startswith("no_gradient")
    np.testing.assert_allclose(counted.best_z, CENTRE, atol=1e-7)


def test_a_minimum_inside_the_withheld_part_stops_after_bounded_runs():
    """When the cost keeps falling into the withheld part, the trust region shrinks until
    it is below the floor or the runs are spent: the run ends, never loops."""
    cube = UnitCube(np.zeros(2), np.ones(2))
    counted = _counted()

    def withheld_beyond_half(z):
        if z[0] > 0.5:
            return SimpleNamespace(grad=None, reason="withheld")
        return SimpleNamespace(grad=2.0 * (np.asarray(z) - np.array([0.9, 0.5])), reason="")

    def cost(Z):
        return np.sum((np.atleast_2d(Z) - np.array([0.9, 0.5])) ** 2, axis=1)

    counted = CountingObjective(cost, max_evals=100_000)
    message, _ = backtracking_run(counted, np.zeros(2), cube, withheld_beyond_half, 1.0,
                                  LBFGSSettings())
    assert message.startswith("no_gradient")
    assert counted.n_gradients <= MAX_LOCAL_RUNS * 20 * LBFGSSettings().maxiter
    assert counted.best_z[0] >= 0.5 - 1e-6  # it went as far as the gradient allowed


def test_polish_records_how_it_ended_and_what_it_spent():
    lb, ub = np.zeros(2), np.ones(2)
    settings = optim.make_settings("pso", {"max_evals": 400, "polish": "gradient",
                                           "polish_share": 0.5, "grad_cost": 1.0,
                                           "n_particles": 4})
    res = optim.minimize("pso", _cost, lb, ub, settings, 5, gradient=_gradient)
    assert res.stop_reason.endswith("+polish")
    assert 0 < res.polish_evals <= res.n_evals <= 400
    np.testing.assert_allclose(res.best_z, CENTRE, atol=1e-6)

    def nowhere(z):
        return SimpleNamespace(grad=None, reason="never")

    res = optim.minimize("pso", _cost, lb, ub, settings, 5, gradient=nowhere)
    assert res.stop_reason.endswith("+polish:no_gradient")
    assert res.polish_evals == 2 * (1 + len(NUDGES))  # start and nudges: value + gradient
