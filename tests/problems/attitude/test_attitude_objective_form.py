"""The companion study's objective form (``objective_form: neg_reciprocal``): −1/J for
converged candidates, the final error d − tol otherwise; records keep J; the exact cutoff
stays exact; MATLAB's stall test on −1/J stops a seeded run where predicted."""

from __future__ import annotations

from importlib.resources import files
from types import SimpleNamespace

import numpy as np
import pytest
from omegaconf import OmegaConf

from penaltyrun import optim
from penaltyrun.dynamics import integrate
from penaltyrun.errors import ConfigError
from penaltyrun.optim.pso_matlab import stalled
from penaltyrun.problems import make
from penaltyrun.problems.attitude.objective import cost_thresholds, optimizer_values
from penaltyrun.runner.job import _objective
from penaltyrun.runner.plan import plan_jobs
from penaltyrun.runner.setup import build_layout
from penaltyrun.runner.swarm import LocalEvaluation

CASE = "schaub_detumble"
ROOT_SEED = OmegaConf.load(files("penaltyrun") / "conf" / "config.yaml").runner.seed


def _batch(n=24, seed=0):
    """Random diagonal gains in the companion box [1e-8, 20] (about half converge)."""
    rng = np.random.default_rng(seed)
    kp, kd = rng.uniform(1e-8, 20.0, (2, n, 3))
    kp[0], kd[0] = (0.26617752, 0.34685239, 0.20612607), (4.43098254, 6.56962029, 5.39346573)
    return {"Kp": np.stack([np.diag(r) for r in kp]), "Kd": np.stack([np.diag(r) for r in kd])}


def test_on_by_default_in_the_companion_presets_only():
    for case in ("schaub_detumble", "schaub_detumble_sat"):
        assert make("attitude_lyapunov", case).params.objective_form == "neg_reciprocal"
        assert make("attitude_lqr", case).params.objective_form == "neg_reciprocal"
    assert make("attitude_lyapunov", "detumble").params.objective_form == "cost"
    assert make("attitude_lyapunov", CASE, {"objective_form": "cost"}).params.objective_form \
        == "cost"
    with pytest.raises(ConfigError, match="objective_form"):
        make("attitude_lyapunov", CASE, {"objective_form": "reciprocal"})
    with pytest.raises(ConfigError, match="objective_form"):
        make("attitude_lyapunov", CASE, {"train_scenarios": [{}],
                                         "objective_form": "neg_reciprocal"})
    multi = make("attitude_lyapunov", CASE, {"train_scenarios": [{}, {"t_max": 300.0}]})
    assert multi.base.params.objective_form == "cost"
    assert all(p.params.objective_form == "cost" for p in multi.scenarios)


def test_values_are_the_authors_and_costs_are_unchanged():
    mats = _batch()
    rec = make("attitude_lyapunov", CASE).evaluate_batch(mats)
    plain = make("attitude_lyapunov", CASE, {"objective_form": "cost"}).evaluate_batch(mats)
    assert plain.objective is None
    np.testing.assert_array_equal(rec.cost, plain.cost)
    conv = rec.converged
    assert 3 <= conv.sum() <= len(conv) - 3, "need converged and failed candidates"
    np.testing.assert_array_equal(rec.objective[conv], -1.0 / rec.cost[conv])
    assert np.all(rec.objective[conv] < 0) and np.all(rec.objective[~conv] > 0)
    i = int(np.flatnonzero(~conv)[0])
    detail = make("attitude_lyapunov", CASE).evaluate({"Kp": mats["Kp"][i],
                                                       "Kd": mats["Kd"][i]})
    assert not detail["converged"]
    assert detail["objective"] == pytest.approx(detail["final_distance"] - 1e-3, rel=1e-12)
    assert detail["objective_form"] == "neg_reciprocal" and detail["cost"] > 1000.0


def test_same_ordering_of_converged_candidates():
    rec = make("attitude_lyapunov", CASE).evaluate_batch(_batch(seed=1))
    conv = rec.converged
    order_cost = np.argsort(rec.cost[conv], kind="stable")
    order_value = np.argsort(rec.objective[conv], kind="stable")
    np.testing.assert_array_equal(order_cost, order_value)
    assert rec.objective[conv].max() < rec.objective[~conv].min()


def test_hard_failures_rank_last():
    status = np.array([integrate.EVENT, integrate.HORIZON, integrate.NONFINITE])
    cost = np.array([90.0, 1500.0, 1e6])
    out = optimizer_values("neg_reciprocal", cost, np.array([90.0, 500.0, np.nan]),
                           np.array([1e-3, 0.5, np.nan]), 1e-3, status, np.ones(3, bool))
    np.testing.assert_allclose(out, [-1 / 90.0, 0.499, 1e6])
    assert optimizer_values("cost", cost, cost, cost, 1e-3, status, np.ones(3, bool)) is None


def test_thresholds_convert_to_energy():
    thr = np.array([-0.01, -1.0 / 95.0, 0.3, 0.0, np.inf, np.nan])
    out = cost_thresholds("neg_reciprocal", thr)
    np.testing.assert_allclose(out[:2], [100.0, 95.0])
    assert np.all(np.isinf(out[2:5])) and np.isnan(out[5])
    np.testing.assert_array_equal(cost_thresholds("cost", thr), thr)


