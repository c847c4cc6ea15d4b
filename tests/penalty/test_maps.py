"""Property-based tests of the SPD parameterizations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from penaltyrun.errors import ConfigError
from penaltyrun.penalty import KINDS, make
from penaltyrun.penalty import orthogonal as orth

MAPS = ("diagonal", "geagsp", "givens", "cayley", "cayley_tan")
FULL = ("geagsp", "givens", "cayley", "cayley_tan")
#: Maps whose Q has det +1 (rotations).
PROPER = ("givens", "cayley", "cayley_tan", "diagonal")
#: Maps that cannot represent every rotation (Cayley: none near a rotation by π).
PARTIAL = ("cayley", "cayley_tan")
NS = (2, 3, 5, 6)
EIG = (0.1, 100.0)
CASES = [(kind, n) for kind in MAPS for n in NS]
FULL_CASES = [(kind, n) for kind in FULL for n in NS]


def z_in_box(p):
    """Strategy: a decision vector inside p's box (endpoints included)."""
    lb, ub = p.bounds()
    unit = arrays(np.float64, p.dim, elements=st.floats(0.0, 1.0))
    return unit.map(lambda u: np.clip(lb + u * (ub - lb), lb, ub))


def random_box(p, rng, size):
    lb, ub = p.bounds()
    return lb + rng.random((size, p.dim)) * (ub - lb)


