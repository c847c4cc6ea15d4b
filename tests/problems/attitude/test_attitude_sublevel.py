"""The sub-level-set estimate of the attitude laws' region of attraction: its Lyapunov
matrix, V̇ against a finite difference along an independent integration, the certified
level against sampled states, and the sampled level against simulation."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from penaltyrun.problems.attitude import lyapunov, sublevel

INERTIA = np.diag([10.0, 15.0, 20.0])
#: A slow diagonal PD gain of the kind a free-final-time tune finds (N·m, N·m·s).
KP = np.diag([0.0105, 0.0072, 0.0158])
KD = np.diag([0.41, 0.48, 0.71])
G = np.hstack([KP, KD])


def rigid_body(t, y, gain, inertia):
    """Quaternion kinematics q̇ = ½ q ⊗ (0, ω) and Euler's equation, u = −G (q_v, ω)."""
    q, w = y[:4], y[4:]
    u = -gain @ np.concatenate([q[1:], w])
    dq0 = -0.5 * q[1:] @ w
    dqv = 0.5 * (q[0] * w + np.cross(q[1:], w))
    dw = np.linalg.solve(inertia, -np.cross(w, inertia @ w) + u)
    return np.concatenate([[dq0], dqv, dw])


def test_the_lyapunov_matrix_solves_its_equation():
    P, Q = sublevel.lyapunov_matrix(G, INERTIA)
    A = sublevel.closed_loop_matrix(G, INERTIA)
    assert np.allclose(A.T @ P + P @ A, -Q, atol=1e-8 * np.abs(P).max())
    assert np.linalg.eigvalsh(P)[0] > 0
    tau = 1.0 / np.min(np.abs(np.linalg.eigvals(A).real))
    assert np.allclose(np.diag(Q), [1, 1, 1] + [tau ** 2] * 3)


def test_an_unstable_gain_has_no_estimate():
    assert sublevel.estimate(np.hstack([-KP, KD]), INERTIA) is None
    assert sublevel.estimate(G, INERTIA, saturated=True) is None


@pytest.mark.parametrize("seed", range(4))
def test_vdot_matches_a_finite_difference_along_solve_ivp(seed):
    rng = np.random.default_rng(seed)
    gain = np.hstack([KP + 0.002 * np.eye(3), KD]) + 0.001 * rng.standard_normal((3, 6))
    P, _ = sublevel.lyapunov_matrix(gain, INERTIA)
    qv = 0.4 * rng.standard_normal(3)
    qv *= min(1.0, 0.9 / np.linalg.norm(qv))
    w = 0.02 * rng.standard_normal(3)
    y0 = np.concatenate([[np.sqrt(1 - qv @ qv)], qv, w])
    h = 1e-3

    def V(t):
        sol = solve_ivp(rigid_body, (0.0, t), y0, args=(gain, INERTIA), rtol=1e-12,
                        atol=1e-14) if t > 0 else \
            solve_ivp(lambda s, y: -rigid_body(-s, y, gain, INERTIA), (0.0, -t), y0,
                      rtol=1e-12, atol=1e-14)
        x = sol.y[1:, -1]
        return x @ P @ x

    fd = (V(h) - V(-h)) / (2 * h)
    got = sublevel.vdot(np.concatenate([qv, w]), P, gain, INERTIA)
    assert got == pytest.approx(fd, rel=1e-5, abs=1e-9 * np.abs(P).max())


def test_v_decreases_on_the_certified_set():
    region = sublevel.estimate(G, INERTIA)
    x = sublevel.states_inside(region, region.certified, 2000)[:, 1:]
    assert np.all(region.value(x) <= region.certified * (1 + 1e-12))
    assert np.all(sublevel.vdot(x, region.P, G, INERTIA) < 0)
    assert 0 < region.certified < region.sampled <= sublevel.SAFETY * region.edge * (1 + 1e-12)


def test_the_sampled_set_lies_in_the_hemisphere_and_v_decreases_on_fresh_samples():
    region = sublevel.estimate(G, INERTIA)
    x = sublevel.states_inside(region, region.sampled, 4000, seed=7)[:, 1:]
    assert np.linalg.norm(x[:, :3], axis=1).max() < 1.0
    assert np.all(sublevel.vdot(x, region.P, G, INERTIA) < 0)


