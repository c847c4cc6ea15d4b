"""Closed-form Zermelo kernel against numpy, the DOP853 kernel and scipy ``solve_ivp``."""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import integrate
from penaltyrun.dynamics.zermelo import simulate_batch
from penaltyrun.dynamics.zermelo_closed import QUAD_RTOL, closed_batch, eig_sym2

X0 = np.array([-8.0, 6.0])
R_EVENT = 1e-3
T_MAX = 1000.0


def gains(rng, n, lo=1e-8, hi=10.0):
    """Symmetric PD gains, eigenvalues log-uniform in [lo, hi], random rotation."""
    out = np.empty((n, 2, 2))
    for k in range(n):
        th = rng.uniform(0.0, np.pi)
        Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
        K = Q @ np.diag(np.exp(rng.uniform(np.log(lo), np.log(hi), 2))) @ Q.T
        out[k] = 0.5 * (K + K.T)
    return out


def box_gains():
    """Random gains over the eigenvalue box plus the hard corners: eigenvalues near the
    1e-8 bound, near-equal and equal eigenvalues, diagonal K, runs that do not arrive."""
    rng = np.random.default_rng(3)
    near_equal = [np.diag([1.0, 1.0]), np.array([[0.5, 1e-9], [1e-9, 0.5 + 1e-12]]),
                  np.array([[2.0, 1e-7], [1e-7, 2.0]]), np.diag([1e-8, 1e-8]),
                  np.array([[1e-8, 0.0], [0.0, 10.0]]), np.diag([10.0, 10.0]),
                  np.array([[3.0, 2.9999], [2.9999, 3.0]])]  # eigenvalues 5.9999 and 1e-4
    return np.concatenate([gains(rng, 40), gains(rng, 20, 1e-3, 0.1),
                           gains(rng, 10, 1e-8, 1e-5), np.array(near_equal)])


def closed(K, x0=X0, t_max=T_MAX, cutoff=None, rtol=QUAD_RTOL):
    B = len(K)
    cut = np.full(B, np.inf) if cutoff is None else cutoff
    return closed_batch(np.ascontiguousarray(K), np.tile(x0, (B, 1)), t_max, R_EVENT, cut, rtol)


def reference(K, x0=X0, t_max=T_MAX):
    """scipy solve_ivp (DOP853, rtol 1e-12) of the closed loop with J as a state."""
    def rhs(t, s):
        x, y = s[0], s[1]
        d = -np.array([x, y]) * np.cos(y) * np.sin(x)
        u = -d - K.T @ s[:2]
        return [*(u + d), 0.5 * float(u @ u)]

    def hit(t, s):
        return np.hypot(s[0], s[1]) - R_EVENT

    hit.terminal = True
    sol = solve_ivp(rhs, (0.0, t_max), [x0[0], x0[1], 0.0], events=hit, rtol=1e-12,
                    atol=1e-14, method="DOP853")
    if sol.t_events[0].size:
        return float(sol.y_events[0][0][2]), float(sol.t_events[0][0]), True
    return float(sol.y[2, -1]), float(sol.t[-1]), False


@settings(max_examples=200, deadline=None)
@given(a=st.floats(1e-8, 10.0), c=st.floats(1e-8, 10.0), b=st.floats(-10.0, 10.0))
@example(a=4.288025965487387, b=4.169390523123407, c=4.169390523123407)
def test_eig_sym2_matches_eigh(a, b, c):
    l1, l2, cs, sn = eig_sym2(a, b, c)
    K = np.array([[a, b], [b, c]])
    V = np.array([[cs, sn], [-sn, cs]])
    # both are backward stable: each eigenvalue within a few eps of ||K||_2 (not of max|K_ij|,
    # which is up to half of it: a = c = b gives 4 ulp of the larger eigenvalue at 8e-16 max|K|)
    scale = np.linalg.norm(K, 2)
    np.testing.assert_allclose(np.sort([l1, l2]), np.linalg.eigvalsh(K), rtol=0,
                               atol=8e-16 * scale)
    np.testing.assert_allclose(V.T @ V, np.eye(2), atol=1e-15)
    np.testing.assert_allclose(K @ V, V @ np.diag([l1, l2]), rtol=0, atol=8e-16 * scale)


