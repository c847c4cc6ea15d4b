"""Scaling model: wall time of the paper's studies vs cores, job-level vs swarm-level Dask.

A study is a Hydra multirun: its cells (problem, case, law, parameterization) run one after
another, each with ``n_starts`` jobs. Within a cell on P worker threads:

* job-level (``runner.backend=dask``): min(starts, P) starts at once, each serial, so
  wall = ceil(starts / P) · iters · B · t;
* swarm-level (``runner.evaluate_on=dask``, ``chunks=auto``): S = min(starts, P) starts at
  once, each batch of B candidates in c chunks, c ≤ P // S and c ≤ B, so one iteration of
  the S starts takes ceil(B / c) · t · κ + o + S · c · τ, where t is the CPU time per
  evaluation, κ ≥ 1 the imbalance (slowest chunk over the mean chunk), o the per-batch
  overhead (round trip, serialization) and τ the scheduler's cost per task. c is chosen to
  minimize it (the auto rule also lowers c when chunks get short against the overhead).

All inputs are measured (see bench/README.md) except where flagged as assumptions.

Usage::

    python bench/swarm_model.py [--overhead 0.02] [--tau 0.001] [--kappa 1.3]
"""

from __future__ import annotations

import argparse
import math

#: Q-law minimum-time CPU s per evaluation of random full K (bench/README.md: kernel table
#: for A, B; no-progress table for D, E, E*; C from the same kernel bench, rounded up).
QLAW_MIN_TIME = {"A": 0.0146, "B": 0.131, "C": 0.004, "D": 0.206, "E": 0.219, "Estar": 0.178}
#: Assumption: a min-fuel evaluation costs this many min-time ones (issue 10 measured 3.2×
#: before the analytic law; the min-fuel search got 3.6× faster, the min-time law 4.6×).
MIN_FUEL_FACTOR = 3.2


def cell_wall(t: float, starts: int, iters: int, batch: int, cores: int, swarm: bool,
              overhead: float, tau: float, kappa: float) -> float:
    """Wall seconds of one cell (see the module docstring)."""
    if not swarm:
        return math.ceil(starts / cores) * iters * batch * t
    s = min(starts, cores)
    waves = math.ceil(starts / s)
    best = min(math.ceil(batch / c) * t * (kappa if c > 1 else 1.0) + overhead + s * c * tau
               for c in range(1, min(batch, max(1, cores // s)) + 1))
    return waves * iters * best


def study(name: str, cells: list[float], starts: int, iters: int, batch: int,
          args: argparse.Namespace) -> None:
    """Print the wall time of a study (one t per cell) for each core count."""
    cpu_h = sum(cells) * starts * iters * batch / 3600
    print(f"\n{name}: {len(cells)} cells x {starts} starts x {batch} particles x {iters} "
          f"iterations; {cpu_h:,.0f} CPU hours")
    print(f"{'cores':>6} {'job-level h':>12} {'swarm-level h':>14} {'ratio':>6} "
          f"{'ideal CPU/cores h':>18}")
    for cores in args.cores:
        kw = {"overhead": args.overhead, "tau": args.tau, "kappa": args.kappa}
        job = sum(cell_wall(t, starts, iters, batch, cores, False, **kw) for t in cells) / 3600
        swm = sum(cell_wall(t, starts, iters, batch, cores, True, **kw) for t in cells) / 3600
        print(f"{cores:>6} {job:12.1f} {swm:14.2f} {job / swm:6.1f} {cpu_h / cores:18.2f}")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", type=int, nargs="+", default=[64, 512, 4096])
    ap.add_argument("--overhead", type=float, default=0.02, help="o, s per batch (measured)")
    ap.add_argument("--tau", type=float, default=0.001,
                    help="τ, scheduler s per task (dask's documented order of magnitude)")
    ap.add_argument("--kappa", type=float, default=1.3,
                    help="κ, slowest / mean chunk (measured on the Q-law start)")
    ap.add_argument("--attitude-t", type=float, default=0.002,
                    help="attitude CPU s per evaluation (measured)")
    ap.add_argument("--attitude-iters", type=int, default=1000,
                    help="attitude iterations per start (assumption: the stall rule ends "
                         "most starts far before the 1e4 cap)")
    args = ap.parse_args(argv)
    print(f"inputs: o = {args.overhead * 1e3:.0f} ms per batch, τ = {args.tau * 1e3:.2f} ms "
          f"per task, κ = {args.kappa}, min-fuel = {MIN_FUEL_FACTOR}x min-time")
    lowthrust = [t * f for f in (1.0, MIN_FUEL_FACTOR) for t in QLAW_MIN_TIME.values()
                 for _param in ("diagonal", "full")]
    study("Low thrust 200 x 300 (Q-law, both laws, cases A-E*, diagonal and full)", lowthrust,
          10, 300, 200, args)
    study("Attitude, 500 particles (2 laws x 2 manoeuvres x diagonal and full)",
          [args.attitude_t] * 8, 10, args.attitude_iters, 500, args)


if __name__ == "__main__":
    main()
