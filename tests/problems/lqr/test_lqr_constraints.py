"""Settling time, overshoot and disk margin of problem=lqr (penaltyrun/problems/lqr/margins.py
and constraints.py) against python-control's step_info and disk_margins, and the graded
'constraint' status."""

import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import margins

control = pytest.importorskip("control")

OSC = {"A": [[0.0, 1.0], [-1.0, 0.1]], "B": [[0.0], [1.0]], "x0": [[1.0, 0.0], [0.3, -1.0]],
       "t_max": 25.0}


def test_siso_disk_margin_matches_python_control():
    rng = np.random.default_rng(3)
    for dt in (None, 0.2):
        A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 1))
        if dt:
            A = 0.6 * A / np.max(np.abs(np.linalg.eigvals(A))) + 0.5 * np.eye(3)
        K = (control.dlqr if dt else control.lqr)(A, B, np.eye(3), np.eye(1))[0]
        omega = margins.frequency_grid(A, dt, 300)
        ours = margins.disk_margin_curve(A, B, K[None], omega, dt)[0]
        L = control.ss(A, B, K, 0, dt) if dt else control.ss(A, B, K, 0)
        ref = control.disk_margins(L, omega, skew=0.0, returnall=True)[0]
        np.testing.assert_allclose(ours, ref, rtol=1e-9)
        dm, dgm, dpm = control.disk_margins(L, omega, skew=0.0)
        assert ours.min() == pytest.approx(dm, rel=1e-9)
        gain, phase = margins.disk_gain_phase(float(ours.min()))
        assert gain == pytest.approx(dgm, rel=1e-9) and phase == pytest.approx(dpm, rel=1e-9)


def test_mimo_disk_margin_is_the_unstructured_bound():
    rng = np.random.default_rng(4)
    A, B = rng.normal(size=(4, 4)), rng.normal(size=(4, 2))
    K = control.lqr(A, B, np.eye(4), np.eye(2))[0]
    omega = margins.frequency_grid(A, None, 120)
    ours = margins.disk_margin_curve(A, B, K[None], omega)[0]
    S = control.feedback(control.ss([], [], [], np.eye(2)), control.ss(A, B, K, 0))
    resp = S.frequency_response(omega)
    Sjw = np.moveaxis(resp.magnitude * np.exp(1j * resp.phase), 2, 0)
    ref = 1.0 / np.linalg.svd(Sjw - 0.5 * np.eye(2), compute_uv=False)[:, 0]
    np.testing.assert_allclose(ours, ref, rtol=1e-9)


@pytest.mark.parametrize("dt", [None, 0.1])
def test_settling_and_overshoot_match_step_info(dt):
    params = dict(OSC)
    if dt:
        A = np.eye(2) + dt * np.array(OSC["A"])
        params.update(A=A.tolist(), B=(dt * np.array(OSC["B"])).tolist(), dt=dt)
    prob = lqr.make_problem("default", {**params, "outputs": [[1, 0], [0, 1]],
                                        "settling_band": 0.05})
    Q, R = np.diag([1.0, 0.01]), np.array([[0.05]])
    out = prob.evaluate({"Q": Q, "R": R})
    K = np.array(out["gain"])
    A_cl = prob.plant.A - prob.plant.B @ K
    if dt:
        t = np.arange(prob.params.t_max / dt + 1) * dt
    else:
        t = np.linspace(0.0, prob.t_max, prob.params.response_points)
    for k, x0 in enumerate(prob.x0):
        settle, over = [], []
        for i in range(2):
            c = np.eye(2)[i:i + 1]
            if abs(c @ x0)[0] == 0:
                continue
            # y(0) − y(t) is the step response of (A_cl, b, −c) with b = A_cl x0 (discrete:
            # (A_cl − I) x0); its final value is y(0)
            b = (A_cl - np.eye(2)) @ x0 if dt else A_cl @ x0
            sys = control.ss(A_cl, b[:, None], -c, 0, dt) if dt else \
                control.ss(A_cl, b[:, None], -c, 0)
            info = control.step_info(sys, T=t, SettlingTimeThreshold=0.05)
            settle.append(info["SettlingTime"])
            over.append(info["Overshoot"])
        assert out["settling_time"][k] == pytest.approx(max(settle), abs=1e-9)
        assert out["overshoot_percent"][k] == pytest.approx(max(over), rel=1e-7, abs=1e-9)
    assert max(out["overshoot_percent"]) > 1.0  # the test sees a real overshoot


