"""Closed-loop diagnostics (``closed_loop`` hook, penaltyrun/problems/diagnostics.py) against
closed loops built independently here: python-control's ``lqr`` / ``dlqr`` gains and finite
differences of the nonlinear dynamics with the law applied; the formulas on hand-made
matrices."""

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun import problems
from penaltyrun.problems import diagnostics as dg
from penaltyrun.problems.attitude.reference import _rhs_numpy
from penaltyrun.problems.base import ClosedLoop
from penaltyrun.problems.mpc import rendezvous as rz


def spd(rng, n, lo=0.2, hi=5.0):
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    M = Q @ np.diag(rng.uniform(lo, hi, n)) @ Q.T
    return 0.5 * (M + M.T)


def sorted_eig(values):
    values = np.asarray(values, complex)
    return values[np.lexsort((values.imag, values.real))]


def assert_same_eigs(a, b, tol=1e-8):
    a, b = sorted_eig(a), sorted_eig(b)
    assert a.shape == b.shape
    assert np.max(np.abs(a - b)) <= tol * max(1.0, np.max(np.abs(b)))


def check_columns(loop, a_cl, gain):
    """The stored columns equal numpy.linalg.eig of the independent closed loop."""
    cols = dg.columns(loop)
    eig = np.linalg.eig(a_cl)[0]
    assert_same_eigs(np.asarray(cols["cl_eig_real"]) + 1j * np.asarray(cols["cl_eig_imag"]),
                     eig)
    if loop.time == "continuous":
        s = eig
    else:
        s = np.log(eig.astype(complex)) / loop.dt
    assert cols["cl_slowest_real"] == pytest.approx(np.max(s.real), rel=1e-7, abs=1e-12)
    zeta = -s.real / np.abs(s)
    assert cols["cl_min_damping"] == pytest.approx(np.min(zeta), rel=1e-7, abs=1e-9)
    sv = np.linalg.svd(gain, compute_uv=False)
    assert cols["cl_gain_norm"] == pytest.approx(np.linalg.norm(gain, 2), rel=1e-10)
    assert cols["cl_gain_cond"] == pytest.approx(sv[0] / sv[-1], rel=1e-8)
    return cols


@pytest.mark.parametrize("seed", range(3))
def test_lqr_closed_loop_is_a_minus_bk_with_python_control_gain(seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(4, 4))
    B = rng.normal(size=(4, 2))
    prob = problems.make("lqr", "default", {"A": A.tolist(), "B": B.tolist(),
                                            "x0": [[1.0, 0, 0, 0]]})
    Q, R = spd(rng, 4), spd(rng, 2)
    K, _, _ = control.lqr(A, B, Q, R)
    loop = prob.closed_loop({"Q": Q, "R": R})
    assert loop.time == "continuous" and loop.gain.shape == (2, 4)
    np.testing.assert_allclose(loop.gain, K, rtol=1e-8, atol=1e-10)
    assert loop.state_names == ("x1", "x2", "x3", "x4") and loop.input_names == ("u1", "u2")
    check_columns(loop, A - B @ np.asarray(K), np.asarray(K))


def test_lqr_closed_loop_of_a_sampled_plant_uses_the_dlqr_gain():
    """A plant with a sample time dt > 0 (python-control's convention) gives the discrete
    loop x_{k+1} = (A − B K) x_k with python-control's ``dlqr`` gain."""
    rng = np.random.default_rng(11)
    A = np.array([[1.0, 0.1], [0.0, 1.0]])
    B = np.array([[0.005], [0.1]])
    prob = problems.make("lqr", "default", {"A": A.tolist(), "B": B.tolist(), "dt": 0.1,
                                            "x0": [[1.0, 0.0]]})
    Q, R = spd(rng, 2), spd(rng, 1)
    K, _, _ = control.dlqr(A, B, Q, R)
    loop = prob.closed_loop({"Q": Q, "R": R})
    assert loop.time == "discrete" and loop.dt == 0.1
    np.testing.assert_allclose(loop.gain, K, rtol=1e-9)
    check_columns(loop, A - B @ np.asarray(K), np.asarray(K))


