"""Decision-vector layout (several matrices + scalars) and the binary selector S."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from penaltyrun.penalty import build_layout, make, selected_quadratic, selector

EIG = (0.1, 100.0)


@pytest.fixture
def layout():
    return build_layout([("K", make("geagsp", 3, EIG)), ("P", make("givens", 2, (1.0, 5.0)))],
                        [("eta", (0.5, 2.0))])


def test_dim_names_bounds(layout):
    assert layout.dim == 6 + 3 + 1
    names = layout.names()
    assert len(names) == layout.dim
    assert len(set(names)) == layout.dim
    assert names == ["K.lam1", "K.lam2", "K.lam3", "K.ang1", "K.ang2", "K.ang3",
                     "P.lam1", "P.lam2", "P.ang1", "eta"]
    lb, ub = layout.bounds()
    assert lb.shape == ub.shape == (layout.dim,)
    klb, kub = make("geagsp", 3, EIG).bounds()
    plb, pub = make("givens", 2, (1.0, 5.0)).bounds()
    np.testing.assert_array_equal(lb, np.concatenate([klb, plb, [0.5]]))
    np.testing.assert_array_equal(ub, np.concatenate([kub, pub, [2.0]]))


def test_split_shapes_and_values(layout):
    rng = np.random.default_rng(0)
    lb, ub = layout.bounds()
    Z = lb + rng.random((7, layout.dim)) * (ub - lb)
    mats, scalars = layout.split(Z)
    assert set(mats) == {"K", "P"} and set(scalars) == {"eta"}
    assert mats["K"].shape == (7, 3, 3) and mats["P"].shape == (7, 2, 2)
    np.testing.assert_array_equal(mats["K"], make("geagsp", 3, EIG).decode(Z[:, :6]))
    np.testing.assert_array_equal(mats["P"], make("givens", 2, (1.0, 5.0)).decode(Z[:, 6:9]))
    np.testing.assert_array_equal(scalars["eta"], Z[:, 9])
    # a copy, not a view of Z
    scalars["eta"][0] = -1.0
    assert Z[0, 9] != -1.0


def test_split_single_vector_is_a_batch_of_one(layout):
    lb, ub = layout.bounds()
    mats, scalars = layout.split(0.5 * (lb + ub))
    assert mats["K"].shape == (1, 3, 3)
    assert scalars["eta"].shape == (1,)


def test_split_wrong_dim(layout):
    with pytest.raises(ValueError, match="10"):
        layout.split(np.ones((2, 9)))


def test_split_join_round_trip(layout):
    rng = np.random.default_rng(1)
    lb, ub = layout.bounds()
    Z = lb + rng.random((10, layout.dim)) * (ub - lb)
    mats, scalars = layout.split(Z)
    for b in range(len(Z)):
        z = layout.join({k: v[b] for k, v in mats.items()}, {"eta": scalars["eta"][b]})
        assert z.shape == (layout.dim,)
        assert np.all(lb <= z) and np.all(z <= ub)
        mats2, scalars2 = layout.split(z)
        np.testing.assert_allclose(mats2["K"][0], mats["K"][b], atol=1e-10)
        np.testing.assert_allclose(mats2["P"][0], mats["P"][b], atol=1e-10)
        assert scalars2["eta"][0] == scalars["eta"][b]


def test_layout_without_scalars():
    lay = build_layout([("K", make("diagonal", 2, EIG))])
    assert lay.dim == 2
    assert lay.names() == ["K.lam1", "K.lam2"]
    z = lay.join({"K": np.diag([2.0, 3.0])})
    np.testing.assert_array_equal(z, [2.0, 3.0])
    lb, ub = lay.bounds()
    np.testing.assert_array_equal(lb, [0.1, 0.1])


# --------------------------------------------------------------------------- selector


def test_selector_matrix():
    S = selector(np.array([True, False, True]))
    np.testing.assert_array_equal(S, np.diag([1.0, 0.0, 1.0]))
    assert S.dtype == float
    np.testing.assert_array_equal(selector([1, 0]), np.diag([1.0, 0.0]))


@st.composite
def quadratic_case(draw):
    n = draw(st.integers(2, 6))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    K = A @ A.T + 0.1 * np.eye(n)  # full SPD, generic coupling
    mask = draw(arrays(bool, n))
    e = draw(arrays(np.float64, n, elements=st.floats(-10, 10)))
    return K, mask, e, rng


@settings(max_examples=100)
@given(case=quadratic_case())
def test_two_sided_ignores_untargeted_components_for_any_k(case):
    K, mask, e, rng = case
    base = selected_quadratic(e, K, mask)
    e2 = e.copy()
    e2[~mask] = rng.uniform(-1e3, 1e3, int((~mask).sum()))
    np.testing.assert_allclose(selected_quadratic(e2, K, mask), base,
                               rtol=1e-12, atol=1e-12)
    # equals the quadratic form of the targeted sub-vector
    se = np.where(mask, e, 0.0)
    np.testing.assert_allclose(base, se @ K @ se, rtol=1e-12, atol=1e-12)


@settings(max_examples=50)
@given(case=quadratic_case())
def test_all_targeted_equals_plain_quadratic(case):
    K, _, e, _ = case
    mask = np.ones(len(e), bool)
    for two_sided in (True, False):
        np.testing.assert_allclose(selected_quadratic(e, K, mask, two_sided=two_sided),
                                   e @ K @ e, rtol=1e-12, atol=1e-10)


def test_one_sided_form_differs_and_depends_on_untargeted():
    K = np.array([[2.0, 0.5, 0.3], [0.5, 1.0, 0.2], [0.3, 0.2, 3.0]])
    mask = np.array([True, False, True])
    e = np.array([1.0, 2.0, -1.0])
    two = selected_quadratic(e, K, mask)
    one = selected_quadratic(e, K, mask, two_sided=False)
    se = e * mask
    assert one == pytest.approx(e @ K @ se)
    assert two == pytest.approx(se @ K @ se)
    assert one != pytest.approx(two)
    e2 = e.copy()
    e2[1] = 5.0
    assert selected_quadratic(e2, K, mask, two_sided=False) != pytest.approx(one)
    assert selected_quadratic(e2, K, mask) == pytest.approx(two)


def test_selected_quadratic_batched_errors():
    rng = np.random.default_rng(0)
    K = np.diag([1.0, 2.0, 3.0]) + 0.1
    mask = np.array([True, True, False])
    E = rng.standard_normal((4, 5, 3))
    out = selected_quadratic(E, K, mask)
    assert out.shape == (4, 5)
    np.testing.assert_allclose(out[2, 3], selected_quadratic(E[2, 3], K, mask))


def test_layout_vjp_is_the_gradient_of_a_function_of_all_blocks(layout):
    """f = tr(A K) + tr(B P)² + 3 η, against central differences through ``split``."""
    rng = np.random.default_rng(0)
    A, Bm = rng.normal(size=(3, 3)), rng.normal(size=(2, 2))
    lb, ub = layout.bounds()
    z = lb + (ub - lb) * rng.uniform(0.1, 0.9, layout.dim)

    def f(zz):
        mats, sc = layout.split(zz)
        return np.trace(A @ mats["K"][0]) + np.trace(Bm @ mats["P"][0]) ** 2 + 3 * sc["eta"][0]

    mats, _ = layout.split(z)
    g = layout.vjp(z, {"K": A, "P": 2 * np.trace(Bm @ mats["P"][0]) * Bm}, {"eta": 3.0})
    h = 1e-6
    fd = np.array([(f(z + h * e) - f(z - h * e)) / (2 * h) for e in np.eye(layout.dim)])
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-7)
    # a block without a gradient contributes zeros
    g0 = layout.vjp(z, {"K": A})
    assert np.all(g0[3 + 3:] == 0.0)
    with pytest.raises(ValueError, match="expected z of shape"):
        layout.vjp(z[:-1], {})
