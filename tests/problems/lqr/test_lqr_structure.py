"""Semi-definite Q (q_output, q_fixed) with its detectability check, and integral action
(integral_outputs), through problem=lqr against python-control's lqr / dlqr."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr

control = pytest.importorskip("control")

# Double integrator, position measured: python-control's examples weight Q = CᵀC.
A2 = [[0.0, 1.0], [0.0, 0.0]]
B2 = [[0.0], [1.0]]
C2 = np.array([[1.0, 0.0]])


@pytest.mark.parametrize("dt", [None, 0.05])
def test_q_equals_ct_q_c_matches_python_control(dt):
    A, B = np.array(A2), np.array(B2)
    if dt:
        A, B = np.eye(2) + dt * A, dt * B + 0.5 * dt**2 * np.array(A2) @ B
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(), "dt": dt,
                                        "q_output": C2.tolist()})
    assert [s.size for s in prob.matrices] == [1, 1]
    design = control.dlqr if dt else control.lqr
    for q, r in ((1.0, 1.0), (37.0, 0.02), (0.01, 50.0)):
        out = prob.evaluate({"Q": [[q]], "R": [[r]]})
        Q = q * C2.T @ C2
        np.testing.assert_array_equal(out["state_penalty"], Q)
        K_ref = design(A, B, Q, np.array([[r]]))[0]
        np.testing.assert_allclose(out["gain"], K_ref, rtol=1e-9)


def test_fixed_part_adds_to_the_structured_tuned_part():
    rng = np.random.default_rng(5)
    A, B = rng.normal(size=(4, 4)), rng.normal(size=(4, 2))
    C = rng.normal(size=(2, 4))
    Q0 = np.diag([0.0, 0.3, 0.0, 0.0])
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(),
                                        "q_output": C.tolist(), "q_fixed": [0, 0.3, 0, 0]})
    Qt = np.array([[2.0, 0.4], [0.4, 0.5]])
    R = np.diag([0.3, 2.0])
    out = prob.evaluate({"Q": Qt, "R": R})
    np.testing.assert_allclose(out["state_penalty"], C.T @ Qt @ C + Q0, rtol=1e-15)
    np.testing.assert_allclose(out["gain"], control.lqr(A, B, C.T @ Qt @ C + Q0, R)[0],
                               rtol=1e-9)


@pytest.mark.parametrize("params, key, words", [
    # velocity only: the double integrator's position mode (s = 0) is invisible
    ({"A": A2, "B": B2, "q_output": [[0, 1]]}, "problem.params.q_output",
     "mode of A at 0+0j (states 0, 0-based)"),
    ({"A": [[1, 0], [0, -1]], "B": [[1], [1]], "q_fixed": [0, 1], "q_output": [[0, 1]]},
     "problem.params.q_output", "mode of A at 1+0j (states 0, 0-based)"),
    ({"A": [[1.2, 0], [0, 0.5]], "B": [[1], [1]], "dt": 0.1, "q_output": [[0, 1]]},
     "problem.params.q_output", "mode of A at 1.2+0j"),
    ({"A": [[1.2, 0], [0, 0.5]], "B": [[1], [1]], "dt": 0.1, "q_output": [[0, 1]],
      "q_fixed": [[1, 0], [0, -1]]}, "problem.params.q_fixed", "semi-definite"),
    ({"A": A2, "B": B2, "q_output": [[1, 0, 0]]}, "problem.params.q_output", "2 numbers"),
])
def test_undetectable_or_bad_structure_is_one_clear_error(params, key, words):
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", params)
    assert err.value.key == key and words in str(err.value)
    assert "\n" not in str(err.value)
    if "detectable" in str(err.value):
        assert "add a row to q_output" in str(err.value)


def test_stable_unweighted_modes_are_fine():
    prob = lqr.make_problem("default", {"A": [[-1, 0], [0, 0.5]], "B": [[1], [1]],
                                        "q_output": [[0, 1]]})
    assert prob.evaluate({"Q": [[1.0]], "R": [[1.0]]})["status"] == "converged"


@pytest.mark.parametrize("dt", [None, 0.1])
def test_integral_action_is_the_lqr_of_the_augmented_plant(dt):
    A = np.array([[0.0, 1.0], [-2.0, -0.5]])
    B = np.array([[0.0], [1.0]])
    if dt:
        A, B = np.eye(2) + dt * A, dt * B
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(), "dt": dt,
                                        "integral_outputs": [[1, 0]],
                                        "x0": [[1, 0], [0, 1]]})
    Aa = np.zeros((3, 3))
    Aa[:2, :2] = A
    Aa[2, :2] = [dt or 1.0, 0.0]
    if dt:
        Aa[2, 2] = 1.0
    Ba = np.vstack([B, [[0.0]]])
    np.testing.assert_allclose(prob.plant.A, Aa)
    np.testing.assert_allclose(prob.x0, [[1, 0, 0], [0, 1, 0]])
    np.testing.assert_allclose(prob.Wx, np.diag([1.0, 1.0, 0.0]))
    Q = np.diag([1.0, 0.5, 4.0])
    out = prob.evaluate({"Q": Q, "R": [[0.2]]})
    design = control.dlqr if dt else control.lqr
    np.testing.assert_allclose(out["gain"], design(Aa, Ba, Q, np.array([[0.2]]))[0], rtol=1e-9)
    assert out["status"] == "converged"
    assert prob.holdout_states().shape[1] == 3 and not prob.holdout_states()[:, 2].any()


def test_integrating_an_output_with_a_zero_at_the_origin_is_refused():
    # velocity of a damped oscillator: transfer s / (s² + s + 1), a zero at s = 0
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", {"A": [[0, 1], [-1, -1]], "B": [[0], [1]],
                                     "integral_outputs": [[0, 1]]})
    assert err.value.key == "problem.params.integral_outputs"
    assert "zero at s = 0" in str(err.value)


def test_evaluate_accepts_python_controls_semidefinite_q():
    prob = lqr.make_problem("default", {"A": A2, "B": B2})
    out = prob.evaluate({"Q": C2.T @ C2, "R": [[1.0]]})  # zeros on the diagonal
    np.testing.assert_allclose(out["gain"], control.lqr(np.array(A2), np.array(B2),
                                                        C2.T @ C2, np.eye(1))[0], rtol=1e-9)
    with pytest.raises(ConfigError) as err:
        prob.evaluate({"Q": [[0.0, 0.0], [0.0, 1.0]], "R": [[1.0]]})
    assert err.value.key == "matrices.Q" and "weight one of these states" in str(err.value)
    with pytest.raises(ConfigError, match="not positive semi-definite"):
        prob.evaluate({"Q": [[1.0, 0.0], [0.0, -1.0]], "R": [[1.0]]})


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 5), seed=st.integers(0, 2**31 - 1), discrete=st.booleans())
def test_pbh_detectability_matches_the_modes_built_invisible(n, seed, discrete):
    # A = T diag(λ) T⁻¹ with distinct real modes; C sees mode i iff column i of C T is not 0
    from penaltyrun.problems.lqr.plant import check_detectable

    rng = np.random.default_rng(seed)
    lam = rng.permutation(np.linspace(-1.5, 1.5, n) + rng.uniform(-0.1, 0.1))
    lam = lam + 0.05 * np.sign(lam)  # keep away from the stability boundary
    if discrete:
        lam = 1.0 + 0.4 * lam      # |λ| < 1 ⇔ the continuous mode was stable
    T = rng.normal(size=(n, n)) + 2 * np.eye(n)
    A = T @ np.diag(lam) @ np.linalg.inv(T)
    seen = rng.random(n) < 0.5
    M = rng.normal(size=(n, n)) * seen  # columns of invisible modes are zero
    C = M @ np.linalg.inv(T)
    stable = np.abs(lam) < 1.0 if discrete else lam < 0.0
    expected = bool(np.all(seen | stable))
    try:
        check_detectable(A, C, "k", 0.1 if discrete else None)
        found = True
    except ConfigError:
        found = False
    assert found == expected