@pytest.mark.slow
def test_agrees_with_the_dop853_kernel():
    K = box_gains()
    t, J, dist, status, covered = closed(K)
    assert covered.all()
    ts, Js, dists, statuss = simulate_batch(K, X0, T_MAX, R_EVENT, 1e-10, 1e-10, np.inf,
                                            1_000_000)
    np.testing.assert_array_equal(status, statuss)
    assert {integrate.EVENT, integrate.HORIZON} <= set(status.tolist())
    np.testing.assert_allclose(J, Js, rtol=1e-8)
    np.testing.assert_allclose(dist, dists, rtol=1e-8)
    ev = status == integrate.EVENT
    # event times: the integrator locates ‖X‖ = r to its tolerance 1e-10, i.e. in time to
    # 1e-10 / |d‖X‖/dt|, which is large for slow gains (d‖X‖/dt = −XᵀKX / ‖X‖ at the event)
    speed = np.array([np.linalg.eigvalsh(k)[0] for k in K[ev]]) * R_EVENT
    assert np.all(np.abs(t[ev] - ts[ev]) <= np.maximum(1e-6, 2e-10 / speed))
    np.testing.assert_array_equal(t[~ev], T_MAX)


@pytest.mark.parametrize("idx", range(0, 77, 4))
def test_agrees_with_solve_ivp(idx):
    K = box_gains()[idx:idx + 1]
    t, J, _, status, covered = closed(K)
    ref_J, ref_t, ref_ok = reference(K[0])
    assert covered[0] and (status[0] == integrate.EVENT) == ref_ok
    assert J[0] == pytest.approx(ref_J, rel=1e-8)
    assert t[0] == pytest.approx(ref_t, rel=0, abs=1e-6)


def test_quadrature_is_converged_far_below_the_integrator_tolerance():
    K = box_gains()
    J = closed(K)[1]
    J_tight = closed(K, rtol=1e-12)[1]
    np.testing.assert_allclose(J, J_tight, rtol=1e-12)


def test_held_out_starts_and_long_horizon():
    rng = np.random.default_rng(5)
    K = gains(rng, 12, 1e-4, 10.0)
    for x0 in (np.array([2.0, 0.0]), np.array([0.0, -10.0]), np.array([3.5, 3.5])):
        t, J, _, status, covered = closed(K, x0, t_max=1e4)
        ts, Js, _, statuss = simulate_batch(K, x0, 1e4, R_EVENT, 1e-10, 1e-10, np.inf,
                                            1_000_000)
        assert covered.all()
        np.testing.assert_array_equal(status, statuss)
        np.testing.assert_allclose(J, Js, rtol=1e-8)


def test_start_on_an_eigenvector():
    # ξ₂ = 0: the log of the vanished coordinate is −inf and must not poison the root
    K = np.diag([0.5, 2.0])[None]
    t, J, dist, status, covered = closed(K, np.array([4.0, 0.0]))
    assert covered[0] and status[0] == integrate.EVENT
    assert t[0] == pytest.approx(np.log(4.0 / R_EVENT) / 0.5, rel=1e-14)
    assert dist[0] == pytest.approx(R_EVENT, rel=1e-13)
    assert J[0] == pytest.approx(reference(K[0], np.array([4.0, 0.0]))[0], rel=1e-8)


def test_cutoff_reports_the_exact_cost():
    K = box_gains()[:30]
    _, J, _, status, _ = closed(K)
    cut = J * np.where(np.arange(30) % 2 == 0, 0.5, 2.0)
    _, Jc, _, sc, _ = closed(K, cutoff=cut)
    np.testing.assert_array_equal(Jc, J)
    np.testing.assert_array_equal(sc == integrate.CUTOFF, J > cut)
    np.testing.assert_array_equal(sc[J <= cut], status[J <= cut])


