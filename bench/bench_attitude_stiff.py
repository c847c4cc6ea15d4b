"""Attitude LQR near-best candidates: old kernel (DOP853 only) vs the guarded, stiff-aware one.

The candidate set is :func:`nearbest_attitude_lqr.near_best_set` (seeded perturbations of
the committed best-known attitude LQR candidates). Three ways to run it, interleaved in
every repetition (rotating order), CPU time by ``time.process_time``:

* ``old``: DOP853 for every run, no divergence guard (the kernel before the guard);
* ``guard``: DOP853 for every run, with the guard (``stiff_rate=inf``);
* ``new``: the production kernel (guard, RODAS4 for stiff runs).

Printed: the per-repetition CPU of each, min and median of the ratios old/new and
guard/new, the statuses, and the largest relative cost difference between ``new`` and
``guard`` (same statuses required). Usage:
``python bench/bench_attitude_stiff.py [--n-per-cell 32] [--repeats 7]``.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np
from machine import machine
from nearbest_attitude_lqr import near_best_set

from penaltyrun.dynamics import attitude as kernel
from penaltyrun.dynamics import integrate
from penaltyrun.problems.attitude import lqr
from penaltyrun.problems.attitude.reference import graded_cost


def _runs(n_per_cell: int) -> list[tuple]:
    """(problem, gains) per cell of the near-best set."""
    out = []
    for cell in near_best_set(n_per_cell):
        prob = lqr.make_problem(cell["case"], cell["problem_params"])
        G, ok = prob.gains({"Q": cell["Q"], "R": cell["R"]})
        out.append((prob, np.ascontiguousarray(G[ok])))
    return out


def _old(prob, G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DOP853 without the guard, run by run (costs, statuses)."""
    p = prob.params
    pv = np.empty(kernel.N_PRM)
    y = np.zeros(kernel.N_STATE)
    y[:7] = prob.y0
    energy, dist, status = (np.empty(len(G)) for _ in range(3))
    for b in range(len(G)):
        kernel.pack_params(prob.inertia, prob.inertia_inv, G[b], p.saturation(), p.tol, pv,
                           *p.event_weights())
        _, yf, st, _ = kernel._integrate(y, pv, p.t_max, p.rtol, p.atol, p.max_step,
                                         p.event_spacing, p.n_event_samples, p.max_steps)
        energy[b], dist[b], status[b] = yf[7], kernel.weighted_distance(yf, pv), st
    return graded_cost(energy, dist, prob.d0, status, p.failure_penalty), status


def _batch(prob, G: np.ndarray, stiff_rate: float) -> tuple[np.ndarray, np.ndarray]:
    p = prob.params
    _, energy, dist, status = kernel.simulate_batch(
        G, prob.y0[None], prob.inertia, prob.inertia_inv, p.t_max, p.tol, p.saturation(),
        p.rtol, p.atol, p.max_step, p.event_spacing, p.n_event_samples, p.max_steps,
        *p.event_weights(), None, stiff_rate)
    return graded_cost(energy, dist, prob.d0, status, p.failure_penalty), status


def _time(fn, runs) -> tuple[float, np.ndarray, np.ndarray]:
    t0 = time.process_time()
    res = [fn(prob, G) for prob, G in runs]
    cpu = time.process_time() - t0
    return cpu, np.concatenate([r[0] for r in res]), np.concatenate([r[1] for r in res])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n-per-cell", type=int, default=32)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    runs = _runs(args.n_per_cell)
    ways = {"old": _old,
            "guard": lambda prob, G: _batch(prob, G, np.inf),
            "new": lambda prob, G: _batch(prob, G, kernel.STIFF_RATE)}
    for fn in ways.values():  # JIT warm-up on two candidates, not timed
        _time(fn, [(prob, G[:2]) for prob, G in runs])
    cpu: dict[str, list[float]] = {k: [] for k in ways}
    res = {}
    names = list(ways)
    for rep in range(args.repeats):
        for k in names[rep % 3:] + names[:rep % 3]:
            t, cost, status = _time(ways[k], runs)
            cpu[k].append(t)
            res[k] = (cost, status)
    n = sum(len(G) for _, G in runs)
    print(f"machine: {machine()}")
    print(f"near-best set: {n} candidates, {len(runs)} cells, {args.repeats} interleaved repeats")
    for k in names:
        st = Counter(integrate.STATUS_NAMES[int(s)] for s in res[k][1])
        print(f"{k:6s} CPU per set: min {min(cpu[k]):.4f} s, median {np.median(cpu[k]):.4f} s;"
              f" statuses {dict(st)}")
    for k in ("old", "guard"):
        ratio = np.asarray(cpu[k]) / np.asarray(cpu["new"])
        print(f"ratio {k}/new: min {ratio.min():.2f}, median {np.median(ratio):.2f}")
    same = res["guard"][1] == res["new"][1]
    cg, cn = res["guard"][0], res["new"][0]
    ordinary = same & (res["new"][1] != integrate.DIVERGED)
    rel = np.abs(cn - cg)[ordinary] / np.abs(cg)[ordinary]
    stiff = np.zeros(n, dtype=bool)
    i = 0
    for prob, G in runs:
        for b in range(len(G)):
            pv = np.empty(kernel.N_PRM)
            kernel.pack_params(prob.inertia, prob.inertia_inv, G[b], prob.params.saturation(),
                               prob.params.tol, pv)
            stiff[i] = kernel.stiffness(pv) > kernel.STIFF_RATE
            i += 1
    print(f"stiff path: {stiff.sum()} of {n} candidates; statuses new vs guard identical: "
          f"{same.all()}; max relative cost difference (not diverged): {rel.max():.1e}")


if __name__ == "__main__":
    main()
