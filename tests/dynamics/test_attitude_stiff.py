"""Attitude kernels: the divergence guard and the stiff (RODAS4) path.

References: the kernel without the guard (same arithmetic, so ordinary runs must be
bitwise identical), DOP853 for every run (``stiff_rate=inf``), and scipy ``solve_ivp``
(Radau, rtol = atol = 1e-12, with the guard as a second terminal event).
"""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.dynamics import attitude as at
from penaltyrun.dynamics import integrate
from penaltyrun.problems.attitude import lqr, lyapunov
from penaltyrun.problems.attitude.reference import graded_cost, reference_run

#: Gains of near-best attitude LQR candidates (rest-to-rest, detumble) that blow up: the
#: first is on the DOP853 path (stiffness ≈ 13 1/s), the second on the RODAS4 path (≈ 2 400).
DIVERGING = {
    "rest_to_rest": np.array([
        [18.952894767357, 28.838883188178, 2.863144608286, 38.344457377104, 29.113478043214,
         16.750538556086],
        [-12.549970157572, -18.662109745859, -2.084044996802, -24.862856913442,
         -15.964314627667, -11.976355208003],
        [-33.835969539581, -51.911567923472, -4.846774665471, -66.739906460493,
         -52.316269381067, -27.662998535116]]),
    "detumble": np.array([
        [-820.788751099068, 111.139355638654, -1320.310282118373, 3805.666608551843,
         -562.673037043762, -691.333300196174],
        [3999.522506878979, -542.26238942631, 6432.214105098431, -18525.307860339846,
         2736.8964877684, 3375.013314838814],
        [4212.707754639036, -571.280893861084, 6774.942440289917, -19510.813074289657,
         2881.217778247858, 3556.774957339003]]),
}


def _stiffness(prob, G):
    p = np.empty(at.N_PRM)
    at.pack_params(prob.inertia, prob.inertia_inv, G, prob.params.saturation(), 1e-4, p)
    return at.stiffness(p)


def _batch(prob, G, stiff_rate=at.STIFF_RATE, tol=None):
    p = prob.params
    rtol = p.rtol if tol is None else tol
    return at.simulate_batch(np.ascontiguousarray(G), prob.y0[None], prob.inertia,
                             prob.inertia_inv, p.t_max, p.tol, p.saturation(), rtol,
                             rtol, p.max_step, p.event_spacing, p.n_event_samples,
                             p.max_steps, *p.event_weights(), None, stiff_rate)


def _stiff_gains(case, n, seed, overrides=None):
    """LQR gains with R near the lower eigenvalue bound (stiffness bounds ~ 500–2 500 1/s)."""
    prob = lqr.make_problem(case, overrides or {})
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, 6, 6))
    Q = M @ np.swapaxes(M, 1, 2) / 6 + 0.1 * np.eye(6)
    R = np.eye(3) * rng.uniform(0.5, 2.0, (n, 1, 3)) * 10.0 ** rng.uniform(-8, -7, (n, 1, 1))
    G, ok = prob.gains({"Q": Q, "R": R})
    assert ok.all()
    return prob, G


@pytest.mark.parametrize("case", sorted(DIVERGING))
def test_guard_stops_a_diverging_gain(case):
    prob = lqr.make_problem(case, {})
    G = DIVERGING[case]
    assert (_stiffness(prob, G) > at.STIFF_RATE) == (case == "detumble")
    t, energy, dist, status = _batch(prob, G[None])
    assert status[0] == integrate.DIVERGED and t[0] < prob.params.t_max
    _, y_end, st = at.final_state(G, prob.y0, prob.inertia, prob.inertia_inv,
                                  prob.params.t_max, prob.params.tol, np.inf, prob.params.rtol,
                                  prob.params.atol, prob.params.max_step,
                                  prob.params.event_spacing, prob.params.n_event_samples,
                                  prob.params.max_steps)
    assert st == integrate.DIVERGED
    assert np.linalg.norm(y_end[4:7]) > at.omega_bound(prob.y0) == at.OMEGA_GUARD_MIN
    # graded penalty: above failure_penalty, the formula of the other failures
    res = prob._finish(G[None], np.ones(1, bool), None, prob.d0)
    fp = prob.params.failure_penalty
    assert res["status"][0] == "diverged" and not res["converged"][0]
    expected = graded_cost(energy, dist, prob.d0, status, fp)[0]
    assert res["cost"][0] == expected == energy[0] + fp * (1 + dist[0] / prob.d0)
    assert res["cost"][0] > fp
    # independent reference: the same status, the bound crossed at about the same time
    ref = reference_run(G, prob.params, method="Radau", rtol=1e-10, atol=1e-10)
    assert ref["status"] == integrate.DIVERGED and ref["cost"] > fp
    assert ref["t_final"] <= t[0] + 1e-6 and t[0] - ref["t_final"] < 0.05


