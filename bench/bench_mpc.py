"""Rendezvous MPC: CPU time of one evaluation of 150 closed-loop steps on the production
path (batched doubling DARE, condensed QP, DAQP with warm starts) vs the independent dense
reference (closed-form CW, scipy DARE, block-matrix QP, BVLS per step), in the same run.

To time exactly 150 steps, the convergence radii are set to 1e-300 (no run stops early);
random SPD weights come from the problem's default eigenvalue boxes (full maps). The same
candidates are run by the reference and the Δv compared. The default problem (runs stop
at convergence) is timed too. Usage: ``python bench/bench_mpc.py [--n 40] [--n-ref 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun import problems
from penaltyrun.penalty import make as make_param
from penaltyrun.problems.mpc.reference import reference_run


def cpu_per_eval(prob, mats, repeats: int) -> tuple[float, object]:
    """CPU seconds per evaluation of ``prob.evaluate_batch(mats)`` and the last result."""
    n = mats["Q"].shape[0]
    t0 = time.process_time()
    for _ in range(repeats):
        batch = prob.evaluate_batch(mats)
    return (time.process_time() - t0) / (repeats * n), batch


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=40, help="candidates in the batch")
    parser.add_argument("--n-ref", type=int, default=3, help="of them run by the reference")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    default = problems.make("mpc_rendezvous", None, {})
    full150 = problems.make("mpc_rendezvous", None, {"pos_tol_m": 1e-300,
                                                     "vel_tol_m_s": 1e-300})
    p = full150.params
    rng = np.random.default_rng(0)
    mats = {}
    for spec in full150.matrices:
        par = make_param("full", spec.size, spec.eig_bounds)
        lb, ub = par.bounds()
        mats[spec.name] = par.decode(rng.uniform(lb, ub, size=(args.n, par.dim)))

    full150.evaluate_batch({k: v[:1] for k, v in mats.items()})   # first call, not timed
    t150, batch = cpu_per_eval(full150, mats, args.repeats)
    tdef, _ = cpu_per_eval(default, mats, args.repeats)
    steps = [default.evaluate({k: v[b] for k, v in mats.items()})["t_final"]
             / p.sample_time_s for b in range(args.n)]

    t0 = time.process_time()
    errs = []
    for b in range(args.n_ref):
        ref = reference_run(mats["Q"][b], mats["R"][b], full150.n, p.sample_time_s,
                            p.horizon, p.u_max, p.s0, p.n_steps, p.pos_tol_m, p.vel_tol_m_s)
        assert ref["steps"] == p.n_steps
        dv = batch.cost[b] - p.failure_penalty * (
            1.0 + full150.error(ref["states"][-1]) / full150.error(p.s0))
        errs.append(abs(dv - ref["delta_v"]) / ref["delta_v"])
    tref = (time.process_time() - t0) / args.n_ref

    print(f"machine: {machine()}")
    print(f"production, {p.n_steps} closed-loop steps, batch of {args.n} random full weights: "
          f"{1e3 * t150:.2f} ms CPU per evaluation")
    print(f"reference (closed-form CW, scipy DARE, BVLS), {p.n_steps} steps, first "
          f"{args.n_ref}: {1e3 * tref:.0f} ms CPU per evaluation")
    print(f"ratio: {tref / t150:.0f}x   (max relative delta-v difference {max(errs):.1e})")
    print(f"production, default problem (runs stop at convergence, mean "
          f"{np.mean(steps):.0f} steps): {1e3 * tdef:.2f} ms CPU per evaluation")


if __name__ == "__main__":
    main()
