"""The cliff probe against costs whose changes are known in closed form: a quadratic at its
minimum (change a·(h·w)²), a step at a known distance, a linear cost, the box's edges and a
change of convergence."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.optim.probe import CLIFF, NOISE, STEPS, probe

LB, UB = np.array([0.0, -2.0, 1.0]), np.array([10.0, 2.0, 5.0])
WIDTH = UB - LB


def quadratic(a, m, j0=1.0):
    def cost_batch(batch):
        return j0 + ((batch - m) ** 2 * a).sum(axis=1), np.ones(len(batch), bool)
    return cost_batch


def test_quadratic_at_its_minimum_changes_by_a_times_step_squared():
    a, m = np.array([1.0, 4.0, 0.5]), np.array([5.0, 0.0, 3.0])
    out = probe(quadratic(a, m), m, LB, UB)
    expected = a[None, :, None] * (np.asarray(STEPS)[:, None, None] * WIDTH[None, :, None]) ** 2
    # J(z) = 1: the change is rounded to about 1e-16 absolute
    np.testing.assert_allclose(out.change, np.repeat(expected, 2, axis=2), rtol=1e-6,
                               atol=1e-15)
    np.testing.assert_allclose(out.largest(), expected.max(axis=(1, 2)), rtol=1e-6)
    assert out.cost == 1.0 and out.converged and not out.status_change.any()
    assert out.lowest() == (0.0, pytest.approx(float("nan"), nan_ok=True))
    assert np.isnan(out.smallest_cliff_step())   # at most 4 * (1e-3 * 4)² = 6.4e-5 < 1 %


@pytest.mark.parametrize(("distance", "rung"), [(5e-6, 1e-5), (3e-5, 1e-4), (2e-3, None)])
def test_a_jump_is_found_at_the_first_step_that_reaches_it(distance, rung):
    z = np.array([4.0, 0.0, 2.0])

    def cost_batch(batch):  # +5 % once variable 0 has moved up by more than distance·width
        jump = batch[:, 0] > z[0] + distance * WIDTH[0]
        return 2.0 + 0.1 * jump, np.ones(len(batch), bool)

    out = probe(cost_batch, z, LB, UB)
    if rung is None:
        assert np.isnan(out.smallest_cliff_step()) and (out.largest() == 0).all()
        return
    assert out.smallest_cliff_step() == rung
    k = STEPS.index(rung)
    assert out.largest()[k] == pytest.approx(0.05) and out.worst_variable()[k] == 0
    assert (out.largest()[:k] == 0).all() and out.change[k, 0, 0] == 0.0


def test_steps_that_leave_the_box_are_not_taken():
    z = np.array([0.0, 2.0, 3.0])           # variable 0 on its lower, 1 on its upper bound
    calls = []

    def cost_batch(batch):
        calls.append(batch.copy())
        return 1.0 + batch.sum(axis=1) ** 2 * 1e-3, np.ones(len(batch), bool)

    out = probe(cost_batch, z, LB, UB)
    assert np.isnan(out.change[:, 0, 0]).all() and np.isnan(out.change[:, 1, 1]).all()
    assert np.isfinite(out.change[:, 0, 1]).all() and np.isfinite(out.change[:, 2]).all()
    (batch,) = calls                         # one batch: the point, then each step taken
    assert len(batch) == 1 + int(np.isfinite(out.change).sum())
    assert ((batch[1:] != z).sum(axis=1) == 1).all() and (batch[0] == z).all()
    assert ((batch >= LB) & (batch <= UB)).all()


def test_a_change_of_convergence_is_a_cliff_even_when_the_cost_barely_moves():
    z = np.array([4.0, 0.0, 2.0])

    def cost_batch(batch):
        return np.ones(len(batch)), batch[:, 2] < z[2] + 1e-4 * WIDTH[2] * 0.5

    out = probe(cost_batch, z, LB, UB)
    assert out.smallest_cliff_step() == 1e-4
    assert out.status_change[2, 2, 1] and out.status_change.sum() == 2  # 1e-4 and 1e-3, up


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-3, 3).filter(lambda v: v == 0 or abs(v) > 1e-3), min_size=3,
                max_size=3),
       st.lists(st.floats(0.1, 0.9), min_size=3, max_size=3))
def test_linear_cost_changes_by_slope_times_step(slope, where):
    g, z = np.asarray(slope), LB + WIDTH * np.asarray(where)

    def cost_batch(batch):
        return 100.0 + batch @ g, np.ones(len(batch), bool)

    out = probe(cost_batch, z, LB, UB)
    j0 = 100.0 + z @ g
    h = np.asarray(STEPS)[:, None] * WIDTH[None, :] * g[None, :] / abs(j0)
    np.testing.assert_allclose(out.change[..., 1], h, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(out.change[..., 0], -h, rtol=1e-6, atol=1e-12)
    assert np.all(np.diff(out.largest()) >= 0)
    low, step = out.lowest()
    if np.abs(g).max() > 0:
        assert low == pytest.approx(-out.largest()[-1]) and step == STEPS[-1]
    else:
        assert low == 0.0 and np.isnan(step)


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"steps": (1e-4, 1e-5)}, "increasing positive"),
    ({"steps": (0.0, 1e-5)}, "increasing positive"),
    ({"z": np.array([11.0, 0.0, 2.0])}, "outside the box"),
])
def test_bad_arguments_are_refused(kwargs, words):
    args = {"z": np.array([4.0, 0.0, 2.0]), **kwargs}
    with pytest.raises(ValueError, match=words):
        probe(quadratic(np.ones(3), np.zeros(3)), lb=LB, ub=UB, **args)


def test_zero_cost_is_refused():
    with pytest.raises(ValueError, match="cost at z is 0"):
        probe(quadratic(np.ones(3), np.array([4.0, 0.0, 2.0]), j0=0.0),
              np.array([4.0, 0.0, 2.0]), LB, UB)


def test_threshold_is_one_percent():
    assert CLIFF == 0.01


def test_a_fall_within_the_noise_is_not_a_lower_cost():
    z = np.array([4.0, 0.0, 2.0])

    def cost_batch(batch, fall=0.0):
        moved = (batch != z).any(axis=1)
        return 3.0 * (1.0 - fall * moved), np.ones(len(batch), bool)

    assert probe(lambda b: cost_batch(b, NOISE / 2), z, LB, UB).lowest()[0] == 0.0
    low, step = probe(lambda b: cost_batch(b, 10 * NOISE), z, LB, UB).lowest()
    assert low == pytest.approx(-10 * NOISE) and step == STEPS[0]
