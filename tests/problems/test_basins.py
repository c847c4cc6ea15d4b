"""Basin-of-attraction maps: a saturated linear plant whose region of attraction is known in
closed form, Zermelo against an independent integration, the attitude plane."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun import problems
from penaltyrun.problems.attitude.frames import euler_to_quaternion, quaternion_to_euler
from penaltyrun.problems.basins import BasinMap, BasinProblem, basin_map, grid
from penaltyrun.problems.zermelo import reference_cost

#: Open-loop rates of the two unstable modes (1/s) and the input limit.
A_RATES = (1.0, 0.5)
U_MAX = 1.0


def test_saturated_unstable_plant_matches_its_closed_form_region():
    """ẋᵢ = aᵢ xᵢ + uᵢ, |uᵢ| ≤ u_max, decoupled: with a diagonal gain uᵢ = sat(−kᵢ xᵢ),
    kᵢ > aᵢ, the run from x returns to 0 if and only if |xᵢ| < u_max / aᵢ for both modes
    (outside, aᵢ|xᵢ| > u_max and the mode grows). The map must be that rectangle at every
    grid point not within 3 % of its edges."""
    prob = problems.make("lqr", "default", {
        "A": [[A_RATES[0], 0.0], [0.0, A_RATES[1]]], "B": [[1.0, 0.0], [0.0, 1.0]],
        "u_max": U_MAX, "x0": [[1.5, 0.0]], "t_max": 20.0})
    assert isinstance(prob, BasinProblem)
    mats = {"Q": np.eye(2), "R": np.eye(2)}
    bm = basin_map(prob, mats, n=30)
    assert bm.axes.labels == ("x1", "x2") and bm.axes.marker == (1.5, 0.0)
    assert bm.axes.hi == (3.0, 3.0)
    edge = np.array([U_MAX / a for a in A_RATES])
    xs, ys = np.meshgrid(bm.x, bm.y)
    ratio = np.maximum(np.abs(xs) / edge[0], np.abs(ys) / edge[1])
    clear = np.abs(ratio - 1.0) > 0.03
    assert clear.sum() > 800
    assert np.array_equal(bm.converged[clear], (ratio < 1.0)[clear])
    assert np.all(np.isnan(bm.arrival_time))  # a cost without a target event
    assert np.all(bm.cost[~bm.converged] > bm.cost[bm.converged].max())


def test_zermelo_map_against_an_independent_integration():
    """Every start converges (the closed loop Ẋ = −KᵀX is linear and stable); arrival times
    and costs at sampled points equal scipy's solve_ivp."""
    prob = problems.make("zermelo", "default", {})
    K = np.array([[1.7421, 0.9560], [0.9560, 1.1414]])
    bm = basin_map(prob, {"K": K}, n=6)
    assert bm.converged.all() and bm.share_converged == 1.0
    assert bm.axes.marker == (-8.0, 6.0) and bm.axes.hi == (12.0, 12.0)
    assert bm.horizon == 10_000.0
    rng = np.random.default_rng(2)
    for i, j in rng.integers(0, 6, size=(4, 2)):
        params = replace(prob.params, x0=(float(bm.x[j]), float(bm.y[i])), t_max=bm.horizon)
        cost, t_final, converged = reference_cost(K, params)
        assert converged
        assert bm.arrival_time[i, j] == pytest.approx(t_final, rel=1e-6)
        assert bm.cost[i, j] == pytest.approx(cost, rel=1e-6)


def test_attitude_map_covers_yaw_and_pitch_at_the_held_out_horizon():
    prob = problems.make("attitude_lqr", "detumble", {})
    mats = {"Q": np.eye(6), "R": np.eye(3)}
    bm = basin_map(prob, mats, n=4)
    assert bm.axes.labels == ("yaw (deg)", "pitch (deg)")
    assert bm.converged.shape == (4, 4) and bm.horizon > prob.params.t_max
    direct = prob.evaluate_grid(mats, [[bm.x[1], bm.y[2], 0.0]])
    assert direct["converged"][0] == bm.converged[2, 1]


def test_grid_and_rows():
    prob = problems.make("zermelo", "default", {})
    x, y, points = grid(prob.basin_axes(), 3)
    assert points.tolist()[:3] == [[-12.0, -12.0], [0.0, -12.0], [12.0, -12.0]]
    with pytest.raises(ValueError, match="at least 2"):
        grid(prob.basin_axes(), 1)
    bm = basin_map(prob, {"K": np.eye(2)}, n=2)
    assert isinstance(bm, BasinMap)
    rows = bm.rows()
    assert len(rows) == 4 and set(rows[0]) == {"x", "y", "converged", "arrival_time", "cost"}


def test_a_problem_without_a_plane_has_no_map():
    one_state = problems.make("lqr", "default", {"A": [[0.5]], "B": [[1.0]]})
    assert basin_map(one_state, {"Q": np.eye(1), "R": np.eye(1)}) is None
    assert basin_map(object(), {}) is None


@settings(max_examples=60, deadline=None)
@given(st.floats(-179.0, 179.0), st.floats(-89.0, 89.0), st.floats(-179.0, 179.0))
def test_quaternion_to_euler_inverts_euler_to_quaternion(yaw, pitch, roll):
    back = quaternion_to_euler(euler_to_quaternion([yaw, pitch, roll]))
    assert back == pytest.approx([yaw, pitch, roll], abs=1e-6)


def test_mpc_map_point_is_a_run_from_that_start():
    """A grid point of the rendezvous map equals the problem built with that start (at
    rest, the training z) and the held-out horizon as its deadline."""
    prob = problems.make("mpc_rendezvous", "default", {})
    mats = {"Q": np.eye(6), "R": np.eye(3)}
    bm = basin_map(prob, mats, n=3)
    assert bm.axes.labels == ("along-track y (m)", "radial x (m)")
    assert bm.axes.marker == (prob.params.s0[1], prob.params.s0[0])
    y, x = bm.x[0], bm.y[2]
    z = prob.params.s0[2]
    alone = problems.make("mpc_rendezvous", "default", {
        "s0": [float(x), float(y), z, 0.0, 0.0, 0.0], "t_max": bm.horizon})
    res = alone.evaluate(mats)
    assert bool(res["converged"]) == bool(bm.converged[2, 0])
    assert res["cost"] == pytest.approx(bm.cost[2, 0], rel=1e-12)
    if res["converged"]:
        assert res["t_final"] == pytest.approx(bm.arrival_time[2, 0], rel=1e-12)
