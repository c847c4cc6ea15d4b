"""The orthogonal maps against plain-numpy reference implementations of their definitions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from penaltyrun.penalty import orthogonal as orth

NS = (2, 3, 4, 5, 6)


# --------------------------------------------------------------------------- references


def ref_hypersphere(phi):
    """Spec: v_1 = cos φ_1, v_j = sin φ_1 ⋯ sin φ_{j−1} cos φ_j, v_{k+1} = Π sin φ_j."""
    k = len(phi)
    v = np.empty(k + 1)
    for j in range(k):
        v[j] = np.prod(np.sin(phi[:j])) * np.cos(phi[j])
    v[k] = np.prod(np.sin(phi))
    return v


def ref_complement(placed, n, skip=orth.GS_SKIP):
    """Documented basis: Gram–Schmidt (twice) of e_1..e_N, skipping small residuals."""
    basis = []
    for j in range(n):
        if len(basis) == n - placed.shape[1]:
            break
        r = np.zeros(n)
        r[j] = 1.0
        for _ in range(2):
            for c in range(placed.shape[1]):
                r -= (placed[:, c] @ r) * placed[:, c]
            for b in basis:
                r -= (b @ r) * b
        if np.linalg.norm(r) > skip:
            basis.append(r / np.linalg.norm(r))
    return np.array(basis).T


def ref_geagsp(angles, n):
    Q = np.zeros((n, n))
    pos = 0
    for col in range(n - 1):
        k = n - 1 - col
        v = ref_hypersphere(angles[pos:pos + k])
        pos += k
        Q[:, col] = v if col == 0 else ref_complement(Q[:, :col], n) @ v
    Q[:, n - 1] = ref_complement(Q[:, : n - 1], n)[:, 0]
    return Q


def ref_givens(angles, n):
    Q = np.eye(n)
    pos = 0
    for j in range(n - 1):
        for i in range(j + 1, n):
            c, s = np.cos(angles[pos]), np.sin(angles[pos])
            G = np.eye(n)
            G[j, j] = G[i, i] = c
            G[j, i] = s
            G[i, j] = -s
            Q = Q @ G
            pos += 1
    return Q


def ref_cayley(entries, n):
    C = np.zeros((n, n))
    C[np.triu_indices(n, 1)] = entries
    C = C - C.T
    eye = np.eye(n)
    return (eye - C) @ np.linalg.inv(eye + C)


def random_rotation(rng, n):
    Q, R = np.linalg.qr(rng.standard_normal((n, n)))
    Q = Q * np.sign(np.diag(R))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    return Q


# --------------------------------------------------------------------------- basics


@pytest.mark.parametrize("n,m", [(1, 0), (2, 1), (3, 3), (4, 6), (5, 10), (6, 15)])
def test_n_angles(n, m):
    assert orth.n_angles(n) == m


@pytest.mark.parametrize("n", NS)
def test_geagsp_angle_bounds_last_angle_of_each_row_is_two_pi(n):
    lb, ub = orth.geagsp_angle_bounds(n)
    assert lb.shape == ub.shape == (orth.n_angles(n),)
    np.testing.assert_array_equal(lb, 0.0)
    expected = []
    for row in range(1, n):
        k = n - row
        expected += [np.pi] * (k - 1) + [2 * np.pi]
    np.testing.assert_allclose(ub, expected)


@settings(max_examples=60)
@given(phi=arrays(np.float64, st.integers(1, 5), elements=st.floats(0.0, 2 * np.pi)))
def test_hypersphere_matches_spec_and_is_unit(phi):
    out = np.empty(phi.size + 1)
    orth._hypersphere(phi, out)
    np.testing.assert_allclose(out, ref_hypersphere(phi), atol=1e-15)
    assert np.linalg.norm(out) == pytest.approx(1.0, abs=1e-14)


@settings(max_examples=60)
@given(phi=arrays(np.float64, st.integers(1, 5), elements=st.floats(0.0, np.pi)))
def test_hypersphere_inverse_round_trip(phi):
    phi = phi.copy()
    phi[-1] *= 2.0  # last angle in [0, 2π]
    v = ref_hypersphere(phi)
    back = orth._hypersphere_inverse(v)
    assert np.all(back[:-1] >= 0) and np.all(back[:-1] <= np.pi)
    assert 0.0 <= back[-1] <= 2 * np.pi  # np.mod(-0.0…, 2π) may round to 2π
    np.testing.assert_allclose(ref_hypersphere(back), v, atol=1e-12)


# --------------------------------------------------------------------------- forward maps


@pytest.mark.parametrize("n", NS)
def test_geagsp_matches_reference_construction(n):
    rng = np.random.default_rng(n)
    lb, ub = orth.geagsp_angle_bounds(n)
    A = lb + rng.random((50, orth.n_angles(n))) * (ub - lb)
    Q = orth.geagsp_batch(A, n)
    for a, q in zip(A, Q):
        np.testing.assert_allclose(q, ref_geagsp(a, n), atol=1e-12)


@pytest.mark.parametrize("n", NS)
def test_geagsp_first_column_is_hypersphere_of_row_one(n):
    rng = np.random.default_rng(100 + n)
    lb, ub = orth.geagsp_angle_bounds(n)
    a = lb + rng.random(orth.n_angles(n)) * (ub - lb)
    Q = orth.geagsp_batch(a[None], n)[0]
    np.testing.assert_allclose(Q[:, 0], ref_hypersphere(a[: n - 1]), atol=1e-15)


def test_geagsp_is_deterministic_across_calls():
    rng = np.random.default_rng(7)
    A = rng.random((20, orth.n_angles(5))) * np.pi
    np.testing.assert_array_equal(orth.geagsp_batch(A, 5), orth.geagsp_batch(A.copy(), 5))


@pytest.mark.parametrize("n", NS)
def test_givens_matches_product_of_plane_rotations(n):
    rng = np.random.default_rng(n)
    A = rng.uniform(-np.pi, np.pi, (30, orth.n_angles(n)))
    Q = orth.givens_batch(A, n)
    for a, q in zip(A, Q):
        np.testing.assert_allclose(q, ref_givens(a, n), atol=1e-13)
        assert np.linalg.det(q) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("n", (16, 32))
def test_givens_and_cayley_match_their_definitions_at_large_n(n):
    rng = np.random.default_rng(n)
    A = rng.uniform(-np.pi, np.pi, (3, orth.n_angles(n)))
    for a, q in zip(A, orth.givens_batch(A, n)):
        np.testing.assert_allclose(q, ref_givens(a, n), atol=1e-12)
    E = rng.uniform(-3, 3, (3, orth.n_angles(n)))
    for e, q in zip(E, orth.cayley_batch(E, n)):
        np.testing.assert_allclose(q, ref_cayley(e, n), atol=1e-11)


def test_givens_single_plane_sign_convention():
    """G_jj = G_ii = cos θ, G_ji = sin θ, G_ij = −sin θ (j < i)."""
    th = 0.4
    Q = orth.givens_batch(np.array([[th]]), 2)[0]
    np.testing.assert_allclose(Q, [[np.cos(th), np.sin(th)], [-np.sin(th), np.cos(th)]],
                               atol=1e-15)


def test_givens_is_continuous_in_theta():
    rng = np.random.default_rng(0)
    a = rng.uniform(-np.pi, np.pi, orth.n_angles(4))
    h = 1e-7
    for m in range(a.size):
        b = a.copy()
        b[m] += h
        diff = orth.givens_batch(b[None], 4)[0] - orth.givens_batch(a[None], 4)[0]
        assert np.abs(diff).max() < 10 * h


@pytest.mark.parametrize("n", NS)
def test_cayley_matches_definition(n):
    rng = np.random.default_rng(n)
    E = rng.uniform(-100, 100, (30, orth.n_angles(n)))
    Q = orth.cayley_batch(E, n)
    for e, q in zip(E, Q):
        np.testing.assert_allclose(q, ref_cayley(e, n), atol=1e-11)
        assert np.linalg.det(q) == pytest.approx(1.0, abs=1e-10)


def test_skew_from_entries_layout():
    C = orth.skew_from_entries(np.array([1.0, 2.0, 3.0]), 3)[0]
    np.testing.assert_array_equal(C, [[0, 1, 2], [-1, 0, 3], [-2, -3, 0]])
    np.testing.assert_array_equal(C, -C.T)


# --------------------------------------------------------------------------- inverse maps


@pytest.mark.parametrize("n", NS)
def test_givens_inverse_round_trip(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        Q = random_rotation(rng, n)
        a = orth.givens_inverse(Q)
        assert a.shape == (orth.n_angles(n),)
        assert np.all(np.abs(a) <= np.pi)
        np.testing.assert_allclose(orth.givens_batch(a[None], n)[0], Q, atol=1e-12)


@pytest.mark.parametrize("n", NS)
def test_geagsp_inverse_round_trip_columns(n):
    rng = np.random.default_rng(n)
    lb, ub = orth.geagsp_angle_bounds(n)
    for _ in range(20):
        Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
        a = orth.geagsp_inverse(Q)
        assert np.all(a >= lb) and np.all(a <= ub)
        Q2 = orth.geagsp_batch(a[None], n)[0]
        np.testing.assert_allclose(Q2[:, : n - 1], Q[:, : n - 1], atol=1e-12)
        np.testing.assert_allclose(np.abs(Q2[:, -1]), np.abs(Q[:, -1]), atol=1e-12)


@pytest.mark.parametrize("n", NS)
def test_cayley_inverse_round_trip_entries(n):
    rng = np.random.default_rng(n)
    E = rng.uniform(-3, 3, (20, orth.n_angles(n)))
    for e in E:
        q = orth.cayley_batch(e[None], n)[0]
        np.testing.assert_allclose(orth.cayley_inverse(q), e, atol=1e-9)


@pytest.mark.parametrize("n", NS)
def test_proper_eigenvectors(n):
    rng = np.random.default_rng(n)
    A = rng.standard_normal((n, n))
    K = A @ A.T + n * np.eye(n)
    for prefer in (False, True):
        lam, Q = orth.proper_eigenvectors(K, prefer_positive_diagonal=prefer)
        assert np.linalg.det(Q) == pytest.approx(1.0, abs=1e-12)
        np.testing.assert_allclose(Q @ np.diag(lam) @ Q.T, K, atol=1e-10)
        np.testing.assert_allclose(Q.T @ Q, np.eye(n), atol=1e-12)


def test_proper_eigenvectors_of_diagonal_matrix_keeps_axes():
    lam, Q = orth.proper_eigenvectors(np.diag([3.0, 1.0, 2.0]), prefer_positive_diagonal=True)
    np.testing.assert_array_equal(lam, [3.0, 1.0, 2.0])
    np.testing.assert_allclose(Q, np.eye(3), atol=1e-15)
