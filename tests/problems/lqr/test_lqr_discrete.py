"""Discrete-time plants (dt) through problem=lqr: the batched discrete Riccati gains against
python-control's dlqr and scipy's solve_discrete_are, the stepped cost against the discrete
Lyapunov closed form, the known optimum, and the plant sources."""

import sys
import textwrap

import numpy as np
import pytest

from penaltyrun.dynamics.riccati import discrete_residual, dlqr_gains
from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.problems.lqr import discrete, reference

control = pytest.importorskip("control")


def random_case(rng, n, m, c, semidefinite=False):
    A = rng.normal(size=(n, n))
    B = rng.normal(size=(n, m))
    M = rng.normal(size=(c, n, n))
    Q = M @ np.swapaxes(M, 1, 2) + 0.1 * np.eye(n)
    if semidefinite:  # rank-one Q = c cᵀ, generically detectable
        v = rng.normal(size=(c, n, 1))
        Q = v @ np.swapaxes(v, 1, 2)
    N = rng.normal(size=(c, m, m))
    R = N @ np.swapaxes(N, 1, 2) + np.eye(m)
    return A, B, Q, R


@pytest.mark.parametrize("n, m", [(1, 1), (2, 1), (4, 2), (7, 3)])
@pytest.mark.parametrize("semidefinite", [False, True])
def test_gains_match_python_control_dlqr(n, m, semidefinite):
    rng = np.random.default_rng(10 * n + m + semidefinite)
    A, B, Q, R = random_case(rng, n, m, 6, semidefinite)
    K, ok, failure = dlqr_gains(A, B, Q, R)
    assert ok.all() and not failure.any()
    for c in range(len(Q)):
        K_ref, P_ref, _ = control.dlqr(A, B, Q[c], R[c])
        np.testing.assert_allclose(K[c], K_ref, rtol=1e-9, atol=1e-9 * np.abs(K_ref).max())
        np.testing.assert_allclose(K[c], reference.discrete_gain(A, B, Q[c], R[c]), rtol=1e-9,
                                   atol=1e-9 * np.abs(K_ref).max())
        assert discrete_residual(A, B, Q[c], R[c], np.asarray(P_ref)) < 1e-10


def test_singular_A_and_unstabilizable_candidates():
    A = np.array([[1.0, 1.0], [0.0, 0.0]])  # singular: doubling needs no inverse of A
    B = np.array([[0.0], [1.0]])
    K, ok, _ = dlqr_gains(A, B, np.eye(2)[None], np.eye(1)[None])
    np.testing.assert_allclose(K[0], control.dlqr(A, B, np.eye(2), np.eye(1))[0], rtol=1e-10)
    A2 = np.diag([1.5, 0.5])  # the unstable mode is not reachable: no gain works
    K, ok, failure = dlqr_gains(A2, np.array([[0.0], [1.0]]), np.eye(2)[None], np.eye(1)[None])
    assert not ok[0] and failure[0] > 0 and not K.any()


PLANT = {"A": [[1.0, 0.1], [0.0, 1.0]], "B": [[0.005], [0.1]], "dt": 0.1,
         "x0": [[1.0, 0.0], [0.0, 1.0], [1.0, -1.0]], "t_max": 30.0,
         "state_weight": [[2.0, 0.5], [0.5, 1.0]], "input_weight": [0.5]}


def test_stepped_cost_matches_the_discrete_lyapunov_closed_form():
    prob = lqr.make_problem("default", {**PLANT, "t_max": 3.05})
    Q, R = np.array([[3.0, 1.0], [1.0, 2.0]]), np.array([[0.7]])
    out = prob.evaluate({"Q": Q, "R": R})
    steps = discrete.n_steps(3.05, 0.1)
    assert steps == 31
    ref = reference.discrete_linear_cost(prob.plant.A, prob.plant.B, Q, R, prob.Wx, prob.Wu,
                                         prob.x0, steps)
    np.testing.assert_allclose(out["start_costs"], ref, rtol=1e-12)
    assert out["method"] == "stepped" and out["dt"] == 0.1
    K_ref = reference.discrete_gain(prob.plant.A, prob.plant.B, Q, R)
    np.testing.assert_allclose(out["gain"], K_ref, rtol=1e-9)
    poles = np.array(out["closed_loop_poles"])
    assert np.all(np.hypot(poles[:, 0], poles[:, 1]) < 1.0)


def test_known_optimum_is_reached_by_the_performance_weights():
    prob = lqr.make_problem("default", PLANT)
    out = prob.evaluate({"Q": prob.Wx, "R": prob.Wu})
    assert out["cost"] == pytest.approx(out["optimum"], rel=1e-9)
    worse = prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})
    assert worse["cost"] > out["cost"]


def test_saturation_divergence_and_plots():
    prob = lqr.make_problem("default", {**PLANT, "u_max": 0.5})
    sim = prob.simulate({"Q": np.eye(2), "R": np.eye(1)})
    assert sim["t"][1] == pytest.approx(0.1) and np.abs(sim["u"]).max() <= 0.5 + 1e-15
    out = prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})
    np.testing.assert_allclose(sim["J"][:, -1], out["start_costs"], rtol=1e-12)
    unstable = lqr.make_problem("default", {"A": [[1.2]], "B": [[1.0]], "dt": 1.0,
                                            "u_max": 0.01, "x0": [[10.0]], "t_max": 200.0})
    res = unstable.evaluate({"Q": np.eye(1), "R": np.eye(1)})
    assert res["status"] == "diverged" and res["t_final"] < 200.0
    assert res["cost"] > 2 * res["failure_penalty"]


