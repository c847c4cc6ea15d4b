"""Benchmark: CPU time of seeded optimizer starts with and without the exact cutoff.

Each start runs twice in this process, through the runner's objective (the path of a real
run), once with ``runner.cutoff`` off and once on: same seed, same budget. Printed per cell:
CPU seconds (``time.process_time``) of both, their ratio, the share of evaluations the cutoff
stopped early, and whether the two runs agree bitwise (best cost, best point, anytime trace,
evaluations) — they must.

Default cells: Q-law minimum time, full K (GEAGSP), cases E* and D, ``pso`` and
``pso_matlab`` with a small swarm (8 particles, 15 iterations: 120 and 128 evaluations).

Usage::

    python bench/bench_cutoff.py [--cases Estar D] [--optimizers pso pso_matlab de]
                                 [--swarm 8] [--iters 15] [--seed 1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun import optim, problems
from penaltyrun.runner.job import _objective
from penaltyrun.runner.setup import build_layout


def _settings(name: str, swarm: int, iters: int) -> optim.Settings:
    if name == "pso":
        opts = {"n_particles": swarm, "iters": iters, "ftol_iter": iters + 1}
    elif name == "pso_matlab":
        opts = {"swarm_size": swarm, "max_iterations": iters}
    elif name == "de":
        opts = {"popsize": 1, "iters": iters, "tol": 0.0, "polish": "none"}
    else:
        raise SystemExit(f"no cutoff for optimizer {name!r} (pso, pso_matlab, de)")
    return optim.make_settings(name, opts)


def one_start(prob, layout, name: str, settings, seed: int, cutoff: bool):
    """One seeded start; returns (result, CPU seconds, evaluations cut)."""
    lb, ub = layout.bounds()
    objective = _objective(prob, layout, "bench", cutoff)
    t0 = time.process_time()
    res = optim.minimize(name, objective, lb, ub, settings, seed)
    return res, time.process_time() - t0, objective.n_cutoff


def same(a, b) -> bool:
    """Whether two results agree bitwise."""
    return (a.best_cost == b.best_cost and np.array_equal(a.best_z, b.best_z)
            and a.trace_evals == b.trace_evals and a.trace_best == b.trace_best
            and a.n_evals == b.n_evals and a.history == b.history)


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["Estar", "D"])
    ap.add_argument("--optimizers", nargs="+", default=["pso", "pso_matlab"])
    ap.add_argument("--problem", default="qlaw")
    ap.add_argument("--swarm", type=int, default=8)
    ap.add_argument("--iters", type=int, default=15)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    print(f"date: {time.strftime('%Y-%m-%d')}")
    print(f"\n== Exact cutoff: {args.problem} min time, full K, swarm {args.swarm}, "
          f"{args.iters} iterations, seed {args.seed} (CPU s) ==")
    print(f"{'case':>6} {'optimizer':>10} {'evals':>5} {'off s':>8} {'on s':>8} "
          f"{'ratio':>6} {'cut':>6} {'best cost':>10} {'bitwise':>8}")
    for case in args.cases:
        prob = problems.make(args.problem, case, {})
        layout = build_layout(prob, "full", {})
        lb, ub = layout.bounds()
        mats, _ = layout.split((0.5 * (lb + ub))[None, :])
        prob.evaluate_batch(mats, thresholds=np.array([1.0]))  # compile outside the timing
        for name in args.optimizers:
            settings = _settings(name, args.swarm, args.iters)
            off, off_s, _ = one_start(prob, layout, name, settings, args.seed, False)
            on, on_s, n_cut = one_start(prob, layout, name, settings, args.seed, True)
            print(f"{case:>6} {name:>10} {on.n_evals:5d} {off_s:8.1f} {on_s:8.1f} "
                  f"{off_s / on_s:6.2f} {n_cut / on.n_evals:6.0%} {on.best_cost:10.3f} "
                  f"{'yes' if same(on, off) else 'NO':>8}", flush=True)


if __name__ == "__main__":
    main()
