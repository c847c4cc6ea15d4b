"""The check of a user-given symmetric positive-definite matrix and its spectrum."""

import numpy as np
import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.problems.base import check_spd, spd_spectrum


def test_spectrum_is_the_checked_matrix_eigenvalues():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((4, 4))
    m = a @ a.T + 0.1 * np.eye(4)
    arr, eig = spd_spectrum("K", m.tolist(), 4)
    np.testing.assert_array_equal(arr, check_spd("K", m, 4))
    np.testing.assert_allclose(eig, np.linalg.eigvalsh(m), rtol=1e-14)
    assert np.all(np.diff(eig) >= 0)


@pytest.mark.parametrize("bad", [np.eye(3), [[1.0, 2.0], [0.0, 1.0]], [[1.0, 0.0], [0.0, -1.0]],
                                 [[1.0, np.nan], [np.nan, 1.0]], "text"])
def test_both_refuse_the_same_matrices(bad):
    for check in (check_spd, lambda *a: spd_spectrum(*a)[0]):
        with pytest.raises(ConfigError):
            check("K", bad, 2)