def attitude_fd_closed_loop(prob, G):
    """Jacobian of the nonlinear closed loop in x = (q_v, ω) at the target by central
    differences of the plain-numpy right-hand side (q0 = √(1 − ‖q_v‖²))."""
    rhs = _rhs_numpy(G, prob.inertia, prob.inertia_inv, np.inf)

    def f(x):
        q0 = np.sqrt(1.0 - x[:3] @ x[:3])
        d = rhs(0.0, np.concatenate([[q0], x, [0.0]]))
        return d[1:7]

    h = 1e-6
    J = np.zeros((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        J[:, j] = (f(e) - f(-e)) / (2 * h)
    return J


@pytest.mark.parametrize("name", ["attitude_lyapunov", "attitude_lqr"])
def test_attitude_closed_loop_matches_finite_differences_of_the_dynamics(name):
    rng = np.random.default_rng(3)
    prob = problems.make(name, "detumble", {"u_max": 1.0})
    mats = {m.name: spd(rng, m.size) for m in prob.matrices}
    loop = prob.closed_loop(mats)
    G = prob.gain(mats)
    J = attitude_fd_closed_loop(prob, G)
    np.testing.assert_allclose(loop.matrix, J, atol=1e-7)
    np.testing.assert_allclose(loop.gain, G)
    cols = check_columns(loop, J, G)
    assert cols["cl_slowest_real"] < 0
    assert loop.state_names == ("q1", "q2", "q3", "w1", "w2", "w3")


def test_attitude_lqr_gain_from_python_control():
    rng = np.random.default_rng(5)
    prob = problems.make("attitude_lqr", "rest_to_rest", {})
    Q, R = spd(rng, 6), spd(rng, 3)
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(prob.inertia)])
    K, _, _ = control.lqr(A, B, Q, R)
    loop = prob.closed_loop({"Q": Q, "R": R})
    np.testing.assert_allclose(loop.gain, K, rtol=1e-7, atol=1e-10)
    check_columns(loop, A - B @ np.asarray(K), np.asarray(K))


def test_zermelo_closed_loop_matches_finite_differences():
    from penaltyrun.dynamics.zermelo import drift

    K = np.array([[1.7421, 0.9560], [0.9560, 1.1414]])
    prob = problems.make("zermelo", "default", {})
    loop = prob.closed_loop({"K": K})

    def f(X):  # Ẋ = U + d(X), U = −d(X) − KᵀX
        d = np.asarray(drift(X[0], X[1]), float)
        return (-d - K.T @ X) + d

    h = 1e-6
    J = np.column_stack([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(2)])
    np.testing.assert_allclose(loop.matrix, J, atol=1e-9)
    cols = check_columns(loop, J, K.T)
    assert cols["cl_min_damping"] == pytest.approx(1.0)  # symmetric K: real poles


def test_mpc_unconstrained_gain_is_the_dlqr_gain():
    """With terminal weight P from the DARE, the unconstrained MPC gain is the infinite-
    horizon discrete LQR gain (python-control's ``dlqr``) of the physical weights."""
    prob = rz.make_problem("default", {})
    rng = np.random.default_rng(1)
    Q = spd(rng, 6, 0.5, 50.0)
    R = spd(rng, 3, 1e3, 1e4)
    Qp, Rp = prob.physical_weights(Q[None], R[None])
    K, _, _ = control.dlqr(prob.Ad, prob.Bd, Qp[0], Rp[0])
    loop = prob.closed_loop({"Q": Q, "R": R})
    assert loop.time == "discrete" and loop.dt == prob.params.sample_time_s
    np.testing.assert_allclose(loop.gain, K, rtol=1e-6, atol=1e-12)
    check_columns(loop, prob.Ad - prob.Bd @ np.asarray(K), np.asarray(K))


def test_no_hook_no_closed_loop_or_failing_hook_gives_null_columns():
    class NoHook:
        name = "nohook"

    class NoLoop(NoHook):
        def closed_loop(self, mats, scalars=None):
            return None

    class Broken(NoHook):
        def closed_loop(self, mats, scalars=None):
            return np.eye(2)  # not a ClosedLoop

    for prob in (NoHook(), NoLoop(), Broken()):
        assert dg.record_columns(prob, {"K": np.eye(2)}) == dict.fromkeys(dg.COLUMNS)


def test_lowthrust_laws_have_no_hook():
    for name in ("qlaw", "lyapunov_transfer"):
        prob = problems.make(name, None, {})
        assert not hasattr(prob, "closed_loop")


