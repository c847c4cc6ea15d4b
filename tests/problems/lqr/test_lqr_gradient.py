"""Exact gradient of the problem=lqr cost w.r.t. Q̃ and R: against complex-step derivatives of
an independent implementation (Newton–Kleinman / Hewer iterations with Kronecker solves,
complex-analytic) and against central differences of the problem's own cost, on random
continuous and discrete plants, with structured Q and integral action; and the points where
no gradient exists (reported with a reason, never a number)."""

import numpy as np
import pytest
from scipy.linalg import expm, solve_continuous_are, solve_discrete_are

from penaltyrun.problems import base, lqr
from penaltyrun.problems.lowthrust import lyapunov_transfer

H_CS = 1e-30  # complex step


def _spd(rng, n):
    M = rng.normal(size=(n, n))
    return M @ M.T + n * np.eye(n)


def _plant(seed, n, m, dt=None, **extra):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    if dt:
        A = np.eye(n) + dt * A
        B = dt * B
    params = {"A": A.tolist(), "B": B.tolist(), "x0": rng.normal(size=(3, n)).tolist(),
              "t_max": 2.5, "state_weight": _spd(rng, n).tolist(),
              "input_weight": _spd(rng, m).tolist(), "dt": dt, **extra}
    return lqr.make_problem("default", params), rng


def _lyap_kron(Acl, F, discrete):
    """X with Aclᵀ X + X Acl + F = 0 (discrete: X = Aclᵀ X Acl + F), complex-analytic."""
    n = Acl.shape[0]
    eye = np.eye(n)
    if discrete:
        L = np.eye(n * n) - np.kron(Acl.T, Acl.T)
        return np.linalg.solve(L, F.reshape(-1)).reshape(n, n)
    L = np.kron(Acl.T, eye) + np.kron(eye, Acl.T)
    return np.linalg.solve(L, -F.reshape(-1)).reshape(n, n)


def _reference_cost(prob, Q_ric, R, P0):
    """Cost of (Q_ric, R) by Newton iterations from the real solution P0 and a closed-form
    horizon (complex-analytic in Q_ric and R)."""
    A, B = prob.plant.A, prob.plant.B
    dt = prob.dt
    P = P0.astype(complex)
    for _ in range(8):
        if dt is None:
            K = np.linalg.solve(R, B.T @ P)
            Acl = A - B @ K
            P = _lyap_kron(Acl, Q_ric + K.T @ R @ K, False)
        else:
            K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
            Acl = A - B @ K
            P = _lyap_kron(Acl, Q_ric + K.T @ R @ K, True)
    W = prob.Wx + K.T @ prob.Wu @ K
    X0 = prob.x0
    if dt is None:
        S = _lyap_kron(Acl, W, False)
        E = expm(Acl * prob.t_max)
        M = S - E.T @ S @ E
    else:
        M = np.zeros_like(P)
        Ak = np.eye(A.shape[0], dtype=complex)
        for _ in range(lqr.discrete.n_steps(prob.t_max, dt)):
            M = M + Ak.T @ W @ Ak
            Ak = Acl @ Ak
    return np.mean(np.einsum("ki,ij,kj->k", X0, M, X0))


def _perturbed(prob, Qt, R, name, E, step):
    C, Q0 = prob.q_output, prob.q_fixed
    if name == "Q":
        return C.T @ (Qt + step * E) @ C + Q0, R + 0 * step
    return C.T @ Qt @ C + Q0 + 0 * step, R + step * E


def _riccati(prob, Qt, R):
    solve = solve_continuous_are if prob.dt is None else solve_discrete_are
    return solve(prob.plant.A, prob.plant.B, prob.q_output.T @ Qt @ prob.q_output
                 + prob.q_fixed, R)


def _complex_step(prob, Qt, R, name, E):
    P0 = _riccati(prob, Qt, R)
    return _reference_cost(prob, *_perturbed(prob, Qt, R, name, E, 1j * H_CS), P0).imag / H_CS


def _central(prob, Qt, R, name, E):
    """Central differences (Richardson, error O(h⁴)) of the reference cost, refined to
    round-off by its Newton iterations."""
    P0 = _riccati(prob, Qt, R)

    def f(s):
        return _reference_cost(prob, *_perturbed(prob, Qt, R, name, E, s), P0).real

    h = 1e-3 * max(1.0, float(np.abs(Qt if name == "Q" else R).max()))
    d1 = (f(h) - f(-h)) / (2 * h)
    d2 = (f(h / 2) - f(-h / 2)) / h
    return (4 * d2 - d1) / 3


