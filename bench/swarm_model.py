"""Scaling model: wall time of the paper's studies vs cores, job-level vs swarm-level Dask.

A study is a Hydra multirun: its cells (problem, case, law, parameterization) run one after
another, each with ``n_starts`` jobs. Within a cell on P worker threads:

* job-level (``runner.backend=dask``): min(starts, P) starts at once, each serial, so
  wall = ceil(starts / P) · iters · B · t;
* swarm-level (``runner.evaluate_on=dask``, ``chunks=auto``): S = min(starts, P) starts at
  once, each batch of B candidates in c chunks, c ≤ P // S and c ≤ B, so one iteration of
  the S starts takes m · t · κ(m) + o + S · c · τ with m = ceil(B / c) evaluations per
  chunk, where t is the CPU time per evaluation, κ(m) = 1 + k / √m the imbalance (slowest
  chunk over the mean chunk; k from the 2-worker Q-law start), o the per-batch overhead
  (round trip, serialization) and τ the scheduler's cost per task. c is chosen to minimize
  it (the auto rule also lowers c when chunks get short against the overhead).

All inputs are measured (see bench/README.md) except where flagged as assumptions.

Usage::

    python bench/swarm_model.py [--overhead 0.01] [--tau 0.0002 0.001] [--k 0.15]
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


def _iteration(m: int, c: int, s: int, t: float, overhead: float, tau: float, k: float
               ) -> float:
    """Wall seconds of one iteration: chunks of m evaluations, c per batch, s starts."""
    kappa = 1.0 + k / math.sqrt(m) if c > 1 else 1.0
    return m * t * kappa + overhead + s * c * tau


def cell_wall(t: float, starts: int, iters: int, batch: int, cores: int, swarm: bool,
              overhead: float, tau: float, k: float) -> float:
    """Wall seconds of one cell (see the module docstring)."""
    if not swarm:
        return math.ceil(starts / cores) * iters * batch * t
    s = min(starts, cores)
    waves = math.ceil(starts / s)
    best = min(_iteration(math.ceil(batch / c), c, s, t, overhead, tau, k)
               for c in range(1, min(batch, max(1, cores // s)) + 1))
    return waves * iters * best


def study(name: str, cells: list[float], starts: int, iters: int, batch: int,
          args: argparse.Namespace) -> None:
    """Print the wall time of a study (one t per cell) for each core count."""
    cpu_h = sum(cells) * starts * iters * batch / 3600
    print(f"\n{name}: {len(cells)} cells x {starts} starts x {batch} particles x {iters} "
          f"iterations; {cpu_h:,.0f} CPU hours")
    taus = "  ".join(f"{'swarm h, τ=' + format(tau * 1e3, 'g') + ' ms':>18}" for tau in args.tau)
    print(f"{'cores':>6} {'job-level h':>12}  {taus}  {'CPU/cores h':>12}")
    for cores in args.cores:
        kw = {"overhead": args.overhead, "k": args.k}
        job = sum(cell_wall(t, starts, iters, batch, cores, False, tau=0.0, **kw)
                  for t in cells) / 3600
        swm = [sum(cell_wall(t, starts, iters, batch, cores, True, tau=tau, **kw)
                   for t in cells) / 3600 for tau in args.tau]
        cols = "  ".join(f"{h:18.2f}" for h in swm)
        print(f"{cores:>6} {job:12.1f}  {cols}  {cpu_h / cores:12.2f}")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", type=int, nargs="+", default=[64, 512, 4096])
    ap.add_argument("--overhead", type=float, default=0.01, help="o, s per batch (measured)")
    ap.add_argument("--tau", type=float, nargs="+", default=[0.0002, 0.001],
                    help="τ, scheduler s per task (dask documents 200 µs to 1 ms)")
    ap.add_argument("--k", type=float, default=0.15,
                    help="imbalance κ(m) = 1 + k/√m (from the 2-worker Q-law start)")
    ap.add_argument("--attitude-t", type=float, default=0.0006,
                    help="attitude CPU s per evaluation (measured, detumble)")
    ap.add_argument("--attitude-iters", type=int, nargs="+", default=[1200, 10000],
                    help="attitude iterations per start: 1 200 (a paper-budget start had not "
                         "stalled by then, README) and the 1e4 cap")
    args = ap.parse_args(argv)
    print(f"inputs: o = {args.overhead * 1e3:.0f} ms per batch, κ(m) = 1 + {args.k}/√m, "
          f"min-fuel = {MIN_FUEL_FACTOR}x min-time")
    lowthrust = [t * f for f in (1.0, MIN_FUEL_FACTOR) for t in QLAW_MIN_TIME.values()
                 for _param in ("diagonal", "full")]
    study("Low thrust 200 x 300 (Q-law, both laws, cases A-E*, diagonal and full)", lowthrust,
          10, 300, 200, args)
    for iters in args.attitude_iters:
        study("Attitude, 500 particles (2 laws x 2 manoeuvres x diagonal and full)",
              [args.attitude_t] * 8, 10, iters, 500, args)


if __name__ == "__main__":
    main()
