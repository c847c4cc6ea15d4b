"""LAPACK's dgeev called from compiled code (penaltyrun/dynamics/lapack.py) against
numpy.linalg.eig / eigvals."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.dynamics.lapack import geev, geev_workspace


def _sorted(lam: np.ndarray) -> np.ndarray:
    return lam[np.lexsort((lam.imag, lam.real))]


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 16])
def test_eigenpairs_match_numpy(n):
    rng = np.random.default_rng(n)
    work = np.empty(geev_workspace(n, True))
    work_n = np.empty(geev_workspace(n, False))
    for _ in range(20):
        A = rng.normal(size=(n, n))
        lam, V, info = geev(A, work, True)
        lam_np, V_np = np.linalg.eig(A)
        assert info == 0
        scale = max(1.0, np.max(np.abs(lam_np)))
        np.testing.assert_allclose(lam, lam_np, rtol=0, atol=1e-12 * scale)  # same order
        np.testing.assert_allclose(V, V_np, rtol=0, atol=1e-12)
        np.testing.assert_allclose(A @ V, V * lam, rtol=0, atol=1e-11 * scale)
        only, _, info = geev(A, work_n, False)
        assert info == 0
        np.testing.assert_allclose(_sorted(only), _sorted(np.linalg.eigvals(A)), rtol=0,
                                   atol=1e-12 * scale)


def test_real_spectrum_and_input_left_alone():
    A = np.array([[2.0, 1.0], [0.0, -3.0]])
    kept = A.copy()
    lam, V, info = geev(A, np.empty(geev_workspace(2, True)), True)
    assert info == 0 and np.array_equal(A, kept)
    assert np.allclose(np.sort(lam.real), [-3.0, 2.0]) and np.all(lam.imag == 0.0)
    assert np.allclose(np.linalg.norm(V, axis=0), 1.0)
