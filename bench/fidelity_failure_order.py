"""Which half of the authors' objective form changes a pso_matlab run: the scale the stall
test sees (−1/J for converged candidates) or the ranking of failed candidates (final error
d − tol alone, instead of J + failure_penalty · (1 + d/d0))?

Three objectives on one cell, the same seeds, MATLAB ``particleswarm`` defaults:

* ``cost``: J, failures by the graded penalty (the project's default);
* ``neg_reciprocal``: the authors' form (−1/J; failures d − tol);
* ``hybrid``: −1/J for converged candidates, failures keep the graded penalty (positive,
  so still behind every converged one) — the stall scale of the authors' form with the
  project's failure ranking.

Usage::

    python bench/fidelity_failure_order.py --case detumble --starts 6 \
        --out studies/fidelity_gap/failure_order.csv

Writes one row per (objective, seed): evaluations, iterations, stop reason, J of the best
and CPU seconds.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun import optim
from penaltyrun.problems import make
from penaltyrun.problems.base import BatchEvaluation
from penaltyrun.runner.setup import build_layout


def objective(prob, layout, variant: str):
    """Batched objective returning J as the cost and the variant's value to minimize."""

    def func(Z: np.ndarray) -> BatchEvaluation:
        mats, scalars = layout.split(Z)
        res = prob.evaluate_batch(mats, scalars or None)
        if variant != "hybrid":  # the problem's own form (cost or neg_reciprocal)
            return res
        value = np.where(res.converged, -1.0 / res.cost, res.cost)
        return BatchEvaluation(res.cost, res.converged, res.status, objective=value)

    return func


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", default="detumble")
    ap.add_argument("--param", default="diagonal")
    ap.add_argument("--starts", type=int, default=6)
    ap.add_argument("--out", default="studies/fidelity_gap/failure_order.csv")
    args = ap.parse_args()
    rows = []
    settings = optim.make_settings("pso_matlab", {})
    for variant in ("cost", "neg_reciprocal", "hybrid"):
        form = "neg_reciprocal" if variant == "neg_reciprocal" else "cost"
        prob = make("attitude_lyapunov", args.case, {"objective_form": form})
        layout = build_layout(prob, args.param, {})
        lb, ub = layout.bounds()
        for seed in range(args.starts):
            c0 = time.process_time()
            res = optim.minimize("pso_matlab", objective(prob, layout, variant), lb, ub,
                                 settings, seed)
            rows.append({"case": args.case, "param": args.param, "objective": variant,
                         "seed": seed, "n_evals": res.n_evals, "n_iters": res.n_iters,
                         "stop_reason": res.stop_reason, "J_best": res.best_cost,
                         "cpu_s": time.process_time() - c0})
            print(rows[-1])
    table = pd.DataFrame(rows)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out, index=False, float_format="%.8g")
    print(table.groupby("objective")[["n_evals", "J_best"]].median())


if __name__ == "__main__":
    main()