@pytest.mark.parametrize("K, x0", [
    ([[1.0, 0.5], [0.4, 1.0]], X0),             # not symmetric
    ([[1.0, 2.0], [2.0, 1.0]], X0),             # indefinite
    ([[1.0, 0.0], [0.0, 0.0]], X0),             # singular
    ([[np.nan, 0.0], [0.0, 1.0]], X0),          # not finite
    ([[1.0, 0.0], [0.0, 1.0]], [1e-4, 0.0]),    # start inside the event radius
])
def test_what_the_closed_form_does_not_cover_is_flagged(K, x0):
    res = closed(np.array([K], dtype=float), np.asarray(x0, dtype=float))
    assert not res[4][0] and res[3][0] == -1


@settings(max_examples=30, deadline=None)
@given(l1=st.floats(-8.0, 1.0), l2=st.floats(-8.0, 1.0), th=st.floats(0.0, np.pi),
       r0=st.floats(0.01, 10.0), a0=st.floats(0.0, 2.0 * np.pi))
def test_property_agrees_with_the_dop853_kernel(l1, l2, th, r0, a0):
    # eigenvalues 10^l (1e-8 … 10), any rotation, any start outside the event radius
    Q = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    K = Q @ np.diag([10.0 ** l1, 10.0 ** l2]) @ Q.T
    K = np.ascontiguousarray(0.5 * (K + K.T))[None]
    x0 = np.array([r0 * np.cos(a0), r0 * np.sin(a0)])
    t, J, _, status, covered = closed(K, x0)
    ts, Js, _, statuss = simulate_batch(K, x0, T_MAX, R_EVENT, 1e-10, 1e-10, np.inf,
                                        1_000_000)
    assert covered[0] and status[0] == statuss[0]
    # relative 1e-8, or the integrator's absolute tolerance for tiny energies (from a start
    # near the target: e.g. K = diag(0.1, 1), X0 = (0.125, 0), J = 4.5e-5, where the closed
    # form agrees with scipy.integrate.quad to 1e-15 and the integrator is 4e-12 off)
    assert J[0] == pytest.approx(Js[0], rel=1e-8, abs=1e-9)


def test_energy_against_scipy_quad_on_a_known_path():
    # K = diag(0.1, 1), X0 = (0.125, 0): x(t) = 0.125 e^{−0.1t}, y = 0, U = (x sin x − 0.1x, 0)
    from scipy.integrate import quad

    T = np.log(0.125 / R_EVENT) / 0.1

    def f(t):
        x = 0.125 * np.exp(-0.1 * t)
        return 0.5 * (x * (np.sin(x) - 0.1)) ** 2

    t, J, _, status, _ = closed(np.diag([0.1, 1.0])[None], np.array([0.125, 0.0]))
    assert status[0] == integrate.EVENT and t[0] == pytest.approx(T, rel=1e-14)
    assert J[0] == pytest.approx(quad(f, 0.0, T, epsabs=0.0, epsrel=1e-13, limit=500)[0],
                                 rel=1e-13)


def test_where_the_integrator_drifts_the_closed_form_matches_solve_ivp():
    # one of 4000 random gains on which the DOP853 kernel (tolerance 1e-10 per step) is
    # 3.9e-8 relative off; the closed form agrees with solve_ivp at rtol 1e-12
    K = np.array([[[0.7991986654915277, -0.9810847322387961],
                   [-0.9810847322387961, 2.6738949474033498]]])
    J = closed(K)[1][0]
    Js = simulate_batch(K, X0, T_MAX, R_EVENT, 1e-10, 1e-10, np.inf, 1_000_000)[1][0]
    ref = reference(K[0])[0]
    assert J == pytest.approx(ref, rel=1e-11)
    assert Js == pytest.approx(ref, rel=1e-7)
