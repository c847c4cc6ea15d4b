"""Zermelo: evaluations per second of the production batch path vs scipy solve_ivp.

Both evaluate the same random PD gains at the paper's tolerances (rtol = atol = 1e-10);
the ratio is measured in the same run. Usage: ``python bench/bench_zermelo.py [--n 200]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun import problems
from penaltyrun.penalty import make as make_param
from penaltyrun.problems.zermelo import reference_cost


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="gains per batch")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    prob = problems.make("zermelo", None, {})
    par = make_param("full", 2, (0.05, 10.0))
    lb, ub = par.bounds()
    Z = np.random.default_rng(0).uniform(lb, ub, size=(args.n, par.dim))
    Ks = par.decode(Z)

    prob.evaluate_batch({"K": Ks[:2]})  # JIT warm-up, not timed
    t0 = time.perf_counter()
    for _ in range(args.repeats):
        fast = prob.evaluate_batch({"K": Ks})
    fast_rate = args.n * args.repeats / (time.perf_counter() - t0)

    n_ref = min(args.n, 40)
    t0 = time.perf_counter()
    ref = [reference_cost(K, prob.params)[0] for K in Ks[:n_ref]]
    ref_rate = n_ref / (time.perf_counter() - t0)
    err = np.max(np.abs(fast.cost[:n_ref] - ref) / np.abs(ref))

    decode_t0 = time.perf_counter()
    for _ in range(args.repeats):
        par.decode(Z)
    decode_rate = args.n * args.repeats / (time.perf_counter() - decode_t0)

    print(f"machine: {machine()}")
    print(f"production (numba DOPRI5, batch of {args.n}): {fast_rate:10.0f} evaluations/s")
    print(f"reference (scipy solve_ivp DOP853):        {ref_rate:10.1f} evaluations/s")
    print(f"speed-up: {fast_rate / ref_rate:.0f}x   (max relative cost difference {err:.1e})")
    print(f"GEAGSP decode: {decode_rate:.0f} matrices/s")


if __name__ == "__main__":
    main()
