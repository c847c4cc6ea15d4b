"""Attitude problems: CPU time of one exact gradient relative to one evaluation, forward
sensitivities against the adjoint.

For each law (``attitude_lyapunov``, ``attitude_lqr``), well-posed criterion
(``terminal``, ``time_energy``) and map (``--maps``), on candidates drawn inside the box:
the CPU time (``time.process_time``) of one single-candidate evaluation
(``evaluate_batch``, the compiled kernel), of one gradient d cost / d z by forward
sensitivities (:func:`penaltyrun.optim.gradient.z_gradient`, the production path: the
compiled sensitivity run), of the same gradient with scipy's sensitivity run (the path
before the compiled one, its reference) and of the cost → gain part by the adjoint
(:func:`penaltyrun.dynamics.attitude_sens.adjoint_gradient`), interleaved at each candidate
(:func:`timing.gradient_vs_evaluation`); prints the median times, the median per-candidate
ratios to one evaluation and the median per-candidate ratio scipy / compiled. The forward
ratios are the costs the attitude problems declare (``gradient_cost``). Usage:
``python bench/attitude_gradient_cost.py [--points 5]``.
"""

from __future__ import annotations

import argparse
import functools
import itertools

import numpy as np
from machine import machine
from timing import gradient_vs_evaluation

from penaltyrun.dynamics import attitude_sens as sens
from penaltyrun.optim.gradient import z_gradient
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


def by_scipy(prob, layout, z: np.ndarray) -> None:
    """The production gradient with scipy's sensitivity run instead of the compiled one."""
    compiled = sens.sensitivity_run
    sens.sensitivity_run = functools.partial(compiled, compiled=False)
    try:
        z_gradient(prob, layout, z)
    finally:
        sens.sensitivity_run = compiled


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=5)
    ap.add_argument("--maps", nargs="+", default=["diagonal", "givens"])
    args = ap.parse_args()
    print(machine())
    print(f"{'law':>18} {'criterion':>11} {'map':>9} {'eval ms':>8} {'forward ms':>10} "
          f"{'scipy ms':>9} {'adjoint ms':>10} {'fwd/eval':>8} {'scipy/eval':>10} "
          f"{'adj/eval':>8} {'scipy/fwd':>9}")
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

        timing = gradient_vs_evaluation(
            prob, layout, Z, extra=[by_adjoint, functools.partial(by_scipy, prob, layout)])
        ev, fw = np.median(timing.evaluation), np.median(timing.gradient)
        ad, sc = timing.extra[:, 0], timing.extra[:, 1]
        per_eval = np.maximum(timing.evaluation, 1e-9)
        print(f"{module.NAME:>18} {crit:>11} {kind:>9} {1e3 * ev:8.2f} {1e3 * fw:10.1f} "
              f"{1e3 * np.median(sc):9.1f} {1e3 * np.median(ad):10.1f} "
              f"{np.median(timing.ratio):8.1f} {np.median(sc / per_eval):10.1f} "
              f"{np.median(ad / per_eval):8.1f} "
              f"{np.median(sc / np.maximum(timing.gradient, 1e-9)):9.1f}", flush=True)


if __name__ == "__main__":
    main()
