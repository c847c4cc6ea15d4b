"""LAPACK's real eigensolver ``dgeev`` callable from compiled (numba) code.

``numpy.linalg.eig`` calls ``dgeev`` and returns complex results when the spectrum is;
numba's own ``np.linalg.eig`` refuses a real matrix with complex eigenvalues. The binding
here calls ``dgeev`` from SciPy's LAPACK (``scipy.linalg.cython_lapack``) on the real
matrix, with the workspace size LAPACK asks for (as numpy does), and assembles complex
eigenvalues and eigenvectors exactly as numpy does from LAPACK's packed conjugate pairs:
the same algorithm on the same matrix, so the results agree with ``numpy.linalg.eig`` to
a few units of round-off (the tests compare them).
"""

from __future__ import annotations

import llvmlite.binding as llvm
import numpy as np
from numba import njit, types
from numba.extending import get_cython_function_address

#: The symbol compiled code calls: bound to SciPy's ``dgeev`` at import, before any cached
#: kernel is loaded, so that the kernels can be cached on disk (a ctypes function pointer
#: would be a dynamic global, which numba does not cache).
_SYMBOL = "penaltyrun_scipy_dgeev"
llvm.add_symbol(_SYMBOL, get_cython_function_address("scipy.linalg.cython_lapack", "dgeev"))
_dgeev = types.ExternalFunction(_SYMBOL, types.void(*([types.voidptr] * 14)))
_N = ord("N")
_V = ord("V")


@njit(cache=True)
def geev_workspace(n, vectors):
    """Optimal ``lwork`` of ``dgeev`` for an n × n matrix (LAPACK's workspace query)."""
    a = np.zeros((max(n, 1), max(n, 1)))
    wr = np.empty(max(n, 1))
    wi = np.empty(max(n, 1))
    vl = np.empty((1, 1))
    vr = np.empty((max(n, 1), max(n, 1)))
    work = np.empty(1)
    flags = np.array([_N, _V if vectors else _N], dtype=np.int8)
    ints = np.array([n, max(n, 1), 1, max(n, 1), -1, 0], dtype=np.int32)
    _dgeev(flags[0:].ctypes, flags[1:].ctypes, ints[0:].ctypes, a.ctypes, ints[1:].ctypes,
           wr.ctypes, wi.ctypes, vl.ctypes, ints[2:].ctypes, vr.ctypes, ints[3:].ctypes,
           work.ctypes, ints[4:].ctypes, ints[5:].ctypes)
    return max(int(work[0]), 4 * n, 1)


@njit(cache=True)
def geev(A, work, vectors):
    """Eigenvalues (and right eigenvectors) of a real square matrix.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Real matrix (not modified).
    work : ndarray, shape (lwork,)
        Workspace of :func:`geev_workspace` ``(n, vectors)`` entries (reused between calls).
    vectors : bool
        Also compute the right eigenvectors.

    Returns
    -------
    lam : ndarray of complex, shape (n,)
        Eigenvalues in LAPACK's order.
    V : ndarray of complex, shape (n, n)
        Unit right eigenvectors as columns (empty (0, 0) without ``vectors``).
    info : int
        LAPACK's ``info``: 0 on success, > 0 when the QR algorithm did not converge.
    """
    n = A.shape[0]
    a = np.ascontiguousarray(A.T)  # Fortran order of A
    wr = np.empty(n)
    wi = np.empty(n)
    vl = np.empty((1, 1))
    vr = np.empty((n, n))
    flags = np.array([_N, _V if vectors else _N], dtype=np.int8)
    ints = np.array([n, max(n, 1), 1, max(n, 1), work.size, 0], dtype=np.int32)
    _dgeev(flags[0:].ctypes, flags[1:].ctypes, ints[0:].ctypes, a.ctypes, ints[1:].ctypes,
           wr.ctypes, wi.ctypes, vl.ctypes, ints[2:].ctypes, vr.ctypes, ints[3:].ctypes,
           work.ctypes, ints[4:].ctypes, ints[5:].ctypes)
    lam = wr + 1j * wi
    if not vectors:
        return lam, np.empty((0, 0), dtype=np.complex128), int(ints[5])
    V = np.empty((n, n), dtype=np.complex128)
    j = 0
    while j < n:  # vr is Fortran order: column j of the vectors is row j of vr
        if wi[j] != 0.0 and j + 1 < n:
            for i in range(n):
                V[i, j] = vr[j, i] + 1j * vr[j + 1, i]
                V[i, j + 1] = vr[j, i] - 1j * vr[j + 1, i]
            j += 2
        else:
            for i in range(n):
                V[i, j] = vr[j, i]
            j += 1
    return lam, V, int(ints[5])


__all__ = ["geev", "geev_workspace"]
