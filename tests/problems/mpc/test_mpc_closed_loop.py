"""The rendezvous MPC closed loop: the reference value, an independent dense reference
(closed-form model, scipy DARE, BVLS), solver-tolerance independence, scaling invariances,
the exact cutoff and the graded costs."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.problems.mpc import rendezvous as rz
from penaltyrun.problems.mpc.reference import reference_run

Q_REF = np.diag([1.0, 1, 1, 100, 100, 100])
R_REF = 1e4 * np.eye(3)


@pytest.fixture(scope="module")
def prob():
    return rz.make_problem("default", {})


def spd(rng, n, lo, hi):
    Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return Qo @ np.diag(np.exp(rng.uniform(np.log(lo), np.log(hi), n))) @ Qo.T


def reference(prob, Q, R, **kw):
    p = prob.params
    return reference_run(Q, R, prob.n, p.sample_time_s, p.horizon, p.u_max,
                         kw.get("s0", p.s0), p.n_steps, p.pos_tol_m, p.vel_tol_m_s,
                         kw.get("thrust_scale", 1.0))


def test_reference_value(prob):
    out = prob.evaluate({"Q": Q_REF, "R": R_REF})
    assert out["status"] == "converged" and out["converged"]
    assert out["delta_v"] == pytest.approx(10.42, abs=0.005)
    assert out["t_final"] == 820.0
    assert out["cost"] == out["delta_v"]


@pytest.mark.parametrize("seed", [1, 2])
def test_matches_independent_dense_reference(prob, seed):
    """Full (non-diagonal) weights with saturated phases: same inputs, states and Δv."""
    rng = np.random.default_rng(seed)
    Q = spd(rng, 6, 1e-3, 1e2)
    R = spd(rng, 3, 1e3, 1e4)
    ref = reference(prob, Q, R)
    sim = prob.simulate({"Q": Q, "R": R})
    out = prob.evaluate({"Q": Q, "R": R})
    assert np.any(np.isclose(np.abs(ref["inputs"]), prob.params.u_max, rtol=1e-9))
    assert out["converged"] == ref["converged"] and out["t_final"] == ref["t_final"]
    assert out["delta_v"] == pytest.approx(ref["delta_v"], rel=1e-9)
    np.testing.assert_allclose(sim["u"][:-1], ref["inputs"], rtol=0, atol=1e-11)
    np.testing.assert_allclose(sim["r"], ref["states"][:, :3], rtol=0, atol=1e-6)
    np.testing.assert_allclose(out["mpc_terminal_P"], ref["P"], rtol=1e-8,
                               atol=1e-10 * np.abs(ref["P"]).max())


def test_reference_value_matches_the_dense_reference(prob):
    ref = reference(prob, Q_REF, R_REF)
    out = prob.evaluate({"Q": Q_REF, "R": R_REF})
    assert ref["converged"] and ref["t_final"] == out["t_final"]
    assert out["delta_v"] == pytest.approx(ref["delta_v"], rel=1e-10)


@pytest.mark.parametrize("weights", ["reference", "random"])
def test_result_does_not_depend_on_solver_tolerances(weights):
    rng = np.random.default_rng(7)
    mats = {"Q": Q_REF, "R": R_REF} if weights == "reference" else \
        {"Q": spd(rng, 6, 1e-3, 1e2), "R": spd(rng, 3, 1e3, 1e4)}
    loose = rz.make_problem("default", {"qp_primal_tol": 1e-6, "qp_dual_tol": 1e-6})
    tight = rz.make_problem("default", {"qp_primal_tol": 1e-13, "qp_dual_tol": 1e-14})
    a, b = loose.evaluate(mats), tight.evaluate(mats)
    assert a["t_final"] == b["t_final"] and a["status"] == b["status"]
    assert abs(a["delta_v"] - b["delta_v"]) <= 1e-6 * b["delta_v"]


@pytest.mark.parametrize("c", [1e-3, 1e3])
def test_common_scaling_of_q_and_r_changes_nothing(prob, c):
    a = prob.evaluate({"Q": Q_REF, "R": R_REF})
    b = prob.evaluate({"Q": c * Q_REF, "R": c * R_REF})
    assert b["t_final"] == a["t_final"]
    assert b["delta_v"] == pytest.approx(a["delta_v"], rel=1e-9)


def test_scaled_case_is_the_same_mpc_in_normalized_coordinates(prob):
    scaled = rz.make_problem("scaled", {})
    sx = np.asarray(scaled.params.state_scale)
    su = np.asarray(scaled.params.input_scale)
    rng = np.random.default_rng(3)
    Q, R = spd(rng, 6, 1e-3, 1e2), spd(rng, 3, 1e3, 1e4)
    a = prob.evaluate({"Q": Q, "R": R})
    b = scaled.evaluate({"Q": sx[:, None] * Q * sx[None, :], "R": su[:, None] * R * su[None]})
    assert b["t_final"] == a["t_final"]
    assert b["delta_v"] == pytest.approx(a["delta_v"], rel=1e-9)


def test_batch_equals_single_evaluations(prob):
    rng = np.random.default_rng(11)
    Q = np.stack([Q_REF] + [spd(rng, 6, 1e-4, 1e2) for _ in range(3)])
    R = np.stack([R_REF] + [spd(rng, 3, 1e2, 1e4) for _ in range(3)])
    be = prob.evaluate_batch({"Q": Q, "R": R})
    for b in range(4):
        one = prob.evaluate({"Q": Q[b], "R": R[b]})
        assert be.cost[b] == one["cost"] and be.status[b] == one["status"]


def test_exact_cutoff(prob):
    rng = np.random.default_rng(5)
    Q = np.stack([spd(rng, 6, 1e-4, 1e2) for _ in range(4)])
    R = np.stack([spd(rng, 3, 1e2, 1e4) for _ in range(4)])
    full = prob.evaluate_batch({"Q": Q, "R": R})
    thr = np.array([full.cost[0] * 0.5, full.cost[1] * 2.0, math.inf, np.nan])
    cut = prob.evaluate_batch({"Q": Q, "R": R}, thresholds=thr)
    assert cut.status[0] == "cutoff" and thr[0] < cut.cost[0] <= full.cost[0]
    for b in (1, 2, 3):
        assert cut.cost[b] == full.cost[b] and cut.status[b] == full.status[b]


def test_not_converged_gets_the_graded_penalty():
    short = rz.make_problem("default", {"t_max": 400.0})
    out = short.evaluate({"Q": Q_REF, "R": R_REF})
    assert out["status"] == "horizon" and not out["converged"]
    sim = short.simulate({"Q": Q_REF, "R": R_REF})
    s_t = np.concatenate([sim["r"][-1], sim["v"][-1]])
    fp = short.params.failure_penalty
    expect = out["delta_v"] + fp * (1.0 + short.error(s_t) / short.error(short.params.s0))
    assert out["cost"] == pytest.approx(expect, rel=1e-12)
    # every failure costs more than any run that converges (Δv ≤ t_max · √3 · u_max)
    p = rz.Params()
    assert p.failure_penalty > p.t_max * math.sqrt(3.0) * p.u_max


def test_failure_penalty_grows_with_the_final_error():
    """Shorter time limits leave the chaser farther away: the graded cost is larger."""
    costs = []
    for t_max in (600.0, 400.0, 200.0):
        out = rz.make_problem("default", {"t_max": t_max}).evaluate({"Q": Q_REF, "R": R_REF})
        assert out["status"] == "horizon"
        costs.append(out["cost"] - out["delta_v"])
    assert costs[0] < costs[1] < costs[2]


def test_riccati_failure_is_a_recorded_status(prob):
    Q = np.stack([Q_REF, np.full((6, 6), np.nan)])
    be = prob.evaluate_batch({"Q": Q, "R": np.stack([R_REF, R_REF])})
    assert be.status.tolist() == ["converged", "dare_failure"]
    assert be.cost[1] == rz.HARD_FAILURE_FACTOR * prob.params.failure_penalty
    assert np.all(np.isfinite(be.cost))


def test_simulate_histories_are_consistent(prob):
    sim = prob.simulate({"Q": Q_REF, "R": R_REF})
    out = prob.evaluate({"Q": Q_REF, "R": R_REF})
    assert sim["t"][-1] == out["t_final"]
    assert sim["delta_v"][-1] == pytest.approx(out["delta_v"], rel=1e-12)
    assert np.all(np.abs(sim["u"]) <= prob.params.u_max)


def test_qp_failure_is_a_recorded_status():
    capped = rz.make_problem("default", {"qp_iter_limit": 1})
    out = capped.evaluate({"Q": Q_REF, "R": R_REF})
    assert out["status"] == "qp_failure" and not out["converged"]
    assert out["cost"] == rz.HARD_FAILURE_FACTOR * capped.params.failure_penalty


@settings(max_examples=10)
@given(st.floats(-6.0, 6.0), st.integers(0, 2**16))
def test_scaling_invariance_property(log_c, seed):
    prob = rz.make_problem("default", {"holdout_n_sphere": 0})
    rng = np.random.default_rng(seed)
    Q, R = spd(rng, 6, 1e-4, 1e2), spd(rng, 3, 1e2, 1e4)
    c = 10.0 ** log_c
    a = prob.evaluate_batch({"Q": np.stack([Q, c * Q]), "R": np.stack([R, c * R])})
    assert a.status[0] == a.status[1]
    assert a.cost[1] == pytest.approx(a.cost[0], rel=1e-8)
