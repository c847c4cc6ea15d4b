"""PSO adapter (pyswarms), the counting wrapper and optimizer settings validation."""

from __future__ import annotations

import logging
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from batched_objectives import CENTER, LB, UB, Recorder, sphere

from penaltyrun.errors import ConfigError
from penaltyrun.optim import (
    OPTIMIZERS,
    BaselineSettings,
    DESettings,
    PSOSettings,
    make_settings,
    minimize,
)
from penaltyrun.optim.base import CountingObjective
from penaltyrun.optim.pso import run_pso


def test_finds_minimum_of_sphere():
    res = run_pso(sphere, LB, UB, PSOSettings(n_particles=20, iters=200), seed=1)
    assert res.best_cost < 1e-6
    np.testing.assert_allclose(res.best_z, CENTER, atol=1e-2)
    assert res.best_cost == pytest.approx(float(sphere(res.best_z[None])[0]), abs=1e-12)
    assert res.history[-1] == pytest.approx(res.best_cost)
    assert np.all(np.diff(res.history) <= 0)  # global best never gets worse
    assert res.n_nonfinite == 0


def test_same_seed_identical_different_seed_differs():
    s = PSOSettings(n_particles=10, iters=30, ftol=0.0)
    a = run_pso(sphere, LB, UB, s, seed=42)
    b = run_pso(sphere, LB, UB, s, seed=42)
    c = run_pso(sphere, LB, UB, s, seed=43)
    assert a.history == b.history
    np.testing.assert_array_equal(a.best_z, b.best_z)
    assert a.best_cost == b.best_cost
    assert a.history != c.history
    assert not np.array_equal(a.best_z, c.best_z)


def test_seed_is_independent_of_prior_global_state():
    s = PSOSettings(n_particles=10, iters=10)
    np.random.seed(0)  # noqa: NPY002
    a = run_pso(sphere, LB, UB, s, seed=5)
    np.random.seed(999)  # noqa: NPY002
    np.random.random(17)  # noqa: NPY002
    b = run_pso(sphere, LB, UB, s, seed=5)
    assert a.history == b.history


def test_large_seed_is_accepted():
    res = run_pso(sphere, LB, UB, PSOSettings(n_particles=5, iters=3), seed=2**40 + 3)
    assert res.n_iters == 3


def test_whole_swarm_once_per_iteration_and_eval_count():
    rec = Recorder(sphere)
    s = PSOSettings(n_particles=12, iters=25, ftol=0.0)
    res = run_pso(rec, LB, UB, s, seed=0)
    assert len(rec.batches) == res.n_iters == 25
    assert all(Z.shape == (12, 3) for Z in rec.batches)
    assert res.n_evals == 12 * res.n_iters == sum(len(Z) for Z in rec.batches)
    assert len(res.history) == res.n_iters
    assert res.stop_reason == "iters"


def test_positions_clamped_inside_bounds():
    """The optimum lies outside the box: particles press on the bounds and are clamped."""
    target = np.array([5.0, -5.0, 0.2])
    rec = Recorder(lambda Z: ((Z - target) ** 2).sum(axis=1))
    lb, ub = np.array([-1.0, -2.0, 0.0]), np.array([1.0, 2.0, 0.5])
    res = run_pso(rec, lb, ub, PSOSettings(n_particles=15, iters=60, ftol=0.0), seed=3)
    allZ = np.concatenate(rec.batches)
    assert np.all(allZ >= lb) and np.all(allZ <= ub)
    # clamping ('nearest') puts particles exactly on the bound, wrapping would not
    assert np.any(allZ[:, 0] == ub[0]) and np.any(allZ[:, 1] == lb[1])
    np.testing.assert_allclose(res.best_z[:2], [1.0, -2.0], atol=1e-9)
    assert lb[2] <= res.best_z[2] <= ub[2]


def test_default_boundary_strategy_is_nearest():
    assert PSOSettings().bh_strategy == "nearest"
    assert make_settings("pso", {}).bh_strategy == "nearest"


def test_stall_rule_stops_early_on_flat_function():
    rec = Recorder(lambda Z: np.ones(len(Z)))
    res = run_pso(rec, LB, UB, PSOSettings(n_particles=8, iters=100, ftol_iter=5), seed=0)
    assert res.stop_reason == "ftol"
    assert res.n_iters < 100
    assert res.n_iters == 6  # first iteration sets the best, then 5 stalled ones
    assert res.n_evals == 8 * res.n_iters
    assert len(rec.batches) == res.n_iters
    assert res.best_cost == 1.0


