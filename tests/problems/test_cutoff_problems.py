"""Exact cutoff of every built-in problem (``evaluate_batch(..., thresholds=...)``).

For every candidate and threshold: when the uncut cost exceeds the threshold, the cut result
does too (a cut one with status ``cutoff``, its cost a bound between the threshold and the
uncut cost); otherwise the result is the uncut one, bitwise.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun import problems
from penaltyrun.problems.base import CUTOFF_STATUS, accepts_thresholds
from penaltyrun.runner.setup import build_layout


def _candidates(prob, n, seed, param="full"):
    layout = build_layout(prob, param, {})
    lb, ub = layout.bounds()
    Z = lb + np.random.default_rng(seed).random((n, lb.size)) * (ub - lb)
    mats, scalars = layout.split(Z)
    return mats, scalars or None


def _thresholds(cost, seed):
    """Thresholds around each cost: below it, exactly at it, above it, and none (inf)."""
    rng = np.random.default_rng(seed)
    thr = cost * rng.uniform(0.0, 1.3, cost.size)
    thr[::5] = cost[::5]  # exactly the uncut cost: must not be cut
    thr[1::7] = np.inf
    return thr


def check_exact(prob, mats, scalars, thresholds, base=None):
    """Assert the cutoff contract on one batch; return the number of cut candidates."""
    base = base or prob.evaluate_batch(mats, scalars)
    cut = prob.evaluate_batch(mats, scalars, thresholds=thresholds)
    above = base.cost > thresholds
    assert np.array_equal(cut.cost > thresholds, above)
    stopped = cut.status == CUTOFF_STATUS
    assert not np.any(stopped & ~above)
    assert np.all(cut.cost[stopped] <= base.cost[stopped])
    assert not np.any(cut.converged[stopped])
    same = ~stopped
    assert np.array_equal(cut.cost[same], base.cost[same])
    assert np.array_equal(cut.status[same], base.status[same])
    assert np.array_equal(cut.converged[same], base.converged[same])
    return int(stopped.sum())


@pytest.mark.parametrize(("name", "case", "n"), [
    ("zermelo", "default", 150), ("attitude_lyapunov", "detumble", 150),
    ("attitude_lqr", "detumble", 100), ("qlaw", "C", 10), ("lyapunov_transfer", "C", 10),
])
def test_cutoff_is_exact(name, case, n):
    prob = problems.make(name, case, {})
    assert accepts_thresholds(prob)
    mats, scalars = _candidates(prob, n, 7)
    base = prob.evaluate_batch(mats, scalars)
    thr = _thresholds(base.cost, 8)
    assert check_exact(prob, mats, scalars, thr, base) > 0
    # Thresholds equal to the uncut costs cut nothing: the accumulated cost never overtakes
    # the final cost (J at the event, time of flight, or the failure penalty).
    assert check_exact(prob, mats, scalars, base.cost.copy(), base) == 0


def test_min_fuel_cutoff_on_propellant_with_eta_cut_scalars():
    prob = problems.make("qlaw", "A", {"objective": "min_fuel", "tof_cap_days": 40.0})
    mats, scalars = _candidates(prob, 6, 3, param="diagonal")
    assert set(scalars) == {"eta_cut"}
    base = prob.evaluate_batch(mats, scalars)
    thr = np.where(base.converged, 0.5 * base.cost, 0.5 * prob.params.m0_kg)
    assert check_exact(prob, mats, scalars, thr, base) > 0
    assert check_exact(prob, mats, scalars, base.cost.copy(), base) == 0


def test_lowthrust_thresholds_at_or_above_the_failure_base_never_cut():
    prob = problems.make("qlaw", "C", {})
    mats, scalars = _candidates(prob, 4, 5)
    base = prob.evaluate_batch(mats, scalars)
    thr = np.full(4, prob.params.tof_cap_days)
    res = prob.evaluate_batch(mats, scalars, thresholds=thr)
    assert not np.any(res.status == CUTOFF_STATUS)
    assert np.array_equal(res.cost, base.cost)


def test_lowthrust_negative_fail_weight_disables_the_cutoff():
    prob = problems.make("qlaw", "C", {"fail_weight": -1.0})
    mats, scalars = _candidates(prob, 3, 5)
    base = prob.evaluate_batch(mats, scalars)
    res = prob.evaluate_batch(mats, scalars, thresholds=np.zeros(3))
    assert np.array_equal(res.cost, base.cost) and not np.any(res.status == CUTOFF_STATUS)


def test_attitude_hard_failures_and_care_failures_are_never_cut():
    prob = problems.make("attitude_lqr", "detumble", {})
    mats, scalars = _candidates(prob, 20, 11)
    base = prob.evaluate_batch(mats, scalars)
    hard = 1000.0 * prob.params.failure_penalty
    res = prob.evaluate_batch(mats, scalars, thresholds=np.full(20, hard))
    assert np.array_equal(res.cost, base.cost)
    assert not np.any(res.status == CUTOFF_STATUS)


@settings(max_examples=40, deadline=None)
@given(k11=st.floats(0.01, 10.0), k22=st.floats(0.01, 10.0), corr=st.floats(-0.99, 0.99),
       frac=st.floats(0.0, 1.5))
def test_zermelo_cutoff_property(k11, k22, corr, frac):
    prob = problems.make("zermelo", "default", {})
    k12 = corr * np.sqrt(k11 * k22)
    mats = {"K": np.array([[[k11, k12], [k12, k22]]])}
    base = prob.evaluate_batch(mats)
    check_exact(prob, mats, None, frac * base.cost, base)


@pytest.mark.parametrize("aggregate", ["max", "mean"])
def test_multiscenario_passes_thresholds_only_for_the_max(aggregate):
    params = {"train_scenarios": [{}, {"x0": [3.0, -4.0]}], "train_aggregate": aggregate}
    prob = problems.make("zermelo", "default", params)
    assert accepts_thresholds(prob)
    mats, _ = _candidates(prob, 40, 2)
    base = prob.evaluate_batch(mats)
    thr = _thresholds(base.cost, 4)
    n_cut = check_exact(prob, mats, None, thr, base)
    assert (n_cut > 0) == (aggregate == "max")


def test_problems_without_the_keyword_are_detected():
    class Plain:
        def evaluate_batch(self, mats, scalars=None):
            return None

    class Keyword:
        def evaluate_batch(self, mats, scalars=None, *, thresholds=None):
            return None

    class Star:
        def evaluate_batch(self, mats, *args, **kwargs):
            return None

    assert not accepts_thresholds(Plain())
    assert accepts_thresholds(Keyword())
    assert not accepts_thresholds(Star())
    assert not accepts_thresholds(object())