def test_cut_values_lie_between_threshold_and_value():
    prob = make("attitude_lyapunov", CASE)
    mats = _batch(seed=2)
    full = prob.evaluate_batch(mats)
    best = float(full.objective.min())  # the best converged candidate's −1/J
    cut = prob.evaluate_batch(mats, thresholds=np.full(full.cost.size, best))
    was_cut = cut.status == "cutoff"
    assert was_cut.sum() >= 3
    assert np.all(cut.objective[was_cut] > best)
    assert np.all(cut.objective[was_cut] <= full.objective[was_cut])
    np.testing.assert_array_equal(cut.objective[~was_cut], full.objective[~was_cut])
    np.testing.assert_array_equal(cut.cost[~was_cut], full.cost[~was_cut])


def _run(cutoff, form, settings, seed=7):
    prob = make("attitude_lyapunov", CASE, {"objective_form": form})
    layout = build_layout(prob, "diagonal", {})
    lb, ub = layout.bounds()
    opts = optim.make_settings("pso_matlab", settings)
    objective = _objective(LocalEvaluation(), SimpleNamespace(job_id="t", cutoff=cutoff), prob,
                           layout, "diagonal", opts)
    return optim.minimize("pso_matlab", objective, lb, ub, opts, seed), objective


def test_cutoff_leaves_the_neg_reciprocal_run_unchanged():
    settings = {"swarm_size": 10, "max_iterations": 8}
    off, beat_off = _run(False, "neg_reciprocal", settings)
    on, beat_on = _run(True, "neg_reciprocal", settings)
    assert beat_off.n_cutoff == 0 and beat_on.n_cutoff > 0
    assert (on.best_cost, on.history, on.trace_best, on.n_evals) == \
        (off.best_cost, off.history, off.trace_best, off.n_evals)
    assert np.array_equal(on.best_z, off.best_z)
    assert off.best_cost > 0 and all(h > 0 for h in off.history)  # J, not −1/J


def test_seeded_run_stops_where_the_stall_test_on_neg_reciprocal_predicts():
    """MATLAB's test allows a change of 1e-6·max(1, |f|): absolute on −1/J (J > 1). The run
    stops at the first iteration k > W where its own best J's give |Δ(−1/J)| ≤ 1e-6, and
    spends S·(k + 1) evaluations; the same seed under J stops later (relative test)."""
    settings = {"swarm_size": 12, "max_iterations": 400}
    rec, _ = _run(True, "neg_reciprocal", settings)
    plain, _ = _run(True, "cost", settings)
    bests = [rec.trace_best[0]] + rec.history  # J after the initial swarm, then per iteration
    assert len(bests) == rec.n_iters + 1
    values = [-1.0 / b for b in bests]
    predicted = next(k for k in range(1, len(values))
                     if stalled(values[:k + 1], 20, 1e-6, "code"))
    assert rec.stop_reason == "ftol" and rec.n_iters == predicted
    assert rec.n_evals == 12 * (predicted + 1)
    assert not any(stalled(bests[:k + 1], 20, 1e-6, "code") for k in range(len(bests)))
    assert plain.n_evals > rec.n_evals


@pytest.mark.slow
def test_companion_diagonal_cell_spends_the_authors_evaluations():
    """Issue acceptance: with their objective form, MATLAB defaults (swarm 60, stall 1e-6
    over 20) and the study's 20 starts, seeded as the runner seeds them from its default
    root seed, the median evaluation count is within a factor 1.5 of the authors' 12 450
    (their range 4 560–35 160). (Under J the same cell spent about twice theirs; the
    seeded short run above shows the direction.)"""
    jobs = plan_jobs("attitude_lyapunov", CASE, "diagonal", "pso_matlab", n_starts=20,
                     root_seed=ROOT_SEED)
    runs = [_run(True, "neg_reciprocal", {}, seed=job.seed)[0] for job in jobs]
    assert all(r.stop_reason == "ftol" for r in runs)
    median = float(np.median([r.n_evals for r in runs]))
    assert 12450 / 1.5 <= median <= 12450 * 1.5


class _SyncEvaluation:
    """Stands in for a DaskEvaluation: chunks run at once in this process."""

    auto = False
    client = SimpleNamespace(submit=lambda fn, *args, pure=False: fn(*args))

    def chunk_cap(self):
        return 3

    def gather(self, futures):
        return futures


def test_swarm_level_chunks_keep_the_objective_values():
    pytest.importorskip("distributed")
    from penaltyrun.runner import swarm
    from penaltyrun.runner.dask_swarm import DaskBatch

    spec = swarm.ProblemSpec("attitude_lyapunov", CASE, "diagonal")
    prob, layout = spec.build()
    lb, ub = layout.bounds()
    Z = lb + np.random.default_rng(4).random((7, lb.size)) * (ub - lb)
    whole = prob.evaluate_batch(*layout.split(Z))
    swarm.register(spec)
    try:
        got = DaskBatch(_SyncEvaluation(), spec.key)(Z)
    finally:
        swarm.forget(spec.key)
    np.testing.assert_array_equal(got.cost, whole.cost)
    np.testing.assert_array_equal(got.objective, whole.objective)
    assert list(got.status) == list(whole.status)