def test_guard_leaves_ordinary_candidates_unchanged():
    """Random full LQR and PD candidates, both cases: the guarded kernel's results are
    bitwise those of the same kernel without the guard (bound ``inf``)."""
    rng = np.random.default_rng(11)
    for module in (lqr, lyapunov):
        for case in ("detumble", "rest_to_rest"):
            prob = module.make_problem(case, {})
            mats = {}
            for spec in prob.matrices:
                M = rng.standard_normal((40, spec.size, spec.size))
                lam = rng.uniform(1e-3, 10.0, (40, spec.size))
                Qo, _ = np.linalg.qr(M)
                mats[spec.name] = Qo @ (lam[:, :, None] * np.swapaxes(Qo, 1, 2))
            G, ok = prob.gains(mats)
            G = np.ascontiguousarray(G[ok])
            t, energy, dist, status = _batch(prob, G, stiff_rate=np.inf)
            assert not np.any(status == integrate.DIVERGED)
            p = prob.params
            pv = np.empty(at.N_PRM)
            y = np.zeros(at.N_STATE)
            y[:7] = prob.y0
            for b in range(len(G)):
                at.pack_params(prob.inertia, prob.inertia_inv, G[b], p.saturation(), p.tol, pv,
                               *p.event_weights())  # no guard
                t_b, y_b, st_b, _ = at._integrate(y, pv, p.t_max, p.rtol, p.atol, p.max_step,
                                                  p.event_spacing, p.n_event_samples,
                                                  p.max_steps)
                assert (t_b, y_b[7], st_b) == (t[b], energy[b], status[b])


@pytest.mark.parametrize("case", ["detumble", "rest_to_rest"])
def test_stiff_path_matches_dop853(case):
    """Stiff candidates: RODAS4 and DOP853 (both at the problem's tolerances) give the same
    statuses and costs to 1e-8; the non-stiff ones stay on DOP853 bitwise."""
    prob, G = _stiff_gains(case, 12, 4)
    rho = np.array([_stiffness(prob, g) for g in G])
    assert np.sum(rho > at.STIFF_RATE) >= 6
    t_a, e_a, d_a, s_a = _batch(prob, G)
    t_b, e_b, d_b, s_b = _batch(prob, G, stiff_rate=np.inf)
    np.testing.assert_array_equal(s_a, s_b)
    fp = prob.params.failure_penalty
    c_a = graded_cost(e_a, d_a, prob.d0, s_a, fp)
    c_b = graded_cost(e_b, d_b, prob.d0, s_b, fp)
    np.testing.assert_allclose(c_a, c_b, rtol=1e-8)
    easy = rho <= at.STIFF_RATE
    np.testing.assert_array_equal(c_a[easy], c_b[easy])


def test_stiff_path_cutoff():
    prob, G = _stiff_gains("rest_to_rest", 4, 4)
    G = G[[_stiffness(prob, g) > at.STIFF_RATE for g in G]][:1]
    _, energy, _, status = _batch(prob, G)
    cut = 0.5 * energy
    p = prob.params
    t_c, e_c, _, s_c = at.simulate_batch(G, prob.y0[None], prob.inertia, prob.inertia_inv,
                                         p.t_max, p.tol, np.inf, p.rtol, p.atol, p.max_step,
                                         p.event_spacing, p.n_event_samples, p.max_steps,
                                         1.0, 1.0, 1.0, cut)
    assert s_c[0] == integrate.CUTOFF and cut[0] < e_c[0] <= energy[0] * (1 + 1e-10)


def _against_radau(case, n, seed, overrides=None):
    prob, G = _stiff_gains(case, n, seed, overrides)
    G = G[[_stiffness(prob, g) > at.STIFF_RATE for g in G]]
    assert len(G)
    fp = prob.params.failure_penalty
    t, e, d, s = _batch(prob, G)
    cost = graded_cost(e, d, prob.d0, s, fp)
    t_tight, _, _, s_tight = _batch(prob, G, tol=1e-12)
    for b in range(len(G)):
        ref = reference_run(G[b], prob.params, method="Radau", rtol=1e-12, atol=1e-12)
        assert s[b] == s_tight[b] == ref["status"]
        assert cost[b] == pytest.approx(ref["cost"], rel=1e-8)
        assert t_tight[b] == pytest.approx(ref["t_final"], abs=1e-6)


def test_stiff_path_matches_radau():
    """Costs (problem tolerances) to 1e-8, identical statuses and event times to 1e-6 s
    (kernel at 1e-12) against scipy Radau at rtol = atol = 1e-12: a stiff rest-to-rest
    candidate that converges at 26 s, and the same with t_max = 20 s (it fails)."""
    _against_radau("rest_to_rest", 2, 4)
    _against_radau("rest_to_rest", 2, 4, {"t_max": 20.0})


@pytest.mark.slow
@pytest.mark.parametrize("case", ["detumble", "rest_to_rest"])
@pytest.mark.parametrize("t_max", [100.0, 30.0])
def test_stiff_path_matches_radau_many(case, t_max):
    _against_radau(case, 12, 7, {"t_max": t_max})
