"""problem=lqr: CPU time to reach J* within 1e-6 (relative), optimizer=lbfgs vs CMA-ES.

Random plants with n states (m = max(1, n // 2) inputs, n + 1 starts, performance weights
with eigenvalues in [0.5, 5], so J* is reached at Q = W_x, R = W_u inside the box), map
``givens``; one start per optimizer and seed, interleaved. A wrapped objective notes the
CPU time (``time.process_time``) and evaluations at which the best cost first comes within
1e-6 of J*; CMA-ES gets ``--cmaes-evals`` evaluations (× n), lbfgs ``--lbfgs-evals``
evaluation-equivalents (a gradient charged what ``problem=lqr`` declares for the plant's
size, :meth:`~penaltyrun.problems.lqr.LQRProblem.gradient_cost`). Prints per
size the median CPU and evaluations to reach J* and the CMA-ES / lbfgs CPU ratio (min and
median over the seeds). Usage:
``OPENBLAS_NUM_THREADS=1 python bench/lbfgs_vs_cmaes.py [--sizes 4 8] [--seeds 3]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from machine import machine
from timing import cpu_to_target

from penaltyrun.problems import lqr
from penaltyrun.runner.setup import build_layout

RTOL = 1e-6


def plant(n: int, seed: int) -> lqr.LQRProblem:
    """A random plant whose optimum Q = W_x, R = W_u lies inside the box."""
    rng = np.random.default_rng(seed)
    m = max(1, n // 2)

    def spd(k: int) -> np.ndarray:
        V = np.linalg.qr(rng.normal(size=(k, k)))[0]
        return V @ np.diag(rng.uniform(0.5, 5.0, k)) @ V.T

    return lqr.make_problem("default", {
        "A": (rng.normal(size=(n, n)) / np.sqrt(n)).tolist(),
        "B": rng.normal(size=(n, m)).tolist(), "x0": rng.normal(size=(n + 1, n)).tolist(),
        "state_weight": spd(n).tolist(), "input_weight": spd(m).tolist(), "t_max": 60.0,
        "q_bounds": [0.05, 50.0], "r_bounds": [0.05, 50.0]})


def race(name: str, prob: lqr.LQRProblem, budget: int, seed: int
         ) -> tuple[float, float, float]:
    """(CPU s, evaluations) until the best cost is within RTOL of J* (inf if never), and
    the CPU s of the whole run."""
    options = {"max_evals": budget} if name == "cmaes" else {"max_evals": budget,
                                                              "starts": None}
    return cpu_to_target(name, prob, build_layout(prob, "givens", {}), options, seed,
                         prob.optimum * (1.0 + RTOL))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cmaes-evals", type=int, default=5000, help="per state")
    ap.add_argument("--lbfgs-evals", type=int, default=1000, help="per state")
    args = ap.parse_args()
    print(machine())
    print(f"{'n':>3} {'reached':>9} {'cmaes cpu s':>11} {'cmaes evals':>11} "
          f"{'lbfgs cpu s':>11} {'lbfgs evals':>11} {'ratio min':>9} {'ratio median':>12}")
    for n in args.sizes:
        rows = []
        for seed in range(args.seeds):
            prob = plant(n, 100 * n + seed)
            lb_cpu, lb_ev, _ = race("lbfgs", prob, args.lbfgs_evals * n, seed)
            cm_cpu, cm_ev, cm_total = race("cmaes", prob, args.cmaes_evals * n, seed)
            # a CMA-ES start that never reached J*: its whole run's CPU, a lower bound
            rows.append((cm_cpu, cm_ev, lb_cpu, lb_ev, min(cm_cpu, cm_total)))
        a = np.asarray(rows)
        ratio = (a[:, 4] / a[:, 2])[np.isfinite(a[:, 2])]  # seeds where lbfgs reached J*
        reached = (f"{int(np.isfinite(a[:, 0]).sum())}/{int(np.isfinite(a[:, 2]).sum())}"
                   f"/{len(a)}")
        bound = "≥" if not np.all(np.isfinite(a[:, 0])) else ""
        lo, mid = (np.min(ratio), np.median(ratio)) if ratio.size else (np.nan, np.nan)
        print(f"{n:>3} {reached:>9} {np.median(a[:, 0]):11.3g} {np.median(a[:, 1]):11.6g} "
              f"{np.median(a[:, 2]):11.3g} {np.median(a[:, 3]):11.6g} "
              f"{bound}{lo:8.3g} {bound}{mid:11.3g}")
    print("reached: starts within 1e-6 of J*, CMA-ES / lbfgs / seeds; ratios over the seeds "
          "where lbfgs reached J*; ≥: some CMA-ES starts never reached J*, their whole run's "
          "CPU enters the ratio (a lower bound)")


if __name__ == "__main__":
    main()
