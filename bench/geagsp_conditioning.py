"""Is GEAGSP's decode determined by its definition at large N? And what would an O(N³) update give?

GEAGSP builds each column's complement basis by Gram–Schmidt of e_1 … e_N (O(N⁴) per
candidate). For random angles the Gram–Schmidt residuals shrink roughly like a product of
sines from column to column, so at large N they fall to the skip threshold (1e-6) and
below, where the construction amplifies rounding errors. This script measures, for
random z in the box, per N:

* ``skip``: the fraction of z at which a residual is within a factor 2 of the skip
  threshold (there GEAGSP has no derivative, ``NotDifferentiableError``);
* ``prod``: max |Q − Q_ld| of the production decode against the same construction in
  80-bit long double (``np.longdouble``), median and max over the z;
* ``numpy``: the same for a plain-numpy double implementation of the same construction
  (``tests/penalty/test_orthogonal.py``'s reference), i.e. how far two correct double
  implementations of one definition fall apart;
* ``update``: an O(N³) alternative (the basis updated from column to column by the
  rank-one QR downdate with 2(m − 1) plane rotations, Golub & Van Loan §12.5, falling back
  to Gram–Schmidt from the first column whose residual falls below ``--tau``): its error
  and CPU time against the production decode.

Usage: ``python bench/geagsp_conditioning.py [--count 12] [--tau 1e-3]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from machine import machine
from numba import njit

from penaltyrun.penalty import NotDifferentiableError, make
from penaltyrun.penalty import orthogonal as orth
from penaltyrun.penalty.orthogonal import _complement_basis, _hypersphere

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "penalty"))
from test_orthogonal import ref_geagsp  # noqa: E402

LD = np.longdouble


def _ld_complement(placed: np.ndarray, n: int) -> np.ndarray:
    basis: list = []
    for j in range(n):
        if len(basis) == n - placed.shape[1]:
            break
        r = np.zeros(n, LD)
        r[j] = 1
        for _ in range(2):
            for c in range(placed.shape[1]):
                r -= (placed[:, c] @ r) * placed[:, c]
            for b in basis:
                r -= (b @ r) * b
        nrm = np.sqrt(np.sum(r * r))
        if nrm > orth.GS_SKIP:
            basis.append(r / nrm)
    return np.array(basis).T


def geagsp_longdouble(angles: np.ndarray, n: int) -> np.ndarray:
    """The documented construction in 80-bit long double."""
    angles = np.asarray(angles, LD)
    Q = np.zeros((n, n), LD)
    pos = 0
    for col in range(n - 1):
        k = n - 1 - col
        phi = angles[pos:pos + k]
        pos += k
        v = np.empty(k + 1, LD)
        s = LD(1)
        for j in range(k):
            v[j] = s * np.cos(phi[j])
            s = s * np.sin(phi[j])
        v[k] = s
        Q[:, col] = v if col == 0 else _ld_complement(Q[:, :col], n) @ v
    Q[:, n - 1] = _ld_complement(Q[:, : n - 1], n)[:, 0]
    return Q


@njit(cache=True)
def _rotate_rows(X, r0, r1, c, s, lo, hi):
    """Rows r0, r1 of X, columns lo..hi−1 ← [c s; −s c] · (row r0, row r1)."""
    for m in range(lo, hi):
        a = X[r0, m]
        b = X[r1, m]
        X[r0, m] = c * a + s * b
        X[r1, m] = -s * a + c * b


@njit(cache=True)
def _downdate_basis(Bt, H, m, v, n):
    """Remove the direction Σ v_k b_k from the echelon basis b_0..b_{m−1} (rows of Bt).

    On entry the rows of Bt[:m] are the Gram–Schmidt basis of the complement of the placed
    columns, so Bt[:m, :m] = T is upper triangular with a positive diagonal (P E = B T).
    The basis of the next complement is the Q factor of (I − v vᵀ) T: T + v wᵀ with
    w = −Tᵀv is reduced to triangular form by 2(m − 1) plane rotations (Golub & Van Loan,
    the rank-one QR update), applied to the rows of Bt as well. Rows Bt[:m − 1] are then the
    Gram–Schmidt basis of the next complement, in O(n m) operations instead of O(n m²).

    Returns the smallest new diagonal entry (the Gram–Schmidt residual norms).
    """
    for i in range(m):
        for j in range(m):
            H[i, j] = Bt[i, j] if j >= i else 0.0
    w = np.zeros(m)
    for j in range(m):
        acc = 0.0
        for i in range(j + 1):
            acc += H[i, j] * v[i]
        w[j] = -acc
    u = v[:m].copy()
    for k in range(m - 2, -1, -1):
        r = np.hypot(u[k], u[k + 1])
        if r == 0.0:
            continue
        c = u[k] / r
        s = u[k + 1] / r
        u[k] = r
        u[k + 1] = 0.0
        _rotate_rows(H, k, k + 1, c, s, k, m)
        _rotate_rows(Bt, k, k + 1, c, s, 0, n)
    for j in range(m):
        H[0, j] += u[0] * w[j]
    smallest = np.inf
    for k in range(m - 1):
        r = np.hypot(H[k, k], H[k + 1, k])
        if r > 0.0:
            c = H[k, k] / r
            s = H[k + 1, k] / r
            _rotate_rows(H, k, k + 1, c, s, k, m)
            _rotate_rows(Bt, k, k + 1, c, s, 0, n)
        smallest = min(smallest, r)
    return smallest


@njit(cache=True)
def geagsp_update(angles, n, tau):
    """GEAGSP with the basis updated by rotations while every residual stays ≥ tau."""
    B = angles.shape[0]
    Q = np.zeros((B, n, n))
    Bt = np.empty((n, n))
    H = np.empty((n, n))
    v = np.empty(n)
    basis = np.empty((n, n))
    for b in range(B):
        Qb = Q[b]
        for i in range(n):
            for j in range(n):
                Bt[i, j] = 1.0 if i == j else 0.0
        direct_from = n
        pos = 0
        for col in range(n):
            m = n - col
            if m > 1:
                _hypersphere(angles[b, pos:pos + m - 1], v[:m])
                pos += m - 1
            else:
                v[0] = 1.0
            if col >= direct_from:
                _complement_basis(Qb, col, n, basis)
                for i in range(m):
                    for j in range(n):
                        Bt[i, j] = basis[j, i]
            for j in range(n):
                acc = 0.0
                for i in range(m):
                    acc += Bt[i, j] * v[i]
                Qb[j, col] = acc
            if m > 1 and col < direct_from:
                if _downdate_basis(Bt, H, m, v, n) < tau:
                    direct_from = col + 1
    return Q


def cpu(func, reps: int) -> float:
    t0 = time.process_time()
    for _ in range(reps):
        func()
    return (time.process_time() - t0) / reps


def interleaved(A: np.ndarray, n: int, tau: float) -> tuple[list, list]:
    """CPU seconds per candidate of the production decode and the update, 5 rounds."""
    reps = max(1, 4000 // n ** 2)
    t_prod: list = []
    t_upd: list = []
    pair = [(t_prod, lambda: orth.geagsp_batch(A, n)), (t_upd, lambda: geagsp_update(A, n, tau))]
    for r in range(5):
        for out, f in (pair if r % 2 == 0 else pair[::-1]):
            out.append(cpu(f, reps) / A.shape[0])
    return t_prod, t_upd


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--count", type=int, default=12, help="random z per N")
    ap.add_argument("--tau", type=float, default=1e-3)
    args = ap.parse_args()
    print(machine(), time.strftime("%Y-%m-%d"), "CPU time")
    rng = np.random.default_rng(0)
    print(f"{'N':>3s} {'skip':>5s} | {'prod med':>8s} {'prod max':>8s} | {'numpy med':>9s} "
          f"{'numpy max':>9s} | {'update med':>10s} {'update max':>10s} | "
          f"{'prod µs':>8s} {'update µs':>9s}  (errors: max |ΔQ| against long double)")
    for n in (4, 8, 12, 16, 24, 32):
        p = make("geagsp", n, (0.1, 10.0))
        lb, ub = p.bounds()
        Z = lb + (ub - lb) * rng.uniform(size=(args.count, p.dim))
        A = np.ascontiguousarray(Z[:, n:])
        ex = np.array([geagsp_longdouble(a, n).astype(float) for a in A])
        prod = orth.geagsp_batch(A, n)
        upd = geagsp_update(A, n, args.tau)
        ref = np.array([ref_geagsp(a, n) for a in A])
        skip = 0
        for z in Z:
            try:
                p.vjp(z, np.eye(n))
            except NotDifferentiableError:
                skip += 1
        e = {k: np.abs(q - ex).max(axis=(1, 2)) for k, q in
             (("prod", prod), ("numpy", ref), ("update", upd))}
        t_prod, t_upd = interleaved(A, n, args.tau)
        print(f"{n:3d} {skip / args.count:5.2f} | {np.median(e['prod']):8.1e} "
              f"{e['prod'].max():8.1e} | {np.median(e['numpy']):9.1e} {e['numpy'].max():9.1e}"
              f" | {np.median(e['update']):10.1e} {e['update'].max():10.1e} | "
              f"{np.median(t_prod) * 1e6:8.1f} {np.median(t_upd) * 1e6:9.1f}")


if __name__ == "__main__":
    main()
