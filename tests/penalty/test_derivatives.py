"""Exact derivatives of the maps against complex step and central differences.

The complex-step references are plain-numpy decodes written for complex dtype from the
documented constructions (hypersphere + Gram–Schmidt twice of e_1..e_N, Givens product,
Cayley solve), independent of the compiled kernels and of the derivative code.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.penalty import NotDifferentiableError, make
from penaltyrun.penalty import orthogonal as orth
from penaltyrun.penalty.derivatives import hypersphere_jacobian

KINDS = ("diagonal", "geagsp", "givens", "cayley", "cayley_tan")
NS = (2, 3, 4, 6)
H_CS = 1e-30


# --------------------------------------------------------------------------- references


def c_hypersphere(phi):
    k = len(phi)
    v = np.empty(k + 1, complex)
    s = 1.0 + 0j
    for j in range(k):
        v[j] = s * np.cos(phi[j])
        s = s * np.sin(phi[j])
    v[k] = s
    return v


def c_complement(placed, n, residuals=None):
    """Gram–Schmidt twice of e_1..e_N (analytic norm √Σr², skip on the real part)."""
    basis = []
    for j in range(n):
        if len(basis) == n - placed.shape[1]:
            break
        r = np.zeros(n, complex)
        r[j] = 1.0
        for _ in range(2):
            for c in range(placed.shape[1]):
                r = r - (placed[:, c] @ r) * placed[:, c]
            for b in basis:
                r = r - (b @ r) * b
        nrm = np.sqrt(np.sum(r * r))
        if residuals is not None:
            residuals.append(nrm.real)
        if nrm.real > orth.GS_SKIP:
            basis.append(r / nrm)
    return np.array(basis).T


def c_orthogonal(kind, ang, n, residuals=None):
    if kind == "diagonal":
        return np.eye(n, dtype=complex)
    if kind == "geagsp":
        Q = np.zeros((n, n), complex)
        pos = 0
        for col in range(n - 1):
            k = n - 1 - col
            v = c_hypersphere(ang[pos:pos + k])
            pos += k
            Q[:, col] = v if col == 0 else c_complement(Q[:, :col], n, residuals) @ v
        Q[:, n - 1] = c_complement(Q[:, : n - 1], n, residuals)[:, 0]
        return Q
    if kind == "givens":
        Q = np.eye(n, dtype=complex)
        pos = 0
        for j in range(n - 1):
            for i in range(j + 1, n):
                G = np.eye(n, dtype=complex)
                c, s = np.cos(ang[pos]), np.sin(ang[pos])
                G[j, j], G[j, i], G[i, j], G[i, i] = c, s, -s, c
                Q = Q @ G
                pos += 1
        return Q
    ent = np.tan(ang) if kind == "cayley_tan" else ang
    C = np.zeros((n, n), complex)
    C[np.triu_indices(n, 1)] = ent
    C = C - C.T
    return np.linalg.solve(np.eye(n) + C, np.eye(n) - C)


def c_decode(kind, z, n):
    Q = c_orthogonal(kind, z[n:], n)
    return (Q * z[:n]) @ Q.T


def complex_step_jacobian(kind, z, n):
    out = []
    for i in range(z.size):
        zc = z.astype(complex)
        zc[i] += 1j * H_CS
        out.append(c_decode(kind, zc, n).imag / H_CS)
    return np.array(out)


def central_jacobian(p, z, rel=1e-6):
    out = []
    for i in range(z.size):
        h = rel * max(1.0, abs(z[i]))
        e = np.zeros(z.size)
        e[i] = h
        out.append((p.decode(z + e) - p.decode(z - e)) / (2 * h))
    return np.array(out)


def interior(p, rng, margin=0.02):
    lb, ub = p.bounds()
    return lb + (ub - lb) * rng.uniform(margin, 1 - margin, p.dim)


def rel_err(a, b):
    return np.abs(a - b).max() / max(np.abs(b).max(), 1e-300)


# --------------------------------------------------------------------------- tests


def test_reference_decode_equals_the_package_decode():
    rng = np.random.default_rng(1)
    for kind in KINDS:
        for n in NS:
            p = make(kind, n, (0.1, 10.0))
            z = interior(p, rng)
            assert np.allclose(c_decode(kind, z.astype(complex), n).real, p.decode(z),
                               atol=1e-12, rtol=0)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", NS)
def test_jacobian_equals_complex_step_and_central_differences(kind, n):
    rng = np.random.default_rng(100 + n)
    p = make(kind, n, (0.1, 10.0), cayley_bound=5.0)
    for _ in range(3):
        z = interior(p, rng)
        J = p.jacobian(z)
        assert J.shape == (p.dim, n, n)
        assert rel_err(J, complex_step_jacobian(kind, z, n)) < 1e-10
        assert rel_err(J, central_jacobian(p, z)) < 1e-6
        assert np.allclose(J, np.transpose(J, (0, 2, 1)), atol=1e-14 * np.abs(J).max())


@pytest.mark.parametrize("kind", ("givens", "cayley", "cayley_tan"))
def test_jacobian_at_the_box_corners(kind):
    """The smooth maps are differentiable on the bounds (z at lb, at ub, mixed)."""
    rng = np.random.default_rng(7)
    n = 4
    p = make(kind, n, (0.1, 10.0), cayley_bound=3.0)
    lb, ub = p.bounds()
    for z in (lb, ub, np.where(rng.uniform(size=p.dim) < 0.5, lb, ub)):
        J = p.jacobian(z)
        assert rel_err(J, complex_step_jacobian(kind, z, n)) < 1e-10
        assert rel_err(J, central_jacobian(p, z)) < 1e-6


def geagsp_min_residual(z, n):
    res = []
    c_orthogonal("geagsp", z[n:].astype(complex), n, res)
    return min(res)


@pytest.mark.parametrize("n", (2, 3, 4, 5))
def test_geagsp_near_the_angle_bounds(n):
    """Angles 1e-2 from 0 and π (hypersphere poles) and from the 0 / 2π ends of the last ones.

    Angles near poles in several rows multiply their sines in later columns' Gram–Schmidt
    residuals (1e-2, 1e-4, 1e-6, …): where the reference construction's smallest residual
    is within a factor 2 of the skip threshold the map jumps, and NotDifferentiableError is the
    required answer; elsewhere the Jacobian must match.
    """
    rng = np.random.default_rng(11 + n)
    p = make("geagsp", n, (0.1, 10.0))
    lb, ub = p.bounds()
    checked = 0
    for _ in range(8):
        z = interior(p, rng)
        for i in range(n, p.dim):
            r = rng.uniform()
            if r < 0.2:
                z[i] = lb[i] + 1e-2
            elif r < 0.4:
                z[i] = ub[i] - 1e-2
        rmin = geagsp_min_residual(z, n)
        if rmin <= 2.0 * orth.GS_SKIP * (1 + 1e-6):
            with pytest.raises(NotDifferentiableError):
                p.jacobian(z)
            continue
        J = p.jacobian(z)
        h = min(1e-7, 1e-3 * rmin)
        assert rel_err(J, complex_step_jacobian("geagsp", z, n)) < 1e-9
        if rmin > 1e-4:  # below, the central-difference truncation error exceeds 1e-6
            assert rel_err(J, central_jacobian(p, z, rel=h)) < 1e-6
        checked += 1
    assert checked >= 4


def test_geagsp_one_angle_very_near_a_pole():
    p = make("geagsp", 4, (0.1, 10.0))
    z = interior(p, np.random.default_rng(4))
    for phi in (1e-4, np.pi - 1e-4):
        z[p.n] = phi
        J = p.jacobian(z)
        assert rel_err(J, complex_step_jacobian("geagsp", z, 4)) < 1e-9
        assert rel_err(J, central_jacobian(p, z, rel=1e-9)) < 1e-5


def test_geagsp_at_a_hypersphere_pole_is_reported_non_differentiable():
    """φ_1 = 0 puts column 1 on e_1: Gram–Schmidt skips e_1 and the map jumps there."""
    p = make("geagsp", 4, (0.1, 10.0))
    z = interior(p, np.random.default_rng(3))
    z[p.n] = 0.0
    with pytest.raises(NotDifferentiableError, match="no derivative"):
        p.jacobian(z)
    with pytest.raises(NotDifferentiableError):
        p.vjp(z, np.eye(4))
    z[p.n] = 1e-7  # residual sin φ below the skip threshold: discontinuous right there
    with pytest.raises(NotDifferentiableError):
        p.jacobian(z)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("n", (2, 3, 5, 8))
def test_vjp_equals_jacobian_contraction_for_nonsymmetric_g(kind, n):
    rng = np.random.default_rng(200 + n)
    p = make(kind, n, (0.1, 10.0))
    z = interior(p, rng)
    G = rng.normal(size=(n, n))
    g = p.vjp(z, G)
    assert g.shape == (p.dim,)
    assert rel_err(g, np.einsum("ab,iab->i", G, p.jacobian(z))) < 1e-12
    # only the symmetric part of G matters
    assert rel_err(p.vjp(z, 0.5 * (G + G.T)), g) < 1e-12


@pytest.mark.parametrize("kind", KINDS)
def test_vjp_is_the_gradient_of_a_scalar_of_k(kind):
    """f(K) = tr(A K) + ‖K‖²_F with A non-symmetric, G = A + 2K, against complex step."""
    rng = np.random.default_rng(5)
    n = 5
    p = make(kind, n, (0.1, 10.0))
    A = rng.normal(size=(n, n))
    z = interior(p, rng)

    def f(zc):
        K = c_decode(kind, zc, n)
        return np.trace(A @ K) + np.sum(K * K)

    ref = np.array([f(z + 1j * H_CS * e).imag / H_CS for e in np.eye(p.dim)])
    assert rel_err(p.vjp(z, A + 2.0 * p.decode(z)), ref) < 1e-10


@settings(max_examples=25, deadline=None)
@given(kind=st.sampled_from(KINDS), n=st.integers(2, 6), seed=st.integers(0, 2**32 - 1))
def test_jacobian_properties(kind, n, seed):
    """dK/dλ_i = q_i q_iᵀ (trace 1); angle slices keep the spectrum: tr dK = tr(K dK) = 0."""
    rng = np.random.default_rng(seed)
    p = make(kind, n, (0.1, 10.0))
    z = interior(p, rng, margin=0.01)
    try:
        J = p.jacobian(z)
    except NotDifferentiableError:
        assert kind == "geagsp"
        return
    K = p.decode(z)
    scale = np.abs(J).max()
    assert np.allclose(np.trace(J[:n], axis1=1, axis2=2), 1.0, atol=1e-12)
    assert np.allclose(np.trace(J[n:], axis1=1, axis2=2), 0.0, atol=1e-12 * scale)
    assert np.allclose(np.einsum("ab,iba->i", K, J[n:]), 0.0,
                       atol=1e-11 * scale * np.abs(K).max())
    assert np.allclose(J, np.transpose(J, (0, 2, 1)), atol=1e-14 * scale)


@settings(max_examples=40, deadline=None)
@given(k=st.integers(1, 7), seed=st.integers(0, 2**32 - 1))
def test_hypersphere_jacobian(k, seed):
    phi = np.random.default_rng(seed).uniform(0, np.pi, k)
    v, D = hypersphere_jacobian(phi)
    assert np.isclose(v @ v, 1.0)
    ref = np.array([c_hypersphere(phi + 1j * H_CS * e).imag / H_CS for e in np.eye(k)])
    assert np.allclose(D, ref, atol=1e-13)
    assert np.allclose(D @ v, 0.0, atol=1e-13)


def test_geagsp_jacobian_at_n12():
    rng = np.random.default_rng(12)
    p = make("geagsp", 12, (0.1, 10.0))
    z = interior(p, rng)
    J = p.jacobian(z)
    assert rel_err(J, central_jacobian(p, z)) < 1e-6
    G = rng.normal(size=(12, 12))
    assert rel_err(p.vjp(z, G), np.einsum("ab,iab->i", G, J)) < 1e-12


def test_bad_shapes_are_value_errors():
    p = make("givens", 3, (0.1, 10.0))
    with pytest.raises(ValueError, match="expects z of shape"):
        p.jacobian(np.zeros(5))
    with pytest.raises(ValueError, match="G must have shape"):
        p.vjp(np.zeros(p.dim), np.zeros((2, 2)))


@pytest.mark.parametrize("kind", KINDS)
def test_one_by_one_matrix(kind):
    p = make(kind, 1, (0.1, 10.0))
    np.testing.assert_array_equal(p.jacobian(np.array([2.0])), [[[1.0]]])
    np.testing.assert_array_equal(p.vjp(np.array([2.0]), np.array([[3.0]])), [3.0])