def test_every_sampled_start_inside_the_set_converges():
    """The sampled estimate against simulation: starts on the boundary (among them the two
    of largest rotation) and inside it all reach the target at the run horizon."""
    prob = lyapunov.make_problem("rest_to_rest", {"criterion": "time_energy",
                                                  "free_time_cap": 3000.0})
    mats = {"Kp": KP, "Kd": KD}
    region = prob.sublevel_set(mats)
    res = sublevel.check(prob, mats, region.sampled, n=12)
    angle = np.degrees(2 * np.arccos(res["y0"][:, 0].min()))
    assert angle > 90.0  # the set reaches large rotations
    assert res["converged"].all()


def test_the_basin_plane_region_is_the_set_at_zero_rates():
    prob = lyapunov.make_problem("rest_to_rest", {})
    mats = {"Kp": KP, "Kd": KD}
    points = np.array([[0.0, 1.0], [5.0, -5.0], [179.0, 0.0], [0.0, 88.0]])
    reg = prob.basin_region(mats, None, points)
    region = prob.sublevel_set(mats)
    half = np.radians(points) / 2  # yaw then pitch, roll 0: q_v by hand
    cy, sy, cp, sp = np.cos(half[:, 0]), np.sin(half[:, 0]), np.cos(half[:, 1]), \
        np.sin(half[:, 1])
    qv = np.column_stack([-sy * sp, cy * sp, sy * cp])
    want = region.value(np.column_stack([qv, np.zeros((4, 3))])) <= region.sampled
    assert reg["inside"].tolist() == want.tolist()
    assert reg["inside"][0] and not reg["inside"][2]
    assert reg["level"] == region.sampled


def _every_ray_at_every_radius(P, gain, inertia, n_directions, n_radii, seed):
    """The sampled level from every ray at every radius (no early stop)."""
    d = sublevel._directions(P, n_directions, np.random.default_rng(seed))
    s_max = np.sqrt(sublevel.edge_level(P))
    s = np.linspace(0.0, s_max, n_radii + 1)[1:]
    x = s[None, :, None] * d[:, None, :]
    qv, w = x[..., :3], x[..., 3:]
    q0 = np.sqrt(np.clip(1.0 - np.sum(qv * qv, axis=-1), 0.0, None))[..., None]
    dq = 0.5 * (q0 * w + np.cross(qv, w))
    dw = np.einsum("ij,...j->...i", np.linalg.inv(inertia),
                   -np.cross(w, np.einsum("ij,...j->...i", inertia, w))
                   - np.einsum("ij,...j->...i", gain, x))
    vdot = 2.0 * np.einsum("...i,ij,...j->...", x, P, np.concatenate([dq, dw], axis=-1))
    bad = vdot >= 0.0
    first = np.where(bad.any(axis=1), s[np.argmax(bad, axis=1)], s_max)
    return sublevel.SAFETY * float(np.min(first)) ** 2


@pytest.mark.parametrize(("kp", "kd", "turns"), [(1.0, 1.0, False), (1.0, 0.05, False),
                                                (10.0, 0.1, True), (100.0, 0.3, True),
                                                (1000.0, 1.0, True)])
def test_the_sampled_level_stops_where_every_ray_would(kp, kd, turns):
    """Visiting the radii outward and stopping at the first block with V̇ ≥ 0 gives the level
    of evaluating every ray at every radius, whether a ray turns inside the hemisphere
    (stiff, lightly damped gains) or none does (the level is then the edge level's)."""
    rng = np.random.default_rng(int(kp / kd))
    gain = np.hstack([kp * KP, kd * KD]) + 1e-4 * rng.standard_normal((3, 6))
    P, _ = sublevel.lyapunov_matrix(gain, INERTIA)
    edge = sublevel.SAFETY * sublevel.edge_level(P)
    for n_directions, n_radii in [(50, 7), (300, 200), (2000, 200)]:
        got = sublevel.sampled_level(P, gain, INERTIA, n_directions, n_radii, seed=3)
        want = _every_ray_at_every_radius(P, gain, INERTIA, n_directions, n_radii, 3)
        assert got == pytest.approx(want, rel=1e-14)
    assert (got < 0.99 * edge) == turns
