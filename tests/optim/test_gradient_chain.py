"""d cost / d z of problem=lqr through every map (exact Riccati gradient × the map's VJP)
against central differences of the cost over z, and the first-order measures (projected
gradient, active bounds)."""

import numpy as np
import pytest

from penaltyrun.optim import gradient as zg
from penaltyrun.problems import lqr
from penaltyrun.problems.lowthrust import lyapunov_transfer
from penaltyrun.runner.setup import build_layout


def _problem(seed, n=3, m=2, dt=None):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    if dt:
        A, B = np.eye(n) + dt * A, dt * B
    return lqr.make_problem("default", {
        "A": A.tolist(), "B": B.tolist(), "x0": rng.normal(size=(2, n)).tolist(),
        "t_max": 3.0, "dt": dt, "q_bounds": [0.1, 10.0], "r_bounds": [0.1, 10.0]}), rng


def _cost(prob, layout, z):
    mats, _ = layout.split(z[None])
    return prob.evaluate_batch(mats).cost[0]


@pytest.mark.parametrize("kind", ["diagonal", "geagsp", "givens", "cayley", "cayley_tan"])
@pytest.mark.parametrize("dt", [None, 0.1])
def test_z_gradient_matches_central_differences(kind, dt):
    prob, rng = _problem(4, dt=dt)
    layout = build_layout(prob, kind, {})
    lb, ub = layout.bounds()
    z = lb + (ub - lb) * rng.uniform(0.2, 0.8, size=lb.size)
    out = zg.z_gradient(prob, layout, z)
    assert out.exists, out.reason
    assert out.grad.shape == (layout.dim,)
    assert out.cost == pytest.approx(_cost(prob, layout, z), rel=1e-12)
    for i in range(layout.dim):
        h = 1e-3 * max(1.0, abs(z[i]))
        e = np.zeros(layout.dim)
        e[i] = h
        d1 = (_cost(prob, layout, z + e) - _cost(prob, layout, z - e)) / (2 * h)
        d2 = (_cost(prob, layout, z + e / 2) - _cost(prob, layout, z - e / 2)) / h
        cd = (4 * d2 - d1) / 3
        assert out.grad[i] == pytest.approx(cd, rel=1e-6, abs=1e-8 * abs(out.cost)), i


def test_without_gradient_hook_the_reason_is_one_line():
    prob = lyapunov_transfer.make_problem(lyapunov_transfer.DEFAULT_CASE, {})
    layout = build_layout(prob, "diagonal", {})
    lb, ub = layout.bounds()
    out = zg.z_gradient(prob, layout, 0.5 * (lb + ub))
    assert not out.exists and "no gradient" in out.reason
    rec = zg.first_order(prob, layout, 0.5 * (lb + ub))
    assert np.isnan(rec["grad_norm"]) and rec["gradient_note"] == out.reason


def test_projected_gradient_and_active_bounds():
    lb, ub = np.zeros(3), np.ones(3)
    z = np.array([0.0, 0.5, 1.0])
    g = np.array([2.0, 0.0, 3.0])  # pushes the first out of the box, the last inside
    np.testing.assert_allclose(zg.projected_gradient(z, g, lb, ub), [0.0, 0.0, -1.0])
    assert zg.active_bounds(z, lb, ub, ["a", "b", "c"]) == ["a=lower", "c=upper"]
    prob, _ = _problem(1)
    layout = build_layout(prob, "diagonal", {})
    plb, pub = layout.bounds()
    rec = zg.first_order(prob, layout, plb)
    assert rec["gradient_note"] == ""
    assert np.isfinite(rec["grad_norm"])
    assert len(rec["active_bounds"]) == layout.dim
