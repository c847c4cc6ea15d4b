"""Grid optimizer: grid minima, local searches, dimension and budget checks."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.optim import GridSettings, check_dimension, make_settings
from penaltyrun.optim.grid import grid_minima, run_grid


def two_wells(Z):
    """Global minimum 0 at (0.7, 0.2), a local minimum 0.5 at (−0.6, −0.5)."""
    a = ((Z - [0.7, 0.2]) ** 2).sum(axis=1)
    b = ((Z - [-0.6, -0.5]) ** 2).sum(axis=1) + 0.5
    return np.minimum(a, b)


def test_grid_minima_on_a_hand_made_grid():
    cost = np.array([[5.0, 4.0, 5.0],
                     [3.0, 6.0, 1.0],
                     [2.0, 7.0, 8.0]])
    assert grid_minima(cost).tolist() == [5, 6]  # (1, 2) = 1.0, then (2, 0) = 2.0


def test_finds_the_global_minimum_off_the_grid():
    lb, ub = -np.ones(2), np.ones(2)
    res = run_grid(two_wells, lb, ub, GridSettings(points_per_dim=9, n_local=2), seed=0)
    assert res.best_cost < 1e-12
    np.testing.assert_allclose(res.best_z, [0.7, 0.2], atol=1e-6)
    assert res.n_evals > 81 and res.stop_reason == "grid+local"
    assert len(res.history) == 3  # after the grid, after each local search


def test_budget_cap_and_grid_size_check():
    lb, ub = -np.ones(2), np.ones(2)
    res = run_grid(two_wells, lb, ub, GridSettings(points_per_dim=9, max_evals=85), seed=0)
    assert res.n_evals == 85 and res.stop_reason == "max_evals"
    with pytest.raises(ConfigError) as info:
        check_dimension(GridSettings(points_per_dim=9, max_evals=50), 2)
    assert info.value.key == "optimizer.max_evals"


def test_dimension_above_four_is_refused():
    with pytest.raises(ConfigError) as info:
        check_dimension(make_settings("grid", {}), 5)
    assert "at most 4" in str(info.value)
    check_dimension(make_settings("grid", {}), 4)  # allowed


@pytest.mark.parametrize(("options", "key"), [
    ({"points_per_dim": 1}, "optimizer.points_per_dim"),
    ({"n_local": 0}, "optimizer.n_local"),
    ({"local_method": "none"}, "optimizer.local_method"),
])
def test_bad_settings_name_the_key(options, key):
    with pytest.raises(ConfigError) as info:
        make_settings("grid", options)
    assert info.value.key == key


def test_a_grid_too_large_for_memory_is_refused_naming_points_per_dim():
    """100 000 points per side in 3 variables: refused when built, not a MemoryError of
    the job."""
    with pytest.raises(ConfigError, match="1e\\+15 points is more than") as err:
        check_dimension(GridSettings(points_per_dim=100_000), 3)
    assert err.value.key == "optimizer.points_per_dim"
