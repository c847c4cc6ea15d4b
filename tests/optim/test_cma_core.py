"""The CMA-ES update against an independent implementation (the ``cmaes`` package, same
normal samples), the box transformation against pycma's, and each stopping rule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.optim.cma_core import MARGIN, CMARun, from_box, to_box

cmaes = pytest.importorskip("cmaes")
cma = pytest.importorskip("cma")


class _Feed:
    """Stands in for both generators: hands out the rows of a fixed normal sample."""

    def __init__(self, Z: np.ndarray) -> None:
        self.Z = Z
        self.k = 0

    def randn(self, n: int) -> np.ndarray:  # the cmaes package: one candidate per call
        self.k += 1
        return self.Z[self.k - 1]

    def standard_normal(self, shape: tuple[int, int]) -> np.ndarray:  # CMARun: a population
        self.k += shape[0]
        return self.Z[self.k - shape[0]:self.k]


def ellipsoid(X: np.ndarray) -> np.ndarray:
    X = np.atleast_2d(X)
    scale = 10.0 ** (3 * np.arange(X.shape[1]) / max(X.shape[1] - 1, 1))
    return ((X - 0.3) ** 2 * scale).sum(axis=1)


def _mahalanobis(X: np.ndarray, mean: np.ndarray, sigma: float, C: np.ndarray) -> np.ndarray:
    """‖C^(-1/2) (x − m) / σ‖² of each candidate: ‖z‖² of its normal sample, whatever
    eigenvector basis the sampler used."""
    Y = (X - mean) / sigma
    return np.einsum("ki,ki->k", Y, np.linalg.solve(C, Y.T).T)


# The sampled points themselves depend on the eigenvectors of C, which LAPACK returns with
# an arbitrary sign and, where eigenvalues repeat (C starts as the identity), in an arbitrary
# basis of their eigenspace: two implementations (or two processors) then draw different
# points from the same normal sample. So each sampler is checked by an invariant of its
# points (their Mahalanobis norms are the sample's norms), and both updates are fed the same
# population, whose results (mean, σ, C, paths) do not depend on a basis.
@pytest.mark.filterwarnings("ignore:divide by zero")  # λ = 2: cμ = 0, as in the reference
@pytest.mark.parametrize(("dim", "popsize"), [(2, None), (5, None), (12, None), (12, 22),
                                              (2, 2)])
def test_update_matches_the_cmaes_package(dim, popsize):
    rng = np.random.default_rng(dim)
    lam = popsize or 4 + int(3 * np.log(dim))
    gens = 60
    Z = rng.standard_normal((gens * lam, dim))
    mean0 = rng.random(dim)
    ours = CMARun(mean0, 0.4, lam, _Feed(Z))
    ref = cmaes.CMA(mean=mean0.copy(), sigma=0.4, population_size=lam)
    ref._rng = _Feed(Z)
    assert ours.eigen_gap < lam  # the decomposition every generation, as the reference's
    for g in range(gens):
        norms = (Z[g * lam:(g + 1) * lam] ** 2).sum(axis=1)
        before = (ours.mean.copy(), ours.sigma, ours.C.copy())
        X = ours.ask()
        Xr = np.array([ref.ask() for _ in range(lam)])
        np.testing.assert_allclose(_mahalanobis(X, *before), norms, rtol=1e-8)
        np.testing.assert_allclose(_mahalanobis(Xr, ref._mean, ref._sigma, ref._C), norms,
                                   rtol=1e-8)
        f = ellipsoid(X)
        ours.tell(X, f)
        ref.tell(list(zip(X, f)))
        np.testing.assert_allclose(ours.mean, ref.mean, rtol=1e-9, atol=1e-12)
        assert ours.sigma == pytest.approx(ref._sigma, rel=1e-9)
        np.testing.assert_allclose(ours.C, ref._C, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(ours.ps, ref._p_sigma, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(ours.pc, ref._pc, rtol=1e-9, atol=1e-12)


def test_box_transformation_is_pycmas():
    bound = cma.boundary_handler.BoundTransform([0.0, 1.0])
    rng = np.random.default_rng(3)
    X = np.concatenate([rng.normal(0.5, 1.0, (300, 5)), rng.normal(0.5, 30.0, (300, 5)),
                        rng.uniform(-0.2, 1.2, (300, 5)),
                        np.array([[-MARGIN, MARGIN, 1 - MARGIN, 1 + MARGIN, 0.5]])])
    ref = np.array([bound.repair(x) for x in X])
    np.testing.assert_allclose(to_box(X), ref, rtol=0, atol=1e-14)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=8))
def test_from_box_inverts_to_box(u):
    U = np.array([u])
    np.testing.assert_allclose(to_box(from_box(U)), U, atol=1e-12)


def _run(f, dim=4, popsize=8, gens=4000, **kw):
    rng = np.random.default_rng(0)
    es = CMARun(rng.random(dim), 0.3, popsize, rng, **kw)
    for _ in range(gens):
        X = es.ask()
        es.tell(X, f(X))
        reasons = es.stop()
        if reasons:
            return es, reasons
    raise AssertionError("no stopping rule met")


def test_tolfun_on_a_converged_sphere():
    es, reasons = _run(lambda X: ((X - 0.3) ** 2).sum(axis=1), tolfun=1e-8, tolx=0.0)
    assert "tolfun" in reasons
    assert np.all(np.abs(es.mean - 0.3) < 1e-3)


def test_tolx_when_steps_are_small():
    es, reasons = _run(lambda X: ((X - 0.3) ** 2).sum(axis=1), tolfun=0.0, tolx=1e-6)
    assert "tolx" in reasons
    assert es.sigma * np.sqrt(np.diag(es.C)).max() < 1e-6


def test_flat_fitness_stops_after_two_flat_generations():
    es, reasons = _run(lambda X: np.ones(len(X)), tolfun=0.0)
    assert reasons == ["tolflatfitness"] and es.g == 2


def test_stagnation_on_a_noisy_plateau():
    noise = np.random.default_rng(7)
    es, reasons = _run(lambda X: noise.random(len(X)), dim=2, popsize=6, tolfun=0.0,
                       tolx=0.0)
    assert "tolstagnation" in reasons
    assert es.g > es.tolstagnation


def test_maxiter_bounds_a_run():
    es, reasons = _run(lambda X: -np.abs(X).sum(axis=1) * 0 + np.arange(len(X)) * 1e-3,
                       dim=1, popsize=4, tolfun=0.0, tolx=0.0)
    assert reasons and es.g <= es.maxiter
