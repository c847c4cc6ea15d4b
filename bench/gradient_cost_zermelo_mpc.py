"""problem=zermelo and problem=mpc_rendezvous: CPU time of one exact gradient d cost / d z
relative to one evaluation (what these problems declare one gradient to cost).

For each problem and map (``diagonal``, ``givens``): random candidates inside the box, the
CPU time (``time.process_time``) of one single-candidate evaluation (``evaluate_batch``, as
L-BFGS-B asks for it) and of one gradient (:func:`penaltyrun.optim.gradient.z_gradient`),
interleaved in pairs on the same candidates; prints the min and median of the per-pair
ratios. Zermelo on its default case; the MPC on the ``scaled`` case under each criterion
(``terminal``: every run lasts t_max, a fixed amount of work; ``deadline`` and
``time_energy``: to arrival). The medians are the costs the two problems declare
(``gradient_cost``). Usage:
``python bench/gradient_cost_zermelo_mpc.py [--pairs 20] [--criteria terminal ...]``.
"""

from __future__ import annotations

import argparse

import numpy as np
from machine import machine
from timing import gradient_vs_evaluation

from penaltyrun.problems import zermelo
from penaltyrun.problems.criteria import CRITERIA
from penaltyrun.problems.mpc import rendezvous
from penaltyrun.runner.setup import build_layout


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=20)
    ap.add_argument("--criteria", nargs="+", default=list(CRITERIA),
                    help="MPC criteria to measure (default: every one)")
    args = ap.parse_args()
    print(machine())
    print(f"{'problem':>15} {'criterion':>11} {'map':>9} {'eval ms':>8} {'grad ms':>8} "
          f"{'ratio min':>9} {'ratio median':>12}")
    problems = {("zermelo", "-"): zermelo.make_problem("default", {})}
    for criterion in args.criteria:
        problems["mpc_rendezvous", criterion] = rendezvous.make_problem(
            "scaled", {"criterion": criterion})
    for (name, criterion), prob in problems.items():
        for kind in ("diagonal", "givens"):
            layout = build_layout(prob, kind, {})
            lb, ub = layout.bounds()
            rng = np.random.default_rng(0)
            Z = lb + (ub - lb) * rng.uniform(0.1, 0.5, size=(args.pairs, lb.size))
            timing = gradient_vs_evaluation(prob, layout, Z)
            print(f"{name:>15} {criterion:>11} {kind:>9} {timing.row()}", flush=True)


if __name__ == "__main__":
    main()
