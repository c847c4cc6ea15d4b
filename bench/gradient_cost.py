"""problem=lqr: CPU time of one exact gradient d cost / d z relative to one evaluation.

Per plant size n (random plants, m = max(1, n // 2) inputs, n + 1 starts, full map
``givens`` and ``diagonal``): the CPU time (``time.process_time``) of one single-candidate
evaluation (``evaluate_batch`` of one candidate, as L-BFGS-B asks for it) and of one
gradient (:func:`penaltyrun.optim.gradient.z_gradient`: the Riccati and cost adjoints plus
the map's VJP), interleaved in pairs on the same candidates; prints the min and median of
the per-pair ratios. The median over the sizes is the constant ``GRADIENT_COST`` of
``optimizer=lbfgs`` (penaltyrun/optim/lbfgs.py). Usage:
``python bench/gradient_cost.py [--sizes 2 4 8 16] [--pairs 30] [--discrete]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun.optim.gradient import z_gradient
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


def evaluate_one(prob: lqr.LQRProblem, layout, z: np.ndarray) -> None:
    """One single-candidate evaluation, as L-BFGS-B asks for it."""
    prob.evaluate_batch(layout.split(z[None])[0])


def timed(func, *args) -> float:
    t0 = time.process_time()
    func(*args)
    return time.process_time() - t0


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
            z_gradient(prob, layout, Z[0])  # warm-up (imports, caches)
            ev, gr = [], []
            for z in Z:
                ev.append(timed(evaluate_one, prob, layout, z))
                gr.append(timed(z_gradient, prob, layout, z))
            ratio = np.asarray(gr) / np.maximum(np.asarray(ev), 1e-9)
            medians.append(float(np.median(ratio)))
            print(f"{n:>3} {kind:>9} {1e3 * np.median(ev):8.3f} {1e3 * np.median(gr):8.3f} "
                  f"{ratio.min():9.2f} {np.median(ratio):12.2f}")
    print(f"median ratio over sizes and maps: {np.median(medians):.2f}")


if __name__ == "__main__":
    main()