def check_spd_properties(p, z):
    K = p.decode(z)
    Q = p.orthogonal(z)[0]
    lam = np.asarray(z[: p.n])
    n = p.n
    assert K.shape == (n, n)
    scale = float(lam.max())
    np.testing.assert_allclose(K, K.T, rtol=0, atol=1e-14 * scale)
    np.testing.assert_allclose(np.linalg.eigvalsh(K), np.sort(lam), rtol=1e-9,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(Q.T @ Q, np.eye(n), rtol=0, atol=1e-12)
    np.testing.assert_allclose(Q @ np.diag(lam) @ Q.T, K, rtol=0, atol=1e-10 * scale)
    det = np.linalg.det(Q)
    if p.kind in PROPER:
        assert det == pytest.approx(1.0, abs=1e-10)
    else:
        assert abs(det) == pytest.approx(1.0, abs=1e-10)
    assert np.all(np.linalg.eigvalsh(K) > 0)


# --------------------------------------------------------------------------- properties


@pytest.mark.parametrize("kind,n", CASES)
@settings(max_examples=40)
@given(data=st.data())
def test_symmetric_with_eigenvalues_lambda_and_orthogonal_q(kind, n, data):
    p = make(kind, n, EIG)
    z = data.draw(z_in_box(p))
    check_spd_properties(p, z)


@pytest.mark.parametrize("kind,n", CASES)
def test_properties_on_many_random_and_corner_points(kind, n):
    """Vectorised sweep: random interior points plus box corners (degenerate angles)."""
    p = make(kind, n, EIG)
    rng = np.random.default_rng(n)
    lb, ub = p.bounds()
    Z = random_box(p, rng, 400)
    corners = lb + rng.integers(0, 2, (100, p.dim)) * (ub - lb)
    Z = np.vstack([Z, corners])
    K = p.decode(Z)
    Q = p.orthogonal(Z)
    assert K.shape == (len(Z), n, n)
    np.testing.assert_allclose(K, np.transpose(K, (0, 2, 1)), rtol=0, atol=1e-12)
    ev = np.linalg.eigvalsh(K)
    np.testing.assert_allclose(ev, np.sort(Z[:, :n], axis=1), rtol=1e-9, atol=1e-10)
    QtQ = np.einsum("bji,bjk->bik", Q, Q)
    np.testing.assert_allclose(QtQ, np.broadcast_to(np.eye(n), QtQ.shape), rtol=0, atol=1e-12)
    det = np.linalg.det(Q)
    if kind in PROPER:
        np.testing.assert_allclose(det, 1.0, atol=1e-10)
    else:
        np.testing.assert_allclose(np.abs(det), 1.0, atol=1e-10)


def test_properties_with_narrow_eigenvalue_bounds():
    p = make("geagsp", 4, (1.0, 1.0 + 1e-6))
    Z = random_box(p, np.random.default_rng(3), 50)
    for z in Z:
        check_spd_properties(p, z)


# --------------------------------------------------------------------------- dimensions


@pytest.mark.parametrize("n,full_dim", [(2, 3), (3, 6), (5, 15), (6, 21)])
@pytest.mark.parametrize("kind", FULL + ("full",))
def test_dims_full(kind, n, full_dim):
    p = make(kind, n, EIG)
    assert p.dim == full_dim
    assert p.n_angles == n * (n - 1) // 2
    lb, ub = p.bounds()
    assert lb.shape == ub.shape == (full_dim,)
    assert np.all(lb < ub)
    np.testing.assert_array_equal(lb[:n], EIG[0])
    np.testing.assert_array_equal(ub[:n], EIG[1])


@pytest.mark.parametrize("n", NS)
def test_dims_diagonal(n):
    p = make("diagonal", n, EIG)
    assert p.dim == n
    assert p.n_angles == 0
    lb, ub = p.bounds()
    np.testing.assert_array_equal(lb, np.full(n, EIG[0]))
    np.testing.assert_array_equal(ub, np.full(n, EIG[1]))


def test_angle_bounds_per_kind():
    n = 4
    _, ub = make("geagsp", n, EIG).bounds()
    pi, tau = np.pi, 2 * np.pi
    np.testing.assert_allclose(ub[n:], [pi, pi, tau, pi, tau, tau])
    lb, ub = make("givens", n, EIG).bounds()
    np.testing.assert_allclose(lb[n:], -np.pi)
    np.testing.assert_allclose(ub[n:], np.pi)
    lb, ub = make("cayley", n, EIG, cayley_bound=7.0).bounds()
    np.testing.assert_allclose(lb[n:], -7.0)
    np.testing.assert_allclose(ub[n:], 7.0)
    lb, ub = make("cayley_tan", n, EIG, cayley_bound=7.0).bounds()  # bound not used
    np.testing.assert_allclose(lb[n:], -(np.pi / 2 - 0.01))
    np.testing.assert_allclose(ub[n:], np.pi / 2 - 0.01)
    assert np.tan(ub[n]) == pytest.approx(99.9967, abs=1e-4)


def test_full_is_alias_of_geagsp():
    full = make("full", 3, EIG)
    geagsp = make("geagsp", 3, EIG)
    assert full.kind == "geagsp"
    assert full == geagsp
    Z = random_box(geagsp, np.random.default_rng(0), 20)
    np.testing.assert_array_equal(full.decode(Z), geagsp.decode(Z))


# --------------------------------------------------------------------------- batching


@pytest.mark.parametrize("kind,n", CASES)
def test_batch_decode_equals_per_vector_decode(kind, n):
    p = make(kind, n, EIG)
    Z = random_box(p, np.random.default_rng(10 + n), 25)
    batch = p.decode(Z)
    assert batch.shape == (25, n, n)
    single = np.stack([p.decode(z) for z in Z])
    np.testing.assert_allclose(batch, single, rtol=1e-14, atol=1e-13)
    assert p.decode(Z[0]).shape == (n, n)
    assert p.decode(Z[:1]).shape == (1, n, n)
    # decode is a pure function: same input, same output, input untouched
    Z_copy = Z.copy()
    np.testing.assert_array_equal(p.decode(Z), batch)
    np.testing.assert_array_equal(Z, Z_copy)


# --------------------------------------------------------------------------- diagonal subset


def _identity_z(lam):
    n = lam.size
    return np.concatenate([lam, np.zeros(n * (n - 1) // 2)])


@pytest.mark.parametrize("kind,n", FULL_CASES)
def test_diagonal_is_a_subset_zero_angles_give_identity(kind, n):
    """GEAGSP φ = 0 puts e1, e2, … in the columns; Givens θ = 0 and Cayley C = 0 give I."""
    p = make(kind, n, EIG)
    lam = np.linspace(0.5, 50.0, n)
    z = _identity_z(lam)
    lb, ub = p.bounds()
    assert np.all(lb <= z) and np.all(z <= ub)
    np.testing.assert_allclose(p.orthogonal(z)[0], np.eye(n), atol=1e-15)
    np.testing.assert_allclose(p.decode(z), np.diag(lam), atol=1e-13)
    np.testing.assert_allclose(p.decode(z), make("diagonal", n, EIG).decode(lam), atol=1e-13)


def _row_starts(n):
    starts, pos = [], 0
    for row in range(1, n):
        starts.append(pos)
        pos += n - row
    return starts


@pytest.mark.parametrize("n", NS)
@settings(max_examples=30)
@given(data=st.data())
def test_geagsp_first_angle_of_each_row_on_axis_gives_signed_identity(n, data):
    """v(0, φ2, …) = e1 whatever the other angles (and v(π, …) = −e1): |Q| = I, K diagonal."""
    p = make("geagsp", n, EIG)
    z = data.draw(z_in_box(p)).copy()
    for start, on_axis in zip(_row_starts(n), data.draw(
            st.lists(st.booleans(), min_size=n - 1, max_size=n - 1))):
        z[n + start] = 0.0 if on_axis else np.pi
    Q = p.orthogonal(z)[0]
    np.testing.assert_allclose(np.abs(Q), np.eye(n), atol=1e-12)
    np.testing.assert_allclose(p.decode(z), np.diag(z[:n]), atol=1e-10 * z[:n].max())


# --------------------------------------------------------------------------- inverse map


@pytest.mark.parametrize("kind,n", CASES)
@settings(max_examples=40)
@given(data=st.data())
def test_round_trip_from_box(kind, n, data):
    p = make(kind, n, EIG)
    K = p.decode(data.draw(z_in_box(p)))
    try:
        z2 = p.encode(K)
    except ValueError:
        if kind not in PARTIAL:
            raise
        return
    lb, ub = p.bounds()
    assert z2.shape == (p.dim,)
    assert np.all(lb <= z2) and np.all(z2 <= ub)
    np.testing.assert_allclose(p.decode(z2), K, rtol=0, atol=1e-9 * np.abs(K).max())


def _random_spd(rng, n, lo, hi):
    Q, R = np.linalg.qr(rng.standard_normal((n, n)))
    Q = Q * np.sign(np.diag(R))  # Haar; det may be ±1
    lam = rng.uniform(lo, hi, n)
    return Q @ np.diag(lam) @ Q.T


@pytest.mark.parametrize("kind,n", FULL_CASES)
@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1))
def test_round_trip_random_spd(kind, n, seed):
    rng = np.random.default_rng(seed)
    K = _random_spd(rng, n, *EIG)
    p = make(kind, n, EIG)
    try:
        z = p.encode(K)
    except ValueError:
        if kind not in PARTIAL:
            raise
        return
    lb, ub = p.bounds()
    assert np.all(lb <= z) and np.all(z <= ub)
    np.testing.assert_allclose(np.sort(z[:n]), np.linalg.eigvalsh(K), rtol=1e-9)
    np.testing.assert_allclose(p.decode(z), K, rtol=0, atol=1e-9 * np.abs(K).max())


def test_diagonal_encode():
    p = make("diagonal", 3, EIG)
    lam = np.array([3.0, 1.0, 2.0])
    np.testing.assert_array_equal(p.encode(np.diag(lam)), lam)
    K = np.diag(lam)
    K[0, 1] = K[1, 0] = 0.5
    with pytest.raises(ValueError, match="non-diagonal"):
        p.encode(K)


@pytest.mark.parametrize("kind", FULL)
def test_encode_of_diagonal_k_gives_identity_rotation(kind):
    """A diagonal K (unsorted eigenvalues) is encoded with Q = I, not a permutation."""
    p = make(kind, 4, EIG)
    lam = np.array([7.0, 0.5, 30.0, 2.0])
    z = p.encode(np.diag(lam))
    np.testing.assert_allclose(z[:4], lam)
    np.testing.assert_allclose(p.orthogonal(z)[0], np.eye(4), atol=1e-12)


@pytest.mark.parametrize("kind", MAPS)
def test_encode_rejects_eigenvalues_outside_bounds(kind):
    p = make(kind, 3, (1.0, 10.0))
    with pytest.raises(ValueError, match="outside"):
        p.encode(np.diag([0.5, 2.0, 3.0]))
    with pytest.raises(ValueError, match="outside"):
        p.encode(np.diag([2.0, 3.0, 11.0]))


def test_cayley_encode_failure_is_value_error_not_garbage():
    """Rotation angle 40° needs |C_12| = tan 20° ≈ 0.36: outside a [−0.1, 0.1] box."""
    p = make("cayley", 2, EIG, cayley_bound=0.1)
    th = np.deg2rad(40.0)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    K = R @ np.diag([1.0, 5.0]) @ R.T
    with pytest.raises(ValueError):
        p.encode(K)
    # the wide default box represents it
    wide = make("cayley", 2, EIG)
    np.testing.assert_allclose(wide.decode(wide.encode(K)), K, atol=1e-12)


def test_cayley_inverse_of_rotation_by_pi_raises_value_error():
    Q = np.diag([-1.0, -1.0, 1.0])  # eigenvalue −1: (I + Q) is singular
    with pytest.raises(ValueError):
        orth.cayley_inverse(Q)


# --------------------------------------------------------------------------- GEAGSP N = 2


@settings(max_examples=60)
@given(phi=st.floats(0.0, np.pi), l1=st.floats(0.1, 100.0), l2=st.floats(0.1, 100.0))
def test_geagsp_n2_angle_matters_only_modulo_pi(phi, l1, l2):
    p = make("geagsp", 2, EIG)
    K1 = p.decode(np.array([l1, l2, phi]))
    K2 = p.decode(np.array([l1, l2, phi + np.pi]))
    np.testing.assert_allclose(K1, K2, rtol=0, atol=1e-12 * max(l1, l2))


def test_geagsp_n2_angle_is_a_rotation_angle():
    p = make("geagsp", 2, EIG)
    phi = 0.3
    K = p.decode(np.array([1.0, 4.0, phi]))
    v = np.array([np.cos(phi), np.sin(phi)])
    np.testing.assert_allclose(K @ v, 1.0 * v, atol=1e-12)
    # a quarter turn swaps the eigenvalues' axes
    np.testing.assert_allclose(p.decode(np.array([1.0, 4.0, np.pi / 2])),
                               np.diag([4.0, 1.0]), atol=1e-12)


# --------------------------------------------------------------------------- bad input


def test_make_unknown_kind_names_key_and_lists_allowed():
    with pytest.raises(ConfigError) as info:
        make("foo", 3, EIG)
    err = info.value
    assert err.key == "param.name"
    assert "param.name" in str(err)
    assert "foo" in str(err)
    for kind in KINDS:
        assert kind in str(err)
    assert set(err.allowed) == set(KINDS)
    assert isinstance(err, ValueError)


@pytest.mark.parametrize("bounds", [(0.0, 1.0), (-1.0, 1.0), (2.0, 2.0), (3.0, 1.0),
                                    (1.0, float("inf"))])
def test_make_bad_eig_bounds(bounds):
    with pytest.raises(ConfigError) as info:
        make("geagsp", 3, bounds)
    assert info.value.key == "param.eig_bounds"
    assert "param.eig_bounds" in str(info.value)


def test_make_bad_cayley_bound():
    with pytest.raises(ConfigError) as info:
        make("cayley", 3, EIG, cayley_bound=0.0)
    assert info.value.key == "param.cayley_bound"


def test_make_accepts_list_bounds_and_coerces():
    p = make("givens", 3, [1, 5])
    assert p.eig_bounds == (1.0, 5.0)
    assert isinstance(p.n, int)


@pytest.mark.parametrize("kind", MAPS)
def test_decode_wrong_dim_raises_value_error(kind):
    p = make(kind, 3, EIG)
    with pytest.raises(ValueError, match=str(p.dim)):
        p.decode(np.ones(p.dim + 1))
    with pytest.raises(ValueError):
        p.decode(np.ones((4, p.dim - 1)))


# --------------------------------------------------------------------------- Cayley-tan


@pytest.mark.parametrize("n", NS)
@settings(max_examples=40)
@given(data=st.data())
def test_cayley_tan_is_cayley_of_tan_theta(n, data):
    """Cayley-tan at (λ, θ) is Cayley at (λ, tan θ), and its box maps into |C_ij| < 100."""
    tan_map = make("cayley_tan", n, EIG)
    z = data.draw(z_in_box(tan_map))
    entries = np.tan(z[n:])
    assert np.all(np.abs(entries) <= 100.0)
    z_cayley = np.concatenate([z[:n], entries])
    np.testing.assert_allclose(tan_map.decode(z), make("cayley", n, EIG).decode(z_cayley),
                               rtol=0, atol=1e-13 * z[:n].max())
    C = orth.skew_from_entries(entries, n)[0]
    eye = np.eye(n)
    Q = (eye - C) @ np.linalg.inv(eye + C)
    np.testing.assert_allclose(tan_map.orthogonal(z)[0], Q, atol=1e-10)


def test_cayley_tan_encode_gives_arctan_of_cayley_entries():
    """Rotation by 40° in the (1, 2) plane: Q = (I − C)(I + C)⁻¹ with C_12 = tan 20°."""
    p = make("cayley_tan", 2, EIG)
    th = np.deg2rad(40.0)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    K = R @ np.diag([1.0, 5.0]) @ R.T
    z = p.encode(K)
    np.testing.assert_allclose(z, [1.0, 5.0, np.deg2rad(20.0)], atol=1e-12)
    np.testing.assert_allclose(p.decode(z), K, atol=1e-12)


@pytest.mark.parametrize("kind", ["geagsp", "givens", "cayley", "cayley_tan"])
@pytest.mark.parametrize("n", [3, 8, 32])
def test_decode_is_the_sum_of_eigenvalue_weighted_outer_products(kind, n):
    """K = Σ_i λ_i q_i q_iᵀ, one candidate at a time, equals the batched decode to 1e-13."""
    rng = np.random.default_rng(n)
    p = make(kind, n, (0.1, 10.0))
    lb, ub = p.bounds()
    Z = lb + (ub - lb) * rng.uniform(size=(4, p.dim))
    Q = p.orthogonal(Z)
    K = p.decode(Z)
    for b in range(Z.shape[0]):
        ref = sum(Z[b, i] * np.outer(Q[b][:, i], Q[b][:, i]) for i in range(n))
        np.testing.assert_allclose(K[b], ref, rtol=0, atol=1e-13 * 10.0)
        np.testing.assert_array_equal(K[b], K[b].T)


@pytest.mark.parametrize("n", [0, -1, 2.5, "2", None, True])
def test_the_size_must_be_a_positive_integer(n):
    with pytest.raises(ConfigError, match="^n: the matrix size must be a positive integer"):
        make("full", n, (0.1, 10.0))


def test_a_numpy_integer_size_is_a_size():
    assert make("givens", np.int64(3), (0.1, 10.0)).n == 3


def test_bounds_that_are_not_numbers_are_one_config_error():
    with pytest.raises(ConfigError, match="^param.eig_bounds: need two numbers"):
        make("full", 2, ("a", "b"))
