"""Penalty-map decodes (z → K) and their exact derivatives: CPU time per candidate.

For each map and N = 4, 8, 16, 32: the production batch decode (B, dim) → (B, N, N) against
the previous implementation, kept below as the baseline (K by a three-operand ``einsum``,
Givens rotations on strided columns of Q; GEAGSP and Cayley build Q as before), measured
in the same run with the pairs interleaved (the machine is shared); then the cost of one
``vjp`` and one ``jacobian`` relative to one decode. CPU time (``time.process_time``).
Prints min and median of the per-round ratios. Usage:
``python bench/bench_decode.py [--rounds 7] [--batch 24]``.

GEAGSP derivatives are timed at z from the middle half of each angle range: at N ≥ 24
almost every z of the whole box has a skipped Gram–Schmidt vector, where the map has no
derivative (see ``bench/geagsp_conditioning.py``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine
from numba import njit

from penaltyrun.penalty import make

KINDS = ("diagonal", "geagsp", "givens", "cayley", "cayley_tan")
NS = (4, 8, 16, 32)


@njit(cache=True)
def givens_batch_columns(angles, n):
    """Baseline: the previous Givens kernel (rotations on strided columns of Q)."""
    B = angles.shape[0]
    Q = np.zeros((B, n, n))
    for b in range(B):
        Qb = Q[b]
        for m in range(n):
            Qb[m, m] = 1.0
        pos = 0
        for j in range(n - 1):
            for i in range(j + 1, n):
                c = np.cos(angles[b, pos])
                s = np.sin(angles[b, pos])
                pos += 1
                for m in range(n):
                    a_j = Qb[m, j]
                    a_i = Qb[m, i]
                    Qb[m, j] = c * a_j - s * a_i
                    Qb[m, i] = s * a_j + c * a_i
    return Q


def baseline_decode(p, Z: np.ndarray) -> np.ndarray:
    """The previous ``Parameterization.decode`` (its checks included) for a batch."""
    Z = np.asarray(Z, float)
    single = Z.ndim == 1
    Zb = np.atleast_2d(Z)
    if Zb.shape[1] != p.dim:
        raise ValueError(f"{p.kind} (N={p.n}) expects {p.dim} variables")
    lam = Zb[:, : p.n]
    if p.kind == "diagonal":
        K = lam[:, :, None] * np.eye(p.n)[None]
    else:
        ang = np.ascontiguousarray(Zb[:, p.n:])
        Q = givens_batch_columns(ang, p.n) if p.kind == "givens" else p.orthogonal(Zb)
        K = np.einsum("bij,bj,bkj->bik", Q, lam, Q)
        K = 0.5 * (K + np.transpose(K, (0, 2, 1)))
    return K[0] if single else K


def cpu(func, min_time: float = 0.02) -> float:
    """CPU seconds per call, repeating until at least ``min_time`` has been spent."""
    reps = 1
    while True:
        t0 = time.process_time()
        for _ in range(reps):
            func()
        dt = time.process_time() - t0
        if dt >= min_time:
            return dt / reps
        reps *= 2


def middle_z(p, rng: np.random.Generator) -> np.ndarray:
    lb, ub = p.bounds()
    return lb + (ub - lb) * rng.uniform(0.25, 0.75, p.dim)


def measure(p, Z: np.ndarray, z: np.ndarray, G: np.ndarray, flip: bool) -> tuple:
    """One interleaved round: (new, old) per candidate, decode of one z, vjp, jacobian."""
    pair = [("new", lambda: p.decode(Z)), ("old", lambda: baseline_decode(p, Z))]
    if flip:
        pair.reverse()
    t = {name: cpu(f) / Z.shape[0] for name, f in pair}
    return (t["new"], t["old"], cpu(lambda: p.decode(z)), cpu(lambda: p.vjp(z, G)),
            cpu(lambda: p.jacobian(z), min_time=0.005))


def stats(r: list[float]) -> str:
    return f"min {min(r):6.2f}  median {float(np.median(r)):6.2f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--batch", type=int, default=24, help="candidates per decode call")
    args = ap.parse_args()
    print(machine(), time.strftime("%Y-%m-%d"), "CPU time")
    rng = np.random.default_rng(0)
    cases = []
    for kind in KINDS:
        for n in NS:
            p = make(kind, n, (0.1, 10.0))
            lb, ub = p.bounds()
            Z = lb + (ub - lb) * rng.uniform(size=(args.batch, p.dim))
            z = middle_z(p, rng)
            G = rng.normal(size=(n, n))
            assert np.allclose(p.decode(Z), baseline_decode(p, Z), rtol=0,
                               atol=1e-13 * np.abs(Z[:, :n]).max())
            p.vjp(z, G), p.jacobian(z)  # compile
            cases.append((p, Z, z, G))
    res: dict = {}
    for r in range(args.rounds):
        for p, Z, z, G in cases:
            res.setdefault((p.kind, p.n), []).append(measure(p, Z, z, G, bool(r % 2)))
    print(f"{'map':10s} {'N':>3s} {'new µs/cand':>11s} {'old µs/cand':>11s}  old/new ratio"
          f"                   vjp/decode(1)   vjp/decode(batch, per cand)  jacobian/decode(1)")
    for (kind, n), rows in res.items():
        a = np.array(rows)
        print(f"{kind:10s} {n:3d} {np.median(a[:, 0]) * 1e6:11.2f} {np.median(a[:, 1]) * 1e6:11.2f}"
              f"  {stats(list(a[:, 1] / a[:, 0]))}   {np.median(a[:, 3] / a[:, 2]):8.1f}"
              f"   {np.median(a[:, 3] / a[:, 0]):8.1f}   {np.median(a[:, 4] / a[:, 2]):10.1f}")
    print("GEAGSP Q construction is unchanged (O(N⁴) Gram–Schmidt): see "
          "bench/geagsp_conditioning.py for why an O(N³) update cannot reproduce it.")


if __name__ == "__main__":
    main()
