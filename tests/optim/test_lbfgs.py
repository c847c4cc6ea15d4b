"""optimizer=lbfgs: multi-start L-BFGS-B with exact gradients reaches the closed-form LQR
optimum J* (Q ∝ W_x, R ∝ W_u inside the map's range) to 1e-8; its budget is counted in
evaluation-equivalents; its starts come from the job seed; its records carry the
projected-gradient norm and the active bounds."""

import numpy as np
import pytest

from penaltyrun import optim
from penaltyrun.errors import ConfigError
from penaltyrun.optim.gradient import z_gradient
from penaltyrun.optim.lbfgs import UnitCube
from penaltyrun.problems import lqr
from penaltyrun.runner.setup import build_layout


def _random_plant(seed, n, m):
    """A random plant whose performance weights have eigenvalues inside [0.5, 5] (the
    optimum Q = W_x, R = W_u is in the box of every map)."""
    rng = np.random.default_rng(seed)

    def spd(k):
        V = np.linalg.qr(rng.normal(size=(k, k)))[0]
        return V @ np.diag(rng.uniform(0.5, 5.0, k)) @ V.T

    return lqr.make_problem("default", {
        "A": rng.normal(size=(n, n)).tolist(), "B": rng.normal(size=(n, m)).tolist(),
        "x0": rng.normal(size=(n + 1, n)).tolist(), "state_weight": spd(n).tolist(),
        "input_weight": spd(m).tolist(), "t_max": 60.0, "q_bounds": [0.05, 50.0],
        "r_bounds": [0.05, 50.0]})


def _run(prob, kind, options, seed=11):
    layout = build_layout(prob, kind, {})
    lb, ub = layout.bounds()

    def objective(Z):
        return prob.evaluate_batch(layout.split(Z)[0])

    settings = optim.with_gradient_cost(optim.make_settings("lbfgs", options), prob)
    return optim.minimize("lbfgs", objective, lb, ub, settings, seed,
                          gradient=lambda z: z_gradient(prob, layout, z)), layout


@pytest.mark.parametrize(("make", "kind"), [
    (lambda: lqr.make_problem("default", {}), "givens"),
    (lambda: lqr.make_problem("default", {}), "cayley"),
    pytest.param(lambda: _random_plant(2, 4, 2), "givens", marks=pytest.mark.slow),
])
def test_reaches_the_closed_form_optimum_to_1e_8(make, kind):
    prob = make()
    res, _ = _run(prob, kind, {"starts": 1, "max_evals": 20000})
    assert np.isfinite(prob.optimum)
    assert abs(res.best_cost - prob.optimum) <= 1e-8 * prob.optimum


@pytest.mark.parametrize("kind", [pytest.param("givens", marks=pytest.mark.slow), "diagonal"])
def test_log_positive_searches_the_same_box_and_reaches_the_same_optimum(kind):
    prob = lqr.make_problem("default", {})
    options = {"starts": 1, "max_evals": 20000}
    linear, _ = _run(prob, kind, options)
    logged, layout = _run(prob, kind, {**options, "log_positive": True})
    lb, ub = layout.bounds()
    assert np.all(logged.best_z >= lb) and np.all(logged.best_z <= ub)
    assert logged.best_cost == pytest.approx(linear.best_cost, rel=1e-8)
    if kind == "givens":
        assert abs(logged.best_cost - prob.optimum) <= 1e-8 * prob.optimum


def test_unit_cube_log_scale_is_exact_both_ways_with_its_jacobian():
    lb = np.array([0.05, 0.05, -np.pi, 0.0])
    ub = np.array([50.0, 2.0, np.pi, 1.0])
    cube = UnitCube(lb, ub, log_positive=True)
    assert cube.log.tolist() == [True, True, False, False]
    u = np.array([0.5, 0.25, 0.75, 0.3])
    z = cube.to_box(u)
    assert z[0] == pytest.approx(np.sqrt(0.05 * 50.0))  # the geometric middle
    assert z[2] == pytest.approx(np.pi / 2) and z[3] == pytest.approx(0.3)
    np.testing.assert_allclose(cube.to_cube(z), u, rtol=1e-13)
    np.testing.assert_array_equal(cube.to_box([0.0, 0.0, 0.0, 0.0]), lb)
    np.testing.assert_allclose(cube.to_box([1.0, 1.0, 1.0, 1.0]), ub, rtol=1e-15)
    h = 1e-6
    numeric = [(cube.to_box(u + h * e) - cube.to_box(u - h * e))[k] / (2 * h)
               for k, e in enumerate(np.eye(4))]
    np.testing.assert_allclose(cube.dz_du(z), numeric, rtol=1e-8)
    linear = UnitCube(lb, ub)
    assert not linear.log.any()
    np.testing.assert_allclose(linear.to_box(u), lb + u * (ub - lb))