def test_formulas_on_hand_made_matrices():
    # ẍ + 2ζω ẋ + ω² x = 0 with ω = 2, ζ = 0.3: poles −0.6 ± 1.908j
    wn, zeta = 2.0, 0.3
    A = np.array([[0.0, 1.0], [-wn ** 2, -2 * zeta * wn]])
    d = dg.diagnose(ClosedLoop(A, gain=np.array([[3.0, 0.0], [0.0, 0.5]])))
    assert d.slowest_real == pytest.approx(-zeta * wn)
    assert d.min_damping == pytest.approx(zeta)
    assert d.gain_norm == pytest.approx(3.0) and d.gain_cond == pytest.approx(6.0)
    # a real pole pair: slowest = the one nearest the axis, damping 1
    d = dg.diagnose(ClosedLoop(np.diag([-0.05, -3.0])))
    assert d.slowest_real == pytest.approx(-0.05) and d.min_damping == pytest.approx(1.0)
    assert np.isnan(d.gain_norm) and np.isnan(d.gain_cond)
    # discrete: z = r e^{±iθ}, s = (log r ± iθ)/dt
    r, theta, dt = 0.9, 0.4, 0.5
    Ad = r * np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    d = dg.diagnose(ClosedLoop(Ad, "discrete", dt=dt))
    assert d.slowest_real == pytest.approx(np.log(r) / dt)
    assert d.min_damping == pytest.approx(-np.log(r) / np.hypot(np.log(r), theta))
    # a deadbeat pole z = 0 is infinitely fast and fully damped
    d = dg.diagnose(ClosedLoop(np.diag([0.0, 0.5]), "discrete", dt=1.0))
    assert d.slowest_real == pytest.approx(np.log(0.5)) and d.min_damping == 1.0
    # a rank-deficient gain has an infinite condition number
    assert dg.gain_norm_cond(np.array([[1.0, 0.0], [0.0, 0.0]]))[1] == np.inf
    with pytest.raises(ValueError):
        ClosedLoop(np.eye(2), "discrete")


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.sampled_from(["continuous", "discrete"]))
def test_damping_matches_python_control_damp(seed, time):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(4, 4)) - (2.0 if time == "continuous" else 0.0) * np.eye(4)
    if time == "discrete":
        A = 0.9 * A / max(1.0, np.max(np.abs(np.linalg.eigvals(A))))
    dt = 0.3 if time == "discrete" else None
    d = dg.diagnose(ClosedLoop(A, time, dt=dt))
    sys = control.ss(A, np.zeros((4, 1)), np.zeros((1, 4)), 0, dt if dt else 0)
    _, zeta, _ = control.damp(sys, doprint=False)
    assert d.min_damping == pytest.approx(np.nanmin(zeta), abs=1e-9)


def test_loop_json_round_trip():
    loop = ClosedLoop(np.array([[0.5, 0.1], [0.0, 0.2]]), "discrete", dt=2.0,
                      gain=np.array([[1.0, 2.0]]), state_names=("a", "b"), input_names=("u",))
    back = dg.loop_from_json(dg.loop_json(loop))
    np.testing.assert_array_equal(back.matrix, loop.matrix)
    np.testing.assert_array_equal(back.gain, loop.gain)
    assert (back.time, back.dt, back.state_names, back.input_names) == \
        ("discrete", 2.0, ("a", "b"), ("u",))


def test_slowest_reals_of_a_batch_are_each_loops_diagnosis():
    """Loops of several shapes, continuous and discrete (a z = 0 pole), None and an empty
    loop in one call: each value is :func:`dg.diagnose`'s ``slowest_real`` of its loop."""
    rng = np.random.default_rng(5)
    loops = [None, ClosedLoop(np.zeros((0, 0)), "continuous")]
    for n in (2, 3, 2, 4, 3):
        loops.append(ClosedLoop(rng.standard_normal((n, n)), "continuous"))
        loops.append(ClosedLoop(0.5 * rng.standard_normal((n, n)), "discrete", dt=0.1 * n))
    loops.append(ClosedLoop(np.diag([0.0, 0.5]), "discrete", dt=0.2))
    got = dg.slowest_reals(loops)
    assert np.isnan(got[:2]).all()
    want = [dg.diagnose(loop).slowest_real for loop in loops[2:]]
    np.testing.assert_allclose(got[2:], want, rtol=1e-12)
    assert dg.slowest_reals([]).shape == (0,)


def test_slowest_reals_are_nan_for_loops_that_cannot_be_diagnosed():
    """A stored loop may be damaged (non-finite entries): it gives NaN, the other loops of
    its stack their value."""
    good = ClosedLoop(np.diag([-1.0, -3.0]), "continuous")
    bad = [ClosedLoop(np.array([[np.nan, 0.0], [0.0, -1.0]]), "continuous"),
           ClosedLoop(np.array([[np.inf, 0.0], [0.0, -1.0]]), "continuous")]
    got = dg.slowest_reals([good, *bad, good])
    assert got[0] == got[-1] == -1.0 and np.isnan(got[1:-1]).all()

