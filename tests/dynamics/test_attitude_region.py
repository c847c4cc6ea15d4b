"""The compiled first-turn search of the attitude region estimate against numpy's V̇."""

import numpy as np
import pytest

from penaltyrun.dynamics.attitude_region import first_turn
from penaltyrun.problems.attitude import sublevel

INERTIA = np.array([[10.0, 0.4, -0.2], [0.4, 15.0, 0.3], [-0.2, 0.3, 20.0]])


def _gain(rng: np.random.Generator, kp: float, kd: float) -> np.ndarray:
    Kp = kp * np.diag(rng.uniform(0.5, 2.0, 3)) + 0.1 * kp * rng.standard_normal((3, 3))
    Kd = kd * np.diag(rng.uniform(0.5, 2.0, 3))
    return np.hstack([Kp, Kd])


@pytest.mark.parametrize("seed", range(6))
def test_first_turn_is_where_numpy_vdot_first_turns(seed):
    rng = np.random.default_rng(seed)
    G = _gain(rng, kp=10.0 ** rng.uniform(-2, 1), kd=10.0 ** rng.uniform(-2, 0))
    P = sublevel.lyapunov_matrix(G, INERTIA)
    if P is None:
        pytest.skip("unstable draw")
    P = P[0]
    d = rng.standard_normal((300, 6))
    d /= np.sqrt(np.einsum("ni,ij,nj->n", d, P, d))[:, None]
    s = np.linspace(0.0, np.sqrt(sublevel.edge_level(P)), 61)[1:]
    vdot = sublevel.vdot(s[:, None, None] * d[None], P, G, INERTIA)  # (radii, rays)
    turned = np.flatnonzero((vdot >= 0.0).any(axis=1))
    want = int(turned[0]) if turned.size else -1
    assert first_turn(P, G, INERTIA, np.linalg.inv(INERTIA), d, s) == want


def test_no_turn_and_a_turn_at_the_first_radius():
    G = np.hstack([np.eye(3), 5.0 * np.eye(3)])
    P = sublevel.lyapunov_matrix(G, INERTIA)[0]
    d = np.eye(6)
    s = np.array([1e-3, 1e-2])
    assert first_turn(P, G, INERTIA, np.linalg.inv(INERTIA), d, s) == -1
    # V = −|x|²-like with a negative definite P: V̇ > 0 everywhere off the origin
    assert first_turn(-P, G, INERTIA, np.linalg.inv(INERTIA), d, s) == 0