def test_nonfinite_costs_replaced_and_counted():
    def nasty(Z):
        cost = sphere(Z)
        cost[Z[:, 0] > 0.5] = np.nan
        cost[Z[:, 1] > 0.8] = np.inf
        return cost

    res = run_pso(nasty, LB, UB, PSOSettings(n_particles=20, iters=30, ftol=0.0), seed=2)
    assert res.n_nonfinite > 0
    assert np.isfinite(res.best_cost)
    assert all(np.isfinite(res.history))
    assert res.best_cost < 0.05
    assert res.best_z[0] <= 0.5 and res.best_z[1] <= 0.8


def test_counting_objective_unit():
    counted = CountingObjective(lambda Z: np.array([1.0, np.nan, np.inf, -np.inf])[: len(Z)],
                                nonfinite_cost=7.0)
    out = counted(np.zeros((4, 2)))
    np.testing.assert_array_equal(out, [1.0, 7.0, 7.0, 7.0])
    assert counted.n_evals == 4 and counted.n_nonfinite == 3
    out = counted(np.zeros(2))  # a single vector is a batch of one
    np.testing.assert_array_equal(out, [1.0])
    assert counted.n_evals == 5 and counted.n_nonfinite == 3


def test_no_report_log_and_root_logger_untouched(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    res = run_pso(sphere, LB, UB, PSOSettings(n_particles=5, iters=5), seed=0)
    assert res.n_iters == 5
    assert root.handlers == handlers
    assert root.level == level
    assert not (tmp_path / "report.log").exists()
    assert list(tmp_path.iterdir()) == []


def test_import_and_run_in_fresh_process_leave_logging_and_cwd_clean(tmp_path):
    """pyswarms configures logging at import time: check a pristine interpreter."""
    code = textwrap.dedent("""
        import logging
        import numpy as np
        before = list(logging.getLogger().handlers)
        level = logging.getLogger().level
        from penaltyrun.optim.pso import PSOSettings, run_pso
        run_pso(lambda Z: (Z ** 2).sum(1), -np.ones(2), np.ones(2),
                PSOSettings(n_particles=4, iters=3), seed=0)
        assert logging.getLogger().handlers == before, logging.getLogger().handlers
        assert logging.getLogger().level == level
        print("OK")
    """)
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "OK"
    assert not (tmp_path / "report.log").exists()


# --------------------------------------------------------------------------- settings


def test_make_settings_valid():
    s = make_settings("pso", {"n_particles": 10, "iters": 5, "c1": 2.0, "bh_strategy": "random"})
    assert isinstance(s, PSOSettings)
    assert (s.n_particles, s.iters, s.c1, s.bh_strategy) == (10, 5, 2.0, "random")
    d = make_settings("de", {"popsize": 4, "mutation": [0.4, 0.9]})
    assert isinstance(d, DESettings)
    assert d.mutation == (0.4, 0.9)  # YAML lists become tuples (hashable, frozen)
    assert isinstance(make_settings("baseline", {"scale": 2.0}), BaselineSettings)


def test_make_settings_unknown_optimizer():
    with pytest.raises(ConfigError) as info:
        make_settings("nelder", {})
    assert info.value.key == "optimizer.name"
    assert set(info.value.allowed) == set(OPTIMIZERS)
    for name in ("pso", "de"):
        assert name in str(info.value)


def test_make_settings_unknown_option():
    with pytest.raises(ConfigError) as info:
        make_settings("pso", {"n_particles": 10, "swarmsize": 3})
    assert info.value.key == "optimizer.swarmsize"
    assert "n_particles" in info.value.allowed
    assert "popsize" not in info.value.allowed
    with pytest.raises(ConfigError):
        make_settings("de", {"n_particles": 10})


@pytest.mark.parametrize("name,key,value", [
    ("pso", "n_particles", 0), ("pso", "iters", -1), ("pso", "iters", 2.5),
    ("pso", "ftol_iter", 0), ("de", "popsize", 0), ("de", "iters", "10"),
])
def test_make_settings_bad_budget(name, key, value):
    with pytest.raises(ConfigError) as info:
        make_settings(name, {key: value})
    assert info.value.key == f"optimizer.{key}"


def test_make_settings_bad_boundary_strategy():
    with pytest.raises(ConfigError) as info:
        make_settings("pso", {"bh_strategy": "wrap"})
    assert info.value.key == "optimizer.bh_strategy"
    assert "nearest" in info.value.allowed


def test_minimize_dispatch_and_baseline():
    res = minimize("pso", sphere, LB, UB, PSOSettings(n_particles=6, iters=4, ftol=0.0), 0)
    assert res.n_evals == 24
    base = minimize("baseline", sphere, LB, UB, BaselineSettings(), 0, x0=CENTER)
    assert base.best_cost == 0.0 and base.n_evals == 1 and base.stop_reason == "baseline"
    np.testing.assert_array_equal(base.best_z, CENTER)
    with pytest.raises(ValueError, match="x0"):
        minimize("baseline", sphere, LB, UB, BaselineSettings(), 0)
