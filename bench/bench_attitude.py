"""Attitude problems: production batch path vs scipy reference, and one default PSO start.

For ``attitude_lyapunov`` and ``attitude_lqr`` (detumble, t_max = 100 s, rtol = atol = 1e-10)
the same candidates, drawn uniformly in the full (GEAGSP) box of each tuned matrix
(eigenvalues in [1e-8, 10]), are evaluated by

* the production path (``Problem.evaluate_batch``: batched Riccati for LQR + numba
  Dormand–Prince 8(5,3) with the event searched on the dense output), timed after JIT
  warm-up;
* the reference (``reference_cost``: scipy ``solve_continuous_are`` + ``solve_ivp`` DOP853
  with a terminal event, same tolerances, step at most 0.2 s, same graded penalty).

It prints evaluations per second of both, their ratio and the largest relative cost
difference, then the wall time of one default PSO start (``penaltyrun.optim.pso.run_pso``
with default ``PSOSettings``: 30 particles, ≤ 100 iterations) per law and parameterization.

Usage::

    python bench/bench_attitude.py [--n 200] [--n-ref 30] [--repeats 3] [--no-pso]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun import problems
from penaltyrun.penalty import make as make_param
from penaltyrun.penalty.layout import build_layout
from penaltyrun.problems.attitude import lqr as attitude_lqr
from penaltyrun.problems.attitude import lyapunov as attitude_lyapunov

REFERENCE = {"attitude_lyapunov": attitude_lyapunov.reference_cost,
             "attitude_lqr": attitude_lqr.reference_cost}


def layout_for(prob: problems.Problem, kind: str):  # noqa: ANN201 (DecisionLayout)
    """Decision layout with parameterization ``kind`` for every tuned matrix."""
    return build_layout([(m.name, make_param(kind, m.size, m.eig_bounds)) for m in prob.matrices])


def throughput(name: str, n: int, n_ref: int, repeats: int) -> None:
    """Print production and reference evaluations/s for problem ``name``."""
    prob = problems.make(name, "detumble", {})
    lay = layout_for(prob, "full")
    lb, ub = lay.bounds()
    Z = np.random.default_rng(0).uniform(lb, ub, size=(n, lay.dim))
    mats, _ = lay.split(Z)
    prob.evaluate_batch({k: v[:2] for k, v in mats.items()})  # JIT warm-up, not timed
    t0 = time.perf_counter()
    for _ in range(repeats):
        fast = prob.evaluate_batch(mats)
    fast_rate = n * repeats / (time.perf_counter() - t0)
    t0 = time.perf_counter()
    ref = [REFERENCE[name]({k: v[b] for k, v in mats.items()}, prob.params)
           for b in range(n_ref)]
    ref_rate = n_ref / (time.perf_counter() - t0)
    ref_cost = np.array([r["cost"] for r in ref])
    err = np.max(np.abs(fast.cost[:n_ref] - ref_cost) / np.abs(ref_cost))
    agree = np.all(fast.converged[:n_ref] == np.array([r["converged"] for r in ref]))
    print(f"{name}: {fast.converged.mean():.0%} of {n} random full candidates converge")
    print(f"  production (batch of {n}):        {fast_rate:10.0f} evaluations/s")
    print(f"  reference (scipy, {n_ref} candidates): {ref_rate:10.1f} evaluations/s")
    print(f"  speed-up: {fast_rate / ref_rate:.0f}x  (max relative cost difference {err:.1e}, "
          f"converged flags agree: {agree})")


def pso_start(name: str, kind: str, seed: int = 0) -> None:
    """Print the wall time and result of one default PSO start."""
    from penaltyrun.optim.pso import PSOSettings, run_pso

    prob = problems.make(name, "detumble", {})
    lay = layout_for(prob, kind)
    lb, ub = lay.bounds()

    def objective(Z: np.ndarray) -> np.ndarray:
        return prob.evaluate_batch(lay.split(Z)[0]).cost

    t0 = time.perf_counter()
    res = run_pso(objective, lb, ub, PSOSettings(), seed=seed)
    wall = time.perf_counter() - t0
    best = prob.evaluate(dict(zip([m.name for m in prob.matrices],
                                  [v[0] for v in lay.split(res.best_z[None])[0].values()])))
    print(f"  PSO start {name} / {kind:8s}: {wall:6.1f} s, {res.n_evals} evaluations, "
          f"{res.n_iters} iterations ({res.stop_reason}); best J = {res.best_cost:.4f} "
          f"({best['status']}, t_final {best['t_final']:.1f} s)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="candidates per batch")
    parser.add_argument("--n-ref", type=int, default=30, help="candidates for the reference")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-pso", action="store_true", help="skip the PSO start timing")
    args = parser.parse_args()
    print(f"machine: {machine()}")
    for name in ("attitude_lyapunov", "attitude_lqr"):
        throughput(name, args.n, args.n_ref, args.repeats)
    if args.no_pso:
        return
    try:
        import penaltyrun.optim.pso  # noqa: F401
    except ImportError:
        print("penaltyrun.optim.pso not importable: timing 100 batches of 50 instead")
        for name in ("attitude_lyapunov", "attitude_lqr"):
            prob = problems.make(name, "detumble", {})
            lay = layout_for(prob, "full")
            lb, ub = lay.bounds()
            rng = np.random.default_rng(1)
            t0 = time.perf_counter()
            for _ in range(100):
                prob.evaluate_batch(lay.split(rng.uniform(lb, ub, size=(50, lay.dim)))[0])
            print(f"  {name}: 50 x 100 evaluations in {time.perf_counter() - t0:.1f} s")
        return
    print("one default PSO start (30 particles, <= 100 iterations, detumble):")
    for name in ("attitude_lyapunov", "attitude_lqr"):
        for kind in ("diagonal", "full"):
            pso_start(name, kind)


if __name__ == "__main__":
    main()
