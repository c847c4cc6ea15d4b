"""Exact gradient of the Zermelo cost d J / d K (closed form): against complex-step
derivatives of an independent complex-analytic implementation (Cayley–Hamilton matrix
exponential, complex Newton for the event time, fixed composite Gauss–Legendre), against
central differences of the problem's own cost through every map, the Fréchet derivative
against scipy's ``expm_frechet``, and the points where no gradient exists (reported with a
reason, never a number)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm_frechet

import penaltyrun
from penaltyrun.dynamics import zermelo_sens
from penaltyrun.optim.gradient import z_gradient
from penaltyrun.penalty import NotDifferentiableError
from penaltyrun.problems import zermelo
from penaltyrun.runner.setup import build_layout

H_CS = 1e-30
GL_X, GL_W = np.polynomial.legendre.leggauss(20)
SYM = [(0, 0), (1, 1), (0, 1)]


def _unit(i, j):
    E = np.zeros((2, 2))
    E[i, j] = E[j, i] = 1.0
    return E


def _gain(rng, lo=0.05, hi=5.0):
    lam = rng.uniform(lo, hi, 2)
    th = rng.uniform(0.0, np.pi)
    V = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    return V @ np.diag(lam) @ V.T


def _expm2(A, t):
    """e^{A t} of a 2 × 2 A at the times t (P,) by Cayley–Hamilton (complex-analytic)."""
    m = 0.5 * (A[0, 0] + A[1, 1])
    q = np.sqrt(complex(m * m - (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0])))
    qt = q * np.asarray(t, dtype=complex)
    sh = np.sinh(qt) / q if q != 0 else np.asarray(t, dtype=complex)
    N = A - m * np.eye(2)
    return np.exp(m * t)[:, None, None] * (np.cosh(qt)[:, None, None] * np.eye(2)
                                           + sh[:, None, None] * N)


def _reference_cost(K, x0, r, scale, panels=60):
    """J of a (complex) K: T by complex Newton on XᵀX = r² (no conjugate), J by composite
    Gauss–Legendre in s = ln(1 + scale·t) (scale a fixed real number)."""
    lam_min = np.linalg.eigvalsh(K.real)[0]
    T = complex(np.log(np.linalg.norm(x0) / r) / lam_min / 2)
    for _ in range(200):
        X = _expm2(-K, np.array([T]))[0] @ x0
        step = (X @ X - r * r) / (-2.0 * X @ (K @ X))
        T -= step
        if abs(step) < 1e-15 * abs(T):
            break
    S = np.log(1.0 + scale * T)
    u = (np.arange(panels)[:, None] + 0.5 * (GL_X[None, :] + 1.0)) / panels
    s = S * u.ravel()
    w = np.tile(GL_W, panels) * 0.5 / panels * S
    t = np.expm1(s) / scale
    X = _expm2(-K, t) @ x0
    c = np.cos(X[:, 1]) * np.sin(X[:, 0])
    U = c[:, None] * X - X @ K.T
    return np.sum(w * 0.5 * np.sum(U * U, axis=1) * np.exp(s) / scale)


@pytest.mark.parametrize("seed", range(4))
def test_gradient_matches_complex_step_of_an_independent_implementation(seed):
    prob = zermelo.make_problem("default", {})
    p = prob.params
    K = _gain(np.random.default_rng(seed))
    x0 = np.asarray(p.x0)
    scale = float(np.linalg.eigvalsh(K)[-1])
    out = prob.gradient({"K": K})
    assert out.exists and out.reason == "" and out.status == "converged"
    assert out.cost == prob.evaluate_batch({"K": K[None]}).cost[0]
    assert _reference_cost(K.astype(complex), x0, p.event_radius, scale).real == \
        pytest.approx(out.cost, rel=1e-10)
    for i, j in SYM:
        E = _unit(i, j)
        cs = _reference_cost(K + 1j * H_CS * E, x0, p.event_radius, scale).imag / H_CS
        assert float(np.sum(out.matrices["K"] * E)) == pytest.approx(cs, rel=1e-9, abs=1e-12)


def test_frechet_derivative_of_the_exponential_matches_scipy():
    rng = np.random.default_rng(5)
    for K in (_gain(rng), np.diag([0.7, 0.7]), np.diag([1e-8, 10.0]) + 1e-9 * _unit(0, 1)):
        lam, V = np.linalg.eigh(K)
        for t in (0.0, 0.3, 7.0, 250.0):
            D = zermelo_sens._divided(lam, np.array([t]))[0]
            for i, j in SYM:
                E = _unit(i, j)
                ours = V @ (D * (V.T @ E @ V)) @ V.T
                ref = expm_frechet(-K * t, -E * t, compute_expm=False)
                np.testing.assert_allclose(ours, ref, rtol=1e-9, atol=1e-12 * np.exp(-lam[0] * t))


def _cd(f, h):
    """Central difference of f at 0 with Richardson extrapolation (error O(h⁴))."""
    return (4.0 * (f(h / 2) - f(-h / 2)) / h - (f(h) - f(-h)) / (2 * h)) / 3.0


@pytest.mark.parametrize("param", ["diagonal", "givens", "cayley", "full"])
def test_z_gradient_matches_central_differences_through_every_map(param):
    prob = zermelo.make_problem("default", {})
    layout = build_layout(prob, param, {})
    lb, ub = layout.bounds()
    rng = np.random.default_rng(11)
    for _ in range(2):
        z = lb + (ub - lb) * rng.uniform(0.05, 0.5, lb.size)
        try:
            out = z_gradient(prob, layout, z)
        except NotDifferentiableError:  # pragma: no cover - GEAGSP skip, not drawn here
            continue
        assert out.exists, out.reason

        for i in range(z.size):
            e = np.zeros(z.size)

            def f(s, i=i, e=e, z=z):
                e[:] = 0.0
                e[i] = s
                mats = layout.split((z + e)[None])[0]
                return prob.evaluate_batch(mats).cost[0]

            h = 1e-4 * max(1.0, abs(z[i]))
            assert out.grad[i] == pytest.approx(_cd(f, h), rel=1e-6, abs=1e-9 * out.cost), \
                (param, layout.names()[i])


def test_repeated_eigenvalues_and_the_paper_gains():
    prob = zermelo.make_problem("default", {})
    for K in (np.diag([0.6, 0.6]), zermelo.PAPER_K_DIAGONAL, zermelo.PAPER_K_FULL):
        out = prob.gradient({"K": K})
        assert out.exists
        for i, j in SYM:
            E = _unit(i, j)

            def f(s, E=E, K=K):
                return prob.evaluate_batch({"K": (K + s * E)[None]}).cost[0]

            assert float(np.sum(out.matrices["K"] * E)) == pytest.approx(_cd(f, 1e-4),
                                                                         rel=1e-6)


def test_without_arrival_the_graded_penalty_has_its_gradient_and_none_at_the_switch():
    K = np.diag([0.02, 0.05])
    T = float(zermelo.make_problem("default", {})._run(K[None])[0][0])
    late = zermelo.make_problem("default", {"t_max": 0.5 * T})
    out = late.gradient({"K": K})
    assert out.exists and out.status == "horizon"
    assert out.cost == late.evaluate_batch({"K": K[None]}).cost[0]
    for i, j in SYM:
        E = _unit(i, j)

        def f(s, E=E):
            ev = late.evaluate_batch({"K": (K + s * E)[None]})
            assert ev.status[0] == "horizon"
            return ev.cost[0]

        assert float(np.sum(out.matrices["K"] * E)) == pytest.approx(_cd(f, 1e-6), rel=1e-6)
    for t_max in (T * (1 + 1e-12), T * (1 - 1e-12)):  # the status changes next to K
        out = zermelo.make_problem("default", {"t_max": t_max}).gradient({"K": K})
        assert not out.exists and "t_max" in out.reason, out.reason


def test_near_the_deadline_the_gradient_is_none_or_matches_differences():
    """With the event just before t_max (slack 1e-4 of t_max) the gradient exists and
    matches differences small enough to stay on the converged side."""
    K = np.array([[0.05, 0.01], [0.01, 0.03]])
    T = float(zermelo.make_problem("default", {})._run(K[None])[0][0])
    near = zermelo.make_problem("default", {"t_max": T * (1 + 1e-4)})
    out = near.gradient({"K": K})
    assert out.exists
    for i, j in SYM:
        E = _unit(i, j)

        def f(s, E=E):
            ev = near.evaluate_batch({"K": (K + s * E)[None]})
            assert ev.converged[0]
            return ev.cost[0]

        assert float(np.sum(out.matrices["K"] * E)) == pytest.approx(_cd(f, 1e-6), rel=1e-6)


def test_evaluate_gives_grad_in_z_names_order():
    z = [0.8, 0.2]
    out = penaltyrun.evaluate("zermelo", z=z, param="diagonal", gradient=True)
    assert out["gradient_note"] == "" and out["z_names"] == ["K.lam1", "K.lam2"]
    grad = np.asarray(out["grad"])
    for i in range(2):
        def f(s, i=i):
            zz = list(z)
            zz[i] += s
            return penaltyrun.evaluate("zermelo", z=zz, param="diagonal")["cost"]

        assert grad[i] == pytest.approx(_cd(f, 1e-4), rel=1e-6)
    edge = penaltyrun.evaluate("zermelo", z=z, param="diagonal", params={"t_max": 1e3})
    at_edge = penaltyrun.evaluate("zermelo", z=z, param="diagonal", gradient=True,
                                  params={"t_max": edge["t_final"]})
    assert at_edge["grad"] is None and "t_max" in at_edge["gradient_note"]


def test_multi_scenario_gradient_is_the_mean_of_the_starts():
    from penaltyrun import problems

    prob = problems.make("zermelo", None, {"train_scenarios": [{"x0": (-8.0, 6.0)},
                                                               {"x0": (3.0, 4.0)}]})
    K = np.array([[1.2, 0.3], [0.3, 0.7]])
    out = prob.gradient({"K": K})
    assert out.exists
    E = np.array([[1.0, -0.4], [-0.4, 0.5]])

    def f(s):
        return prob.evaluate_batch({"K": (K + s * E)[None]}).cost[0]

    assert float(np.sum(out.matrices["K"] * E)) == pytest.approx(_cd(f, 1e-4), rel=1e-6)


@pytest.mark.slow
def test_lbfgs_and_gradient_polish_reach_a_first_order_point(tmp_path):
    # 400 gradients' worth of budget at Zermelo's declared charge (8.5 evaluations each)
    rec = penaltyrun.tune("zermelo", param="givens", optimizer="lbfgs", n_starts=1, seed=2,
                          optimizer_options={"max_evals": 3400}, workers=1,
                          run_dir=tmp_path / "lbfgs").records.iloc[0]
    assert rec["gradient_note"] == "" and rec["grad_norm"] < 1e-5 * max(1.0, rec["best_cost"])
    pol = penaltyrun.tune("zermelo", param="diagonal", optimizer="cmaes", n_starts=1, seed=2,
                          optimizer_options={"max_evals": 400, "polish": "gradient"},
                          workers=1, run_dir=tmp_path / "polish").records.iloc[0]
    assert "+polish" in pol["stop_reason"] and np.isfinite(pol["grad_norm"])


def test_geagsp_next_to_a_skipped_vector_is_no_gradient():
    for angle in (0.0, 1e-12, np.pi):
        out = penaltyrun.evaluate("zermelo", z=[1.5, 0.4, angle], param="full", gradient=True)
        assert out["grad"] is None and "geagsp" in out["gradient_note"]
        assert out["grad_matrices"] is not None  # d cost / d K itself exists there
    out = penaltyrun.evaluate("zermelo", z=[1.5, 0.4, angle], param="givens", gradient=True)
    assert out["grad"] is not None


@pytest.mark.slow
def test_cli_evaluate_gives_the_librarys_gradient(tmp_path):
    import json
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                           "problem=zermelo", "param=givens", "z=[1.5,0.4,0.7]",
                           "+gradient=true"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    lib = penaltyrun.evaluate("zermelo", z=[1.5, 0.4, 0.7], param="givens", gradient=True)
    assert out["grad"] == lib["grad"] and out["cost"] == lib["cost"]