CASES = [
    ({"n": 3, "m": 1}, {}),
    ({"n": 4, "m": 2}, {}),
    ({"n": 5, "m": 2, "dt": 0.05}, {}),
    ({"n": 4, "m": 2}, {"q_output": [[1.0, 0.5, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]],
                        "q_fixed": np.diag([0.0, 0.0, 0.0, 0.3]).tolist()}),
    ({"n": 3, "m": 2, "dt": 0.1}, {"q_output": [[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]],
                                   "q_fixed": np.diag([0.0, 0.0, 0.5]).tolist()}),
    ({"n": 3, "m": 1}, {"integral_outputs": [[1.0, 0.0, 0.0]]}),
]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("shape", "extra"), CASES)
def test_gradient_matches_complex_step_and_central_differences(seed, shape, extra):
    prob, rng = _plant(seed, **shape, **extra)
    p = prob.matrices[0].size
    m = prob.matrices[1].size
    Qt, R = _spd(rng, p), _spd(rng, m)
    grad = prob.gradient({"Q": Qt, "R": R})
    assert grad.exists, grad.reason
    assert grad.status == "converged"
    assert grad.cost == pytest.approx(prob.evaluate_batch({"Q": Qt[None], "R": R[None]}).cost[0],
                                      rel=1e-12)
    assert grad.cost == pytest.approx(_reference_cost(prob, prob.state_penalty(Qt[None])[0],
                                                      R, _riccati(prob, Qt, R)).real, rel=1e-8)
    for name, size in (("Q", p), ("R", m)):
        G = grad.matrices[name]
        assert G.shape == (size, size)
        np.testing.assert_allclose(G, G.T, atol=1e-12 * np.abs(G).max())
        for _ in range(2):
            E = rng.normal(size=(size, size))
            E = E + E.T
            exact = float(np.sum(G * E))
            cs = _complex_step(prob, Qt, R, name, E)
            assert exact == pytest.approx(cs, rel=1e-8, abs=1e-12 * abs(grad.cost))
            cd = _central(prob, Qt, R, name, E)
            assert exact == pytest.approx(cd, rel=1e-6, abs=1e-9 * abs(grad.cost))


def test_long_horizon_and_fast_poles_stay_finite():
    """e^{A_cl T} of a fast loop underflows instead of overflowing (no e^{−Aᵀ T} anywhere)."""
    prob, rng = _plant(3, 3, 1, t_max=200.0)
    Qt, R = 1e4 * np.eye(3), 1e-3 * np.eye(1)
    grad = prob.gradient({"Q": Qt, "R": R})
    assert grad.exists
    E = np.eye(3)
    exact = float(np.sum(grad.matrices["Q"] * E))
    assert np.all(np.isfinite(grad.matrices["R"]))
    assert exact == pytest.approx(_complex_step(prob, Qt, R, "Q", E), rel=1e-8)
    assert exact == pytest.approx(_central(prob, Qt, R, "Q", E), rel=1e-6)


@pytest.mark.parametrize(("extra", "words"), [
    ({"u_max": [0.5]}, "simulated"),
    ({"settle_tol": 1e-30}, "not_settled"),
    ({"disk_margin_min": 1.99}, "constraint"),
    ({"settling_time_max": 1.0}, "sampled responses"),
])
def test_no_gradient_is_a_reason_never_a_number(extra, words):
    prob, _ = _plant(0, 3, 1, **extra)
    grad = prob.gradient({"Q": np.eye(3), "R": np.eye(1)})
    assert not grad.exists
    assert grad.matrices is None
    assert words in grad.reason
    assert "\n" not in grad.reason


def test_nonlinear_dynamics_have_no_gradient(tmp_path, monkeypatch):
    (tmp_path / "lqr_grad_pendulum.py").write_text(
        "import numpy as np\n\n\ndef f(X, U):\n"
        "    return np.stack([X[:, 1], 9.81 * np.sin(X[:, 0]) + U[:, 0]], axis=1)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    prob = lqr.make_problem("default", {"dynamics": "lqr_grad_pendulum:f",
                                        "x0": [[0.3, 0.0]], "t_max": 2.0,
                                        "input_weight": [[1.0]]})
    grad = prob.gradient({"Q": np.eye(2), "R": np.eye(1)})
    assert not grad.exists and "simulated" in grad.reason


def test_gradient_capability_is_optional_and_named():
    prob, _ = _plant(0, 3, 1)
    assert isinstance(prob, base.GradientProblem)
    assert base.gradient_support(prob) == ""
    other = lyapunov_transfer.make_problem(lyapunov_transfer.DEFAULT_CASE, {})
    reason = base.gradient_support(other)
    assert "no gradient" in reason and "\n" not in reason


