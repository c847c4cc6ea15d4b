"""problem=lqr: CPU time of one exact gradient d cost / d z relative to one evaluation.

Per plant size n (random plants, m = max(1, n // 2) inputs, n + 1 starts, full map
``givens`` and ``diagonal``): the CPU time (``time.process_time``) of one single-candidate
evaluation (``evaluate_batch`` of one candidate, as L-BFGS-B asks for it) and of one
gradient (:func:`penaltyrun.optim.gradient.z_gradient`: the Riccati and cost adjoints plus
the map's VJP), interleaved in pairs on the same candidates; prints the min and median of
the per-pair ratios (:func:`timing.gradient_vs_evaluation`). With ``lqr_scaling_ratio.py``
these medians are what ``problem=lqr`` declares one gradient to cost per plant size
(:meth:`penaltyrun.problems.lqr.LQRProblem.gradient_cost`), the charge of ``optimizer=lbfgs``
and ``optimizer.polish=gradient``. Usage:
``python bench/gradient_cost.py [--sizes 2 4 8 16] [--pairs 30] [--discrete]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from machine import machine
from timing import gradient_vs_evaluation

from penaltyrun.problems import lqr
from penaltyrun.runner.setup import build_layout


def plant(n: int, seed: int, dt: float | None) -> lqr.LQRProblem:
    """A random plant of n states with well-inside-the-box performance weights."""
    rng = np.random.default_rng(seed)
    m = max(1, n // 2)
    A = rng.normal(size=(n, n)) / np.sqrt(n)
    B = rng.normal(size=(n, m))
    if dt:
        A, B = np.eye(n) + dt * A, dt * B
    return lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(), "dt": dt,
                                        "x0": rng.normal(size=(n + 1, n)).tolist(),
                                        "t_max": 20.0})


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[2, 4, 8, 16])
    ap.add_argument("--pairs", type=int, default=30)
    ap.add_argument("--discrete", action="store_true")
    args = ap.parse_args()
    print(machine())
    print(f"{'n':>3} {'map':>9} {'eval ms':>8} {'grad ms':>8} {'ratio min':>9} "
          f"{'ratio median':>12}")
    medians = []
    for n in args.sizes:
        prob = plant(n, n, 0.05 if args.discrete else None)
        for kind in ("diagonal", "givens"):
            layout = build_layout(prob, kind, {})
            lb, ub = layout.bounds()
            rng = np.random.default_rng(0)
            Z = lb + (ub - lb) * rng.uniform(0.3, 0.7, size=(args.pairs, lb.size))
            Z[:, : prob.matrices[0].size] = rng.uniform(0.5, 5.0, (args.pairs,
                                                                  prob.matrices[0].size))
            timing = gradient_vs_evaluation(prob, layout, Z)
            medians.append(float(np.median(timing.ratio)))
            print(f"{n:>3} {kind:>9} {timing.row()}", flush=True)
    print(f"median ratio over sizes and maps: {np.median(medians):.2f}")


if __name__ == "__main__":
    main()