PLANTS = '''
import numpy as np
import control

sys_d = control.ss([[1.0, 0.1], [0.0, 1.0]], [[0.005], [0.1]], np.eye(2), np.zeros((2, 1)), 0.1)
sys_true = control.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]], True)
'''


@pytest.fixture
def plants(tmp_path, monkeypatch):
    (tmp_path / "lqr_discrete_plants.py").write_text(textwrap.dedent(PLANTS))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    sys.modules.pop("lqr_discrete_plants", None)


def test_discrete_statespace_brings_its_dt(plants):
    prob = lqr.make_problem("default", {"plant": "lqr_discrete_plants:sys_d"})
    assert prob.dt == 0.1
    with pytest.raises(ConfigError, match="unspecified sampling time"):
        lqr.make_problem("default", {"plant": "lqr_discrete_plants:sys_true"})


@pytest.mark.parametrize("params, key, words", [
    ({"A": [[1.5, 0], [0, 0.5]], "B": [[0], [1]], "dt": 0.1}, "problem.params.B",
     "not stabilizable"),
    ({"A": [[0.5]], "B": [[1]], "dt": 0.0}, "problem.params.dt", "> 0"),
    ({"A": [[0.5]], "B": [[1]], "dt": 0.1, "dynamics": "math:sin"}, "problem.params.dt",
     "must be linear"),
])
def test_bad_discrete_input(params, key, words):
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", params)
    assert err.value.key == key and words in str(err.value)


@pytest.mark.parametrize("steps", [1, 2, 3, 7, 64, 301])
def test_doubling_sum_equals_stepping(steps):
    rng = np.random.default_rng(steps)
    A, B, Q, R = random_case(rng, 3, 2, 4)
    A = 0.9 * A / np.max(np.abs(np.linalg.eigvals(A)))
    K, ok, _ = dlqr_gains(A, B, Q, R)
    X0 = rng.normal(size=(5, 3))
    Wx, Wu = np.diag([1.0, 2.0, 0.5]), np.diag([0.3, 1.0])
    W = Wx + np.swapaxes(K, 1, 2) @ Wu @ K
    cost, x_end = discrete.linear_sum(A - B @ K, W, X0, steps)
    run = discrete.simulate(A, B, np.repeat(K, 5, 0), np.tile(X0, (4, 1)), Wx, Wu, None,
                            steps, 1e12)
    np.testing.assert_allclose(cost, run["cost"].reshape(4, 5), rtol=1e-11)
    np.testing.assert_allclose(x_end, run["x_final"].reshape(4, 5, 3), rtol=1e-9,
                               atol=1e-12)


def test_batch_costs_take_the_closed_form_path():
    prob = lqr.make_problem("default", {**PLANT, "t_max": 3.05})
    Q = np.stack([np.eye(2), np.diag([3.0, 0.2])])
    R = np.stack([np.eye(1), 2 * np.eye(1)])
    batch = prob.evaluate_batch({"Q": Q, "R": R})
    for c in range(2):
        ref = reference.discrete_linear_cost(prob.plant.A, prob.plant.B, Q[c], R[c], prob.Wx,
                                             prob.Wu, prob.x0, 31)
        assert batch.cost[c] == pytest.approx(ref.mean(), rel=1e-12)


def test_default_cost_unit_says_summed_over_steps():
    prob = lqr.make_problem("default", PLANT)
    assert "summed over steps" in prob.cost_unit
    assert "summed over steps" in lqr.report_info("default", PLANT).cost_unit
    assert "Σ" in lqr.report_info("default", PLANT).cost_name
    named = lqr.make_problem("default", {**PLANT, "cost_unit": "m^2"})
    assert named.cost_unit == "m^2"


def test_yaml_plant_file_with_expressions_and_dt(tmp_path):
    (tmp_path / "plant.yaml").write_text(
        "constants: {Ts: 0.1, h: 'Ts**2/2'}\nA: [[1, Ts], [0, 1]]\nB: [[h], [Ts]]\ndt: Ts\n")
    prob = lqr.make_problem("default", {"plant_file": str(tmp_path / "plant.yaml")})
    assert prob.dt == 0.1
    np.testing.assert_allclose(prob.plant.B, [[0.005], [0.1]], rtol=1e-15)
    with pytest.raises(ConfigError, match="has dt = 0.1"):
        lqr.make_problem("default", {"plant_file": str(tmp_path / "plant.yaml"), "dt": 0.2})
    (tmp_path / "bad.yaml").write_text("A: [[1]]\nB: [[1]]\nC: [[1]]\n")
    with pytest.raises(ConfigError, match="unknown key 'C'"):
        lqr.make_problem("default", {"plant_file": str(tmp_path / "bad.yaml")})
    (tmp_path / "evil.yaml").write_text("A: [['__import__(\"os\")']]\nB: [[1]]\n")
    with pytest.raises(ConfigError, match="not an allowed function"):
        lqr.make_problem("default", {"plant_file": str(tmp_path / "evil.yaml")})
