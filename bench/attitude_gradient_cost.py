"""Attitude problems: CPU time of one exact gradient relative to one evaluation, forward
sensitivities against the adjoint.

For each law (``attitude_lyapunov``, ``attitude_lqr``), well-posed criterion
(``terminal``, ``time_energy``) and map (``--maps``), on candidates drawn inside the box:
the CPU time (``time.process_time``) of one single-candidate evaluation
(``evaluate_batch``, the compiled kernel), of one gradient d cost / d z by forward
sensitivities (:func:`penaltyrun.optim.gradient.z_gradient`, the production path) and of
the cost → gain part by the adjoint
(:func:`penaltyrun.dynamics.attitude_sens.adjoint_gradient`), interleaved at each candidate
(:func:`timing.gradient_vs_evaluation`); prints the median times and the median per-candidate
ratios to one evaluation. The forward ratios are the costs the attitude problems declare
(``gradient_cost``). Usage:
``python bench/attitude_gradient_cost.py [--points 5]``.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
from machine import machine
from timing import gradient_vs_evaluation

from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.problems.attitude import criteria as attitude_criteria
from penaltyrun.problems.attitude import lqr, lyapunov
from penaltyrun.problems.attitude.reference import reference_max_step
from penaltyrun.runner.setup import build_layout


def adjoint(prob, G: np.ndarray) -> None:
    """The cost → gain gradient of one gain by the adjoint, with the production path's step
    bound (none on a fixed horizon without a torque limit)."""
    p = prob.params
    terminal = p.criterion == "terminal"
    sens.adjoint_gradient(G, prob.y0, prob.inertia,
                          float(p.t_max if terminal else p.free_time_cap), p.event_weights(),
                          None if terminal else float(p.tol),
                          attitude_criteria.terminal_weight(p), float(p.rho),
                          max_step=np.inf if terminal else reference_max_step(p))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=5)
    ap.add_argument("--maps", nargs="+", default=["diagonal", "givens"])
    args = ap.parse_args()
    print(machine())
    print(f"{'law':>18} {'criterion':>11} {'map':>9} {'eval ms':>8} {'forward ms':>10} "
          f"{'adjoint ms':>10} {'fwd/eval':>8} {'adj/eval':>8}")
    for module, crit, kind in itertools.product((lyapunov, lqr), ("terminal", "time_energy"),
                                                args.maps):
        prob = module.make_problem("detumble", {"criterion": crit})
        layout = build_layout(prob, kind, {})
        lb, ub = layout.bounds()
        rng = np.random.default_rng(0)
        Z = lb + (ub - lb) * rng.uniform(0.3, 0.6, size=(args.points, lb.size))
        gains = {z.tobytes(): prob.gains(layout.split(z[None])[0])[0][0] for z in Z}

        def by_adjoint(z: np.ndarray, prob=prob, gains=gains) -> None:
            adjoint(prob, gains[z.tobytes()])

        timing = gradient_vs_evaluation(prob, layout, Z, extra=[by_adjoint])
        ev, fw = np.median(timing.evaluation), np.median(timing.gradient)
        ad = timing.extra[:, 0]
        print(f"{module.NAME:>18} {crit:>11} {kind:>9} {1e3 * ev:8.2f} {1e3 * fw:10.1f} "
              f"{1e3 * np.median(ad):10.1f} {np.median(timing.ratio):8.1f} "
              f"{np.median(ad / np.maximum(timing.evaluation, 1e-9)):8.1f}", flush=True)


if __name__ == "__main__":
    main()