@pytest.mark.parametrize("how", ["mean", "max", "quantile"])
def test_multi_scenario_gradient_is_the_aggregates(how):
    """Several training scenarios: the gradient of their mean (max, 0.6 quantile: an
    interpolation of two of three scenarios) against central differences of the aggregate,
    never the base scenario's alone."""
    from penaltyrun import problems

    extra = {"train_quantile": 0.6} if how == "quantile" else {}
    scenarios = [{"x0": [[1, 0, 0]]}, {"x0": [[0, 2, 1]]}]
    if how == "quantile":
        scenarios.append({"x0": [[0.5, -1, 2]]})
    prob = problems.make("lqr", None, {"train_scenarios": scenarios,
                                       "train_aggregate": how, **extra})
    Qt, R = np.diag([2.0, 1.0, 3.0]), np.diag([1.0, 0.5])
    grad = prob.gradient({"Q": Qt, "R": R})
    assert grad.exists
    E = np.array([[1.0, 0.3, 0.0], [0.3, -1.0, 0.2], [0.0, 0.2, 0.5]])

    def f(s):
        return prob.evaluate_batch({"Q": (Qt + s * E)[None], "R": R[None]}).cost[0]

    h = 1e-3
    cd = (4 * (f(h / 2) - f(-h / 2)) / h - (f(h) - f(-h)) / (2 * h)) / 3
    assert float(np.sum(grad.matrices["Q"] * E)) == pytest.approx(cd, rel=1e-6)
    plain = problems.make("lyapunov_transfer", None,
                          {"train_scenarios": [{"e0": 0.01}, {"e0": 0.02}]})
    assert "no gradient" in base.gradient_support(plain)


def test_an_evaluation_then_its_gradient_solve_the_point_once_and_match_a_fresh_problem(
        monkeypatch):
    prob, rng = _plant(11, 4, 2)
    fresh, _ = _plant(11, 4, 2)
    Q, R = _spd(rng, 4), _spd(rng, 2)
    solves = []
    original = prob._rows
    monkeypatch.setattr(prob, "_rows", lambda *a: solves.append(1) or original(*a))
    cost = prob.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]
    out = prob.gradient({"Q": Q, "R": R})
    assert len(solves) == 1  # the gradient reused the evaluation's rows
    ref = fresh.gradient({"Q": Q, "R": R})
    assert out.cost == ref.cost == cost
    for name in ("Q", "R"):
        np.testing.assert_array_equal(out.matrices[name], ref.matrices[name])
    # another point, a batch, other starts or report metrics are computed, never served
    prob.gradient({"Q": Q + np.eye(4), "R": R})
    prob.evaluate_batch({"Q": np.stack([Q, Q]), "R": np.stack([R, R])})
    prob.rows(Q[None], R[None], prob.x0[:1])
    prob.rows(Q[None], R[None], prob.x0, metrics=True)
    assert len(solves) == 5
    # a point one ulp away is a new point
    prob.rows(np.nextafter(Q, np.inf)[None], R[None], prob.x0)
    assert len(solves) == 6


def test_the_gradient_from_the_evaluation_s_loop_equals_one_solved_afresh():
    """The gradient reuses the evaluation's Schur decomposition, S and e^{A_cl T}; solving
    them again gives the same gradient to round-off."""
    from penaltyrun.problems.lqr.gradient import gain_gradient

    prob, rng = _plant(13, 5, 2)
    Q, R = _spd(rng, 5), _spd(rng, 2)
    res = prob.rows(Q[None], R[None], prob.x0)
    assert res["loop"] is not None
    shared = gain_gradient(prob, Q, R, res["K"][0], res["loop"])
    afresh = gain_gradient(prob, Q, R, res["K"][0])
    assert shared[0] == pytest.approx(afresh[0], rel=1e-13)
    for a, b in zip(shared[1:], afresh[1:]):
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-13 * np.abs(b).max())
    assert prob.rows(np.stack([Q, Q]), np.stack([R, R]), prob.x0)["loop"] is None


def test_a_copy_at_another_horizon_never_answers_from_the_original_s_rows():
    from penaltyrun.problems.horizon import at_horizon

    prob, rng = _plant(12, 3, 1)
    Q, R = _spd(rng, 3), _spd(rng, 1)
    short = prob.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]
    longer = at_horizon(prob, 4 * prob.t_max, t_max=4 * prob.t_max)
    fresh = at_horizon(_plant(12, 3, 1)[0], 4 * prob.t_max, t_max=4 * prob.t_max)
    cost = longer.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]
    assert cost == fresh.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]
    assert cost != short
    assert prob.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0] == short
