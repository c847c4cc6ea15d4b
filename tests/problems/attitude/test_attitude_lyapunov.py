"""attitude_lyapunov problem and the shared attitude layer (attitude_common).

Reference agreement: production costs vs an independent scipy ``solve_ivp`` (DOP853) run at
the same tolerances (1e-10), the same ``max_step`` and the same graded penalty. The default
run uses 2 fixed gains (one converging, one too slow to converge) plus 4 random PD pairs
(eigenvalues uniform in [0.1, 10], random rotations) × 3 initial conditions (detumble,
rest-to-rest, and a third attitude with full inertia); the ``slow`` variant uses 50 random
pairs × 3.
"""

from __future__ import annotations

import json
from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest
import yaml
from attitude_agreement import I_FULL, agreement, random_spd

from penaltyrun.errors import ConfigError
from penaltyrun.problems import make
from penaltyrun.problems.attitude import common as ac
from penaltyrun.problems.attitude import lyapunov as lyap

CONF = Path(__file__).resolve().parents[3] / "penaltyrun" / "conf" / "problem"
Q_EXPECTED = np.array([0.413836, -0.610042, 0.290580, 0.610042])
GOOD = {"Kp": 3.0 * np.eye(3), "Kd": 6.0 * np.eye(3)}
SLOW = {"Kp": 0.1 * np.eye(3), "Kd": 0.5 * np.eye(3)}


def _agreement(n_random: int, seed: int) -> tuple[int, int]:
    rng = np.random.default_rng(seed)
    cands = [GOOD, SLOW] + [{"Kp": random_spd(rng, 3, 0.1, 10.0),
                             "Kd": random_spd(rng, 3, 0.1, 10.0)} for _ in range(n_random)]
    return agreement("attitude_lyapunov", cands, ("Kp", "Kd"), _stacked_gains,
                     lyap.reference_cost)


def _stacked_gains(batch: dict[str, np.ndarray], _prob) -> np.ndarray:
    return np.concatenate([batch["Kp"], batch["Kd"]], axis=-1)


def test_production_matches_reference():
    n_conv, n_fail = _agreement(4, seed=11)
    assert n_conv >= 3 and n_fail >= 3


@pytest.mark.slow
def test_production_matches_reference_full():
    n_conv, n_fail = _agreement(50, seed=12)
    assert n_conv >= 10 and n_fail >= 10


# ------------------------------------------------------------------ attitudes and params


def test_default_initial_quaternion():
    np.testing.assert_allclose(ac.Params().initial_quaternion(), Q_EXPECTED, atol=1e-6)
    np.testing.assert_allclose(ac.euler_to_quaternion([60.0, 80.0, -60.0]), Q_EXPECTED,
                               atol=1e-6)


def test_attitude_representations_agree_and_q0_nonnegative():
    q = ac.euler_to_quaternion([60.0, 80.0, -60.0])
    sigma = q[1:] / (1.0 + q[0])
    as_mrp = ac.Params(attitude_type="mrp", attitude=tuple(sigma)).initial_quaternion()
    as_neg = ac.Params(attitude_type="quaternion",
                       attitude=tuple(-2.0 * q)).initial_quaternion()
    np.testing.assert_allclose(as_mrp, q, atol=1e-14)
    np.testing.assert_allclose(as_neg, q, atol=1e-14)
    grid = ac.robustness_grid()
    assert grid.shape == (216, 3)
    qs = ac.euler_to_quaternion(grid)
    assert np.all(qs[:, 0] >= 0.0)
    np.testing.assert_allclose(np.linalg.norm(qs, axis=1), 1.0, atol=1e-14)


def test_euler_convention_is_intrinsic_zyx():
    """A pure yaw of 90° is a rotation about z; yaw-then-pitch composes as q_z ⊗ q_y."""
    s = np.sqrt(0.5)
    np.testing.assert_allclose(ac.euler_to_quaternion([90.0, 0.0, 0.0]), [s, 0, 0, s],
                               atol=1e-15)
    np.testing.assert_allclose(ac.euler_to_quaternion([0.0, 90.0, 0.0]), [s, 0, s, 0],
                               atol=1e-15)
    np.testing.assert_allclose(ac.euler_to_quaternion([90.0, 90.0, 0.0]),
                               [0.5, -0.5, 0.5, 0.5], atol=1e-15)


def test_euler_angles_are_scipys_intrinsic_zyx():
    """The documented convention: SciPy's ``from_euler("ZYX", ...)`` (up to q → −q)."""
    from scipy.spatial.transform import Rotation

    angles = np.random.default_rng(5).uniform(-180.0, 180.0, (50, 3))
    xyzw = Rotation.from_euler("ZYX", angles, degrees=True).as_quat()
    expected = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    expected *= np.where(expected[:, :1] < 0.0, -1.0, 1.0)
    np.testing.assert_allclose(ac.euler_to_quaternion(angles), expected, atol=1e-14)