def test_diagonal_map_stops_at_its_own_optimum_above_j_star():
    """The known-answer plant's J* needs a non-diagonal Q: the diagonal map ends at a
    first-order point of its own box, above J*."""
    prob = lqr.make_problem("default", {})
    res, layout = _run(prob, "diagonal", {"starts": 2, "max_evals": 5000})
    assert res.best_cost > 1.01 * prob.optimum
    grad = z_gradient(prob, layout, res.best_z).grad
    lb, ub = layout.bounds()
    assert np.max(np.abs(optim.gradient.projected_gradient(res.best_z, grad, lb, ub))) < 1e-6


def test_the_budget_stops_a_run_without_a_start_limit():
    """(How each gradient is charged: tests/optim/test_lbfgs_charge.py.)"""
    prob = lqr.make_problem("default", {})
    res, _ = _run(prob, "givens", {"starts": None, "max_evals": 200, "grad_cost": 4}, seed=3)
    assert res.stop_reason == "max_evals" and res.n_evals <= 200


def test_starts_come_from_the_seed():
    prob = lqr.make_problem("default", {})
    a, _ = _run(prob, "diagonal", {"starts": 1, "max_evals": 3}, seed=1)
    b, _ = _run(prob, "diagonal", {"starts": 1, "max_evals": 3}, seed=1)
    c, _ = _run(prob, "diagonal", {"starts": 1, "max_evals": 3}, seed=2)
    np.testing.assert_array_equal(a.trace_best, b.trace_best)
    assert a.trace_best != c.trace_best


@pytest.mark.parametrize(("options", "key"), [
    ({"starts": 0}, "optimizer.starts"),
    ({"starts": None}, "optimizer.starts"),
    ({"gtol": -1.0}, "optimizer.gtol"),
    ({"grad_cost": -2}, "optimizer.grad_cost"),
])
def test_bad_settings_name_their_key(options, key):
    with pytest.raises(ConfigError, match=key):
        optim.make_settings("lbfgs", options)


def test_without_gradient_lbfgs_refuses():
    with pytest.raises(ConfigError, match="exact gradient"):
        optim.minimize("lbfgs", lambda Z: np.zeros(len(Z)), np.zeros(2), np.ones(2),
                       optim.make_settings("lbfgs", {"starts": 1}), 0)


def test_records_carry_projected_gradient_and_active_bounds(tmp_path):
    import penaltyrun

    rec = penaltyrun.tune("lqr", param="givens", optimizer="lbfgs",
                          optimizer_options={"starts": 1, "max_evals": 3000}, n_starts=1,
                          seed=4, workers=1, run_dir=tmp_path / "run").records
    row = rec.iloc[0]
    assert row["grad_norm"] < 1e-6 and row["gradient_note"] == ""
    # J(cQ, cR) = J(Q, R): the search may slide along that ray onto a bound
    assert all(b.split("=")[0] in row["z_names"] and b.split("=")[1] in ("lower", "upper")
               for b in row["active_bounds"])
    cm = penaltyrun.tune("lqr", param="diagonal", optimizer="cmaes",
                         optimizer_options={"max_evals": 200}, n_starts=1, seed=4, workers=1,
                         run_dir=tmp_path / "cmaes").records.iloc[0]
    assert np.isfinite(cm["grad_norm"])  # every optimizer's best gets its certificate


def test_gradient_polish_refines_any_optimizers_best_inside_the_budget():
    prob = lqr.make_problem("default", {})
    layout = build_layout(prob, "givens", {})
    lb, ub = layout.bounds()

    def objective(Z):
        return prob.evaluate_batch(layout.split(Z)[0])

    settings = optim.with_gradient_cost(optim.make_settings(
        "pso", {"max_evals": 600, "polish": "gradient", "polish_share": 0.5}), prob)
    res = optim.minimize("pso", objective, lb, ub, settings, 3,
                         gradient=lambda z: z_gradient(prob, layout, z))
    assert res.n_evals <= 600 and "+polish" in res.stop_reason
    assert abs(res.best_cost - prob.optimum) <= 1e-8 * prob.optimum
    with pytest.raises(ConfigError, match="exact gradient"):
        optim.minimize("pso", objective, lb, ub, settings, 3)


def test_problem_without_gradient_is_refused_before_any_job():
    from penaltyrun.optim import check_gradient_available
    from penaltyrun.problems.lowthrust import lyapunov_transfer, qlaw

    with pytest.raises(ConfigError, match="piecewise in K"):  # the problem's own reason
        check_gradient_available("lbfgs", {}, qlaw.make_problem(qlaw.DEFAULT_CASE, {}))
    prob = lyapunov_transfer.make_problem(lyapunov_transfer.DEFAULT_CASE, {})
    with pytest.raises(ConfigError, match="optimizer: lbfgs needs the exact gradient"):
        check_gradient_available("lbfgs", {}, prob)
    with pytest.raises(ConfigError, match="optimizer.polish"):
        check_gradient_available("cmaes", {"polish": "gradient"}, prob)
    check_gradient_available("cmaes", {"polish": "L-BFGS-B"}, prob)
    check_gradient_available("lbfgs", {}, lqr.make_problem("default", {}))
