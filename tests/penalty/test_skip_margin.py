"""GEAGSP's skip margin: the distance of a decision vector from a jump of the map."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.penalty import orthogonal as orth
from penaltyrun.penalty.layout import DecisionLayout
from penaltyrun.penalty.maps import make


def ref_margin(angles, n, skip=orth.GS_SKIP):
    """The definition in plain numpy: min |r − skip| over every residual examined."""
    Q = np.zeros((n, n))
    margin = np.inf
    pos = 0
    for col in range(n):
        k = n - 1 - col
        if col == 0:
            v = np.empty(n)
            s = 1.0
            for j in range(k):
                v[j] = s * np.cos(angles[j])
                s *= np.sin(angles[j])
            v[k] = s
            Q[:, 0] = v
            pos += k
            continue
        basis = []
        for j in range(n):
            if len(basis) == n - col:
                break
            r = np.zeros(n)
            r[j] = 1.0
            for _ in range(2):
                for c in range(col):
                    r -= (Q[:, c] @ r) * Q[:, c]
                for b in basis:
                    r -= (b @ r) * b
            margin = min(margin, abs(np.linalg.norm(r) - skip))
            if np.linalg.norm(r) > skip:
                basis.append(r / np.linalg.norm(r))
        B = np.array(basis).T
        if k > 0:
            phi = angles[pos:pos + k]
            pos += k
            v = np.empty(k + 1)
            s = 1.0
            for j in range(k):
                v[j] = s * np.cos(phi[j])
                s *= np.sin(phi[j])
            v[k] = s
            Q[:, col] = B @ v
        else:
            Q[:, col] = B[:, 0]
    return margin


@pytest.mark.parametrize("n", (2, 3, 4, 5, 6))
def test_margin_matches_its_definition_at_random_points(n):
    rng = np.random.default_rng(n)
    lb, ub = orth.geagsp_angle_bounds(n)
    A = rng.uniform(lb, ub, size=(50, len(lb)))
    np.testing.assert_allclose(orth.geagsp_skip_margin(A, n),
                               [ref_margin(a, n) for a in A], rtol=1e-9, atol=1e-15)


def test_two_by_two_margin_in_closed_form():
    # N = 2: Q = [(cos φ, sin φ), e_1's residual], whose norm is |sin φ|.
    phi = np.array([0.0, 1e-7, 5e-7, 2e-6, 1e-3, 0.3, 0.5 * np.pi, np.pi - 1e-4, 4.0])
    np.testing.assert_allclose(orth.geagsp_skip_margin(phi[:, None], 2),
                               np.abs(np.abs(np.sin(phi)) - orth.GS_SKIP), rtol=1e-9,
                               atol=1e-18)


@pytest.mark.parametrize("n", (3, 4, 6))
def test_at_a_pole_the_margin_is_the_threshold(n):
    # First angle 0: column 1 is e_1, whose residual is 0 up to rounding (skipped).
    lb, ub = orth.geagsp_angle_bounds(n)
    a = 0.5 * (lb + ub)
    a[0] = 0.0
    assert orth.geagsp_skip_margin(a, n) == pytest.approx(orth.GS_SKIP, rel=1e-9)


def test_q_jumps_where_the_margin_is_zero_and_not_elsewhere():
    # N = 3 next to the pole of the first angle: sin φ crosses the threshold at φ ≈ 1e-6.
    n = 3
    rest = np.array([1.0, 2.0])
    phis = np.linspace(0.5e-6, 1.5e-6, 201)
    A = np.column_stack([phis, np.tile(rest, (phis.size, 1))])
    Q = orth.geagsp_batch(A, n)
    step = np.abs(np.diff(Q, axis=0)).max(axis=(1, 2))
    jumps = np.flatnonzero(step > 0.1)
    assert jumps.size >= 1  # two residuals ∝ sin φ cross the threshold in this range
    assert np.delete(step, jumps).max() < 1e-4
    margins = orth.geagsp_skip_margin(A, n)
    assert np.all(np.minimum(margins[jumps], margins[jumps + 1]) < 1e-8)
    far = np.array([[0.7, 1.0, 2.0]])
    assert orth.geagsp_skip_margin(far, n)[0] > 0.1


def test_margin_kernel_leaves_q_bit_identical():
    rng = np.random.default_rng(1)
    lb, ub = orth.geagsp_angle_bounds(5)
    A = rng.uniform(lb, ub, size=(64, len(lb)))
    Q, _ = orth._geagsp_batch_margin(A, 5)
    np.testing.assert_array_equal(Q, orth.geagsp_batch(A, 5))


@pytest.mark.parametrize("kind", ("diagonal", "givens", "cayley", "cayley_tan"))
def test_continuous_maps_have_no_skip(kind):
    p = make(kind, 4, (0.1, 10.0))
    lb, ub = p.bounds()
    Z = np.random.default_rng(2).uniform(lb, ub, size=(7, p.dim))
    assert np.all(np.isinf(p.skip_margin(Z)))
    assert p.skip_margin(Z[0]) == np.inf


def test_layout_margin_is_the_smallest_over_blocks():
    Q, R = make("geagsp", 4, (0.1, 10.0)), make("geagsp", 3, (0.1, 10.0))
    layout = DecisionLayout((("Q", Q), ("R", R), ("K", make("givens", 2, (0.1, 1.0)))),
                            (("eta", (0.0, 1.0)),))
    lb, ub = layout.bounds()
    Z = np.random.default_rng(3).uniform(lb, ub, size=(9, layout.dim))
    Z[0, 4] = 0.0  # first angle of Q at its pole
    expect = np.minimum(Q.skip_margin(Z[:, :Q.dim]), R.skip_margin(Z[:, Q.dim:Q.dim + R.dim]))
    np.testing.assert_array_equal(layout.skip_margin(Z), expect)
    assert layout.skip_margin(Z)[0] == pytest.approx(orth.GS_SKIP, rel=1e-9)
    with pytest.raises(ValueError, match="decision variables"):
        layout.skip_margin(Z[:, :-1])


@pytest.mark.parametrize("n", (2, 3, 6))
def test_every_diagonal_matrix_sits_on_a_geagsp_jump(n):
    # Q = I (up to signs) needs the first angle of each row at a pole: residual 0.
    rng = np.random.default_rng(n)
    geagsp, givens = make("geagsp", n, (0.1, 10.0)), make("givens", n, (0.1, 10.0))
    for _ in range(3):
        K = np.diag(rng.uniform(0.2, 9.0, n))
        z = geagsp.encode(K)
        np.testing.assert_allclose(geagsp.decode(z), K, atol=1e-12)
        assert geagsp.skip_margin(z) == pytest.approx(orth.GS_SKIP, rel=1e-6)
        np.testing.assert_array_equal(givens.encode(K)[n:], 0.0)  # the centre of its box