def test_cases_and_overrides():
    assert lyap.CASES == ("detumble", "rest_to_rest", "schaub_detumble", "schaub_detumble_sat")
    assert lyap.DEFAULT_CASE == "detumble"
    det = make("attitude_lyapunov", None)
    rest = make("attitude_lyapunov", "rest_to_rest")
    assert det.params.omega0 == (0.01, -0.01, 0.01)
    assert rest.params.omega0 == (0.0, 0.0, 0.0)
    over = make("attitude_lyapunov", "rest_to_rest", {"omega0": [0.1, 0.0, 0.0],
                                                      "inertia": [list(r) for r in I_FULL]})
    assert over.params.omega0 == (0.1, 0.0, 0.0)
    np.testing.assert_array_equal(over.inertia, np.array(I_FULL))
    assert [m.name for m in det.matrices] == ["Kp", "Kd"]
    assert all(m.size == 3 and m.eig_bounds == (1e-8, 10.0) for m in det.matrices)


@pytest.mark.parametrize("key,value", [
    ("nonsense", 1.0), ("inertia", (1.0, -2.0, 3.0)), ("inertia", (1.0, 2.0)),
    ("attitude_type", "dcm"), ("attitude", (1.0, 2.0)), ("omega0", (0.0, 0.0)),
    ("t_max", -1.0), ("u_max", 0.0), ("n_event_samples", 0), ("eig_bounds", (1.0, 0.5)),
])
def test_bad_params_raise_config_error(key, value):
    with pytest.raises(ConfigError, match=key):
        make("attitude_lyapunov", "detumble", {key: value})


def test_bad_matrices_raise_config_error():
    prob = make("attitude_lyapunov", "detumble")
    with pytest.raises(ConfigError, match="matrices.Kp"):
        prob.evaluate({"Kp": -np.eye(3), "Kd": np.eye(3)})
    with pytest.raises(ConfigError, match="matrices.Kd"):
        prob.evaluate({"Kp": np.eye(3), "Kd": np.eye(2)})


def test_config_file_lists_every_param():
    for name in ("attitude_lyapunov", "attitude_lqr"):
        conf = yaml.safe_load((CONF / f"{name}.yaml").read_text())
        assert conf["name"] == name
        assert set(conf["params"]) == {f.name for f in fields(ac.Params)}
        given = {k: v for k, v in conf["params"].items() if v is not None}
        for case in ac.CASES:
            assert make(name, case, given).params == make(name, case).params


# ------------------------------------------------------------------ evaluation


def test_evaluate_is_json_and_consistent_with_batch():
    prob = make("attitude_lyapunov", "detumble")
    res = prob.evaluate(GOOD)
    json.dumps(res)
    assert res["converged"] and res["status"] == "converged"
    assert res["cost"] == res["energy"] and res["t_final"] < 100.0
    assert res["final_distance"] == pytest.approx(1e-4, rel=1e-9)
    np.testing.assert_array_equal(np.asarray(res["gain"]),
                                  np.hstack([GOOD["Kp"], GOOD["Kd"]]))
    be = prob.evaluate_batch({k: v[None] for k, v in GOOD.items()})
    assert be.cost[0] == res["cost"]


def test_failures_are_graded_and_finite():
    prob = make("attitude_lyapunov", "detumble")
    fp = prob.params.failure_penalty
    weak = [prob.evaluate({"Kp": k * np.eye(3), "Kd": 2 * k * np.eye(3)})
            for k in (1e-8, 0.01, 0.1)]
    for r in weak:
        assert not r["converged"] and r["status"] == "horizon"
        assert r["t_final"] == pytest.approx(100.0)
        assert np.isfinite(r["cost"]) and r["cost"] > fp
        assert r["cost"] == pytest.approx(
            r["energy"] + fp * (1 + r["final_distance"] / r["initial_distance"]))
    # closer to the target at t_max → lower cost
    assert weak[0]["cost"] > weak[1]["cost"] > weak[2]["cost"]


def test_simulate_histories():
    prob = make("attitude_lyapunov", "rest_to_rest")
    sim = prob.simulate(GOOD, n_points=200)
    res = prob.evaluate(GOOD)
    assert sim["t"].shape == (200,) and sim["q"].shape == (200, 4)
    assert sim["w"].shape == (200, 3) and sim["u"].shape == (200, 3)
    assert sim["t"][-1] == pytest.approx(res["t_final"])
    assert sim["J"][-1] == pytest.approx(res["energy"], rel=1e-6)
    assert sim["dist"][-1] == pytest.approx(1e-4, rel=1e-4)
    np.testing.assert_allclose(np.linalg.norm(sim["q"], axis=1), 1.0, atol=1e-9)


@pytest.mark.parametrize(("case", "overrides"), [("rest_to_rest", {}),
                                                 ("detumble", {"u_max": 0.05})])