def test_settling_edge_cases():
    t = np.linspace(0.0, 1.0, 5)
    y = np.array([[1.0, 0.5, 0.01, -0.3, 0.0]])[..., None]  # leaves the band at the last
    settle, over = margins.settling_overshoot(t, y, 0.02)
    assert settle[0] == 1.0 and over[0] == pytest.approx(30.0)
    settle, _ = margins.settling_overshoot(t, np.array([[1.0, 0.5, 0.2, 0.1, 0.05]])[..., None],
                                           0.02)
    assert settle[0] == np.inf
    settle, over = margins.settling_overshoot(t, np.zeros((1, 5, 1)), 0.02)
    assert settle[0] == 0.0 and over[0] == 0.0


def test_violations_are_a_graded_status_not_a_crash():
    Q, R = np.diag([1.0, 0.01]), np.array([[0.05]])
    free = lqr.make_problem("default", OSC).evaluate({"Q": Q, "R": R})
    assert free["status"] == "converged"
    alpha = free["disk_margin"]["alpha"]
    ok = lqr.make_problem("default", {**OSC, "disk_margin_min": 0.9 * alpha})
    assert ok.evaluate({"Q": Q, "R": R})["cost"] == pytest.approx(free["cost"], rel=1e-14)
    costs = []
    for factor in (1.05, 1.3):
        prob = lqr.make_problem("default", {**OSC, "disk_margin_min": factor * alpha})
        out = prob.evaluate({"Q": Q, "R": R})
        assert out["status"] == "constraint" and not out["converged"]
        assert set(out["start_status"]) == {"constraint"}
        P = out["failure_penalty"]
        assert free["cost"] + P < out["cost"] < free["cost"] + 2 * P
        costs.append(out["cost"])
    assert costs[0] < costs[1]  # graded: the further from the limit, the worse
    tight = lqr.make_problem("default", {**OSC, "settling_time_max": 0.5, "overshoot_max": 0})
    out = tight.evaluate({"Q": Q, "R": R})
    assert out["status"] == "constraint" and out["limits"]["overshoot_max"] == 0
    batch = tight.evaluate_batch({"Q": np.stack([Q, 2 * Q]), "R": np.stack([R, R])})
    assert list(batch.status) == ["constraint", "constraint"]


def test_response_constraints_need_a_loop_they_can_sample():
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", {**OSC, "u_max": 1.0, "overshoot_max": 5.0})
    assert err.value.key == "problem.params.overshoot_max" and "u_max" in str(err.value)
    prob = lqr.make_problem("default", {**OSC, "u_max": 1.0, "disk_margin_min": 0.1})
    assert prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})["settling_time"] == [None, None]


def test_gain_and_phase_margin_keys_are_the_disk_margin_they_imply():
    rng = np.random.default_rng(8)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 1))
    K = control.lqr(A, B, np.eye(3), np.eye(1))[0]
    omega = margins.frequency_grid(A, None, 200)
    dm, dgm, dpm = control.disk_margins(control.ss(A, B, K, 0), omega)
    assert margins.alpha_for(gain_margin_db=dgm) == pytest.approx(dm, rel=1e-9)
    assert margins.alpha_for(phase_margin_deg=dpm) == pytest.approx(dm, rel=1e-9)
    assert margins.alpha_for() == 0.0
    Q, R = np.diag([1.0, 0.01]), np.array([[0.05]])
    free = lqr.make_problem("default", OSC).evaluate({"Q": Q, "R": R})["disk_margin"]
    for key, value in (("gain_margin_min", free["gain_margin_db"]),
                       ("phase_margin_min", free["phase_margin_deg"])):
        loose = lqr.make_problem("default", {**OSC, key: 0.99 * value})
        tight = lqr.make_problem("default", {**OSC, key: 1.01 * value})
        assert loose.evaluate({"Q": Q, "R": R})["status"] == "converged"
        assert tight.evaluate({"Q": Q, "R": R})["status"] == "constraint"
    with pytest.raises(ConfigError, match="below 180"):
        lqr.make_problem("default", {**OSC, "phase_margin_min": 180})


def test_continuous_siso_lqr_keeps_the_classical_disk_margin():
    # Kalman's return-difference inequality |1 + L(jω)| ≥ 1 gives |S − ½| ≤ 3/2: α ≥ 2/3
    rng = np.random.default_rng(9)
    for _ in range(20):
        n = int(rng.integers(1, 6))
        A, B = rng.normal(size=(n, n)), rng.normal(size=(n, 1))
        C = rng.normal(size=(1, n))
        K = control.lqr(A, B, C.T @ C + 1e-3 * np.eye(n), np.eye(1) * rng.uniform(0.01, 10))[0]
        alpha = margins.disk_margin(A, B, K[None], margins.frequency_grid(A, None, 400))[0]
        assert alpha >= 2.0 / 3.0 - 1e-9