def test_simulate_histories_match_a_run_with_capped_steps(case, overrides):
    """The plotted histories, whose steps the error control chooses alone, agree with a
    scipy run whose steps are capped at 0.05 s to 1e-5 of their range (through the
    saturation's kinks too)."""
    from dataclasses import replace

    from penaltyrun.problems.attitude.reference import trajectory

    prob = make("attitude_lyapunov", case, overrides)
    t_end = prob.evaluate(GOOD)["t_final"]
    G = prob.gain(GOOD)
    free = trajectory(G, prob.params, t_end, 300, prob.y0)
    capped = trajectory(G, replace(prob.params, max_step=0.05), t_end, 300, prob.y0)
    for key in ("q", "w", "u", "J"):
        scale = np.abs(capped[key]).max()
        np.testing.assert_allclose(free[key], capped[key], rtol=0, atol=1e-5 * scale)


def test_saturation_respected():
    prob = make("attitude_lyapunov", "rest_to_rest", {"u_max": 0.05})
    sim = prob.simulate(GOOD, n_points=300)
    assert np.max(np.abs(sim["u"])) <= 0.05
    assert np.max(np.abs(sim["u"])) == pytest.approx(0.05)
    free = make("attitude_lyapunov", "rest_to_rest").evaluate(GOOD)
    assert prob.evaluate(GOOD)["energy"] < free["energy"]


def test_evaluate_grid_matches_single_runs():
    grid = ac.robustness_grid()
    out = ac.evaluate_grid("attitude_lyapunov", GOOD, grid)
    for key in ("cost", "converged", "status", "energy", "t_final"):
        assert len(out[key]) == 216
    assert np.all(np.isfinite(out["cost"]))
    assert out["converged"].mean() > 0.5
    for k in (0, 77, 215):
        single = make("attitude_lyapunov", "rest_to_rest",
                      {"attitude": tuple(grid[k])}).evaluate(GOOD)
        assert out["cost"][k] == single["cost"]
        assert out["converged"][k] == single["converged"]
    prob = make("attitude_lyapunov", "detumble")
    direct = lyap.evaluate_grid(prob, GOOD, [[60.0, 80.0, -60.0]])
    assert direct["cost"][0] == prob.evaluate(GOOD)["cost"]


def test_holdout_is_rest_to_rest_grid():
    prob = make("attitude_lyapunov", "detumble")
    held = prob.holdout(GOOD)
    grid = ac.evaluate_grid("attitude_lyapunov", GOOD, ac.robustness_grid())
    np.testing.assert_array_equal(held["cost"], grid["cost"])
    np.testing.assert_array_equal(held["attitudes_deg"], ac.robustness_grid())
    assert held["cost"].shape == (216,)


def test_holdout_grid_is_configurable():
    small = lyap.make_problem("detumble", {"holdout_n": 2, "holdout_lo_deg": 20.0,
                                           "holdout_hi_deg": 40.0}).holdout(GOOD)
    assert small["cost"].shape == (8,)
    np.testing.assert_array_equal(np.unique(small["attitudes_deg"]), [20.0, 40.0])
    assert lyap.make_problem("detumble", {"holdout_n": 0}).holdout(GOOD) is None


def test_plots_smoke():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prob = make("attitude_lyapunov", "detumble")
    sims = {"best diagonal": prob.simulate(GOOD, n_points=50),
            "best full": prob.simulate({"Kp": np.array([[3, 0.5, 0], [0.5, 3, 0], [0, 0, 3.0]]),
                                        "Kd": 6.0 * np.eye(3)}, n_points=50)}
    fig = lyap.plot_histories(sims)
    assert len(fig.axes) == 3
    assert len(fig.axes[0].lines) == 8 and len(fig.axes[2].lines) == 6
    assert fig.get_layout_engine() is not None  # laid out for a user's plt.show()
    plt.close(fig)
    # the report's hook leaves the layout to the report, which lays out what it saves
    from penaltyrun.problems import report_hooks

    figures = report_hooks.plots(lyap, sims, "detumble", {})
    assert figures and all(f.get_layout_engine() is None for f in figures.values())
    plt.close("all")


def test_reference_rhs_gyroscopic_term_is_the_cross_product():
    """The scipy reference's written-out w × (I w) equals numpy.cross bit for bit."""
    from penaltyrun.problems.attitude import reference

    rng = np.random.default_rng(4)
    G, inertia = rng.normal(size=(3, 6)), np.diag([2.0, 3.0, 4.0]) + 0.1
    rhs = reference._rhs_numpy(G, inertia, np.linalg.inv(inertia), 0.5)
    for y in rng.normal(size=(50, 8)):
        w = y[4:7]
        u = np.clip(-G @ y[1:7], -0.5, 0.5)
        expected = np.linalg.inv(inertia) @ (u - np.cross(w, inertia @ w))
        assert np.array_equal(rhs(0.0, y)[4:7], expected)
