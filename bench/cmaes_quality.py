"""Quality of the vectorized CMA-ES against the former pycma path on committed attitude cells.

For every ``attitude_lyapunov`` CMA-ES cell of ``studies/referee_attitude`` (detumble and
rest-to-rest × the maps given), the first ``--starts`` committed jobs are run again with
the committed job seeds and budget (``optimizer.max_evals = 3000``, the ``cmaes`` preset) on
the objective the runner builds (:func:`penaltyrun.optim.minimize`, one BLAS thread), once
with the current optimizer and once with the former pycma path (``cmaes_pycma.py``); a
start counts as converged when its best candidate converges (the problem's own status). Per
cell the two samples of converged best costs are compared with the report's own map-vs-map
comparison (:func:`penaltyrun.report.compare.pairwise`: two-sided Mann–Whitney U, A12, Holm
over all cells), the two engines standing in for two maps. The committed records' median is
printed beside them (the pycma rerun reproduces it when the kernels are unchanged).

Usage::

    python bench/cmaes_quality.py [--starts 30] [--params diagonal geagsp givens cayley]
                                  [--out quality.csv]
"""

from __future__ import annotations

import argparse
import time
from datetime import date
from pathlib import Path

import pandas as pd
from cmaes_pycma import run_pycma
from machine import machine
from threadpoolctl import threadpool_limits

import penaltyrun.optim as optim
from penaltyrun.optim import make_settings, minimize
from penaltyrun.optim.cmaes import CMAESSettings, run_cmaes
from penaltyrun.report.compare import pairwise
from penaltyrun.runner import swarm

STUDY = Path(__file__).resolve().parents[1] / "studies" / "referee_attitude" / "results.parquet"
ENGINES = {"pycma": run_pycma, "vectorized": run_cmaes}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=30)
    ap.add_argument("--params", nargs="+", default=["diagonal", "geagsp", "givens", "cayley"])
    ap.add_argument("--out", default="")
    args = ap.parse_args()
    print(f"# {machine()}; {date.today()}")
    committed = pd.read_parquet(STUDY, columns=["problem", "case", "param", "optimizer", "start",
                                                "seed", "best_cost", "max_evals"])
    committed = committed[(committed.problem == "attitude_lyapunov")
                          & (committed.optimizer == "cmaes")]
    rows = []
    for case in ("detumble", "rest_to_rest"):
        for param in args.params:
            cell = committed[(committed.case == case) & (committed.param == param)]
            cell = cell.sort_values("start").head(args.starts)
            prob, layout = swarm.ProblemSpec("attitude_lyapunov", case, param, {},
                                             {"name": param}).build()
            func = swarm.LocalEvaluation().objective(None, prob, layout, param)
            lb, ub = layout.bounds()
            max_evals = int(cell.max_evals.iloc[0])
            for engine, run in ENGINES.items():
                optim.OPTIMIZERS["cmaes"] = optim.Optimizer(CMAESSettings, run)
                t0 = time.process_time()
                for seed in cell.seed:
                    with threadpool_limits(limits=1, user_api="blas"):
                        res = minimize("cmaes", func, lb, ub,
                                       make_settings("cmaes", {"max_evals": max_evals}),
                                       int(seed))
                    mats, scalars = layout.split(res.best_z[None])
                    best = prob.evaluate_batch(mats, scalars or None)
                    rows.append({"problem": "attitude_lyapunov", "case": f"{case}/{param}",
                                 "optimizer": "cmaes", "param": engine, "status": "ok",
                                 "best_cost": res.best_cost, "n_evals": res.n_evals,
                                 "max_evals": max_evals,
                                 "best_converged": bool(best.converged[0])})
                print(f"{case:12s} {param:8s} {engine:10s} {len(cell)} starts "
                      f"{time.process_time() - t0:6.1f} s CPU; committed median "
                      f"{cell.best_cost.median():.6g}", flush=True)
            done = pairwise(pd.DataFrame([r for r in rows if r["case"] == f"{case}/{param}"]))
            print(done[["case", "median_a", "median_b", "best_a", "best_b", "a12_b_beats_a",
                        "p_mwu"]].to_string(index=False, header=False), flush=True)
    optim.OPTIMIZERS["cmaes"] = optim.Optimizer(CMAESSettings, run_cmaes)
    df = pd.DataFrame(rows)
    table = pairwise(df)[["case", "n_a", "n_b", "best_a", "best_b", "median_a", "median_b",
                          "a12_b_beats_a", "p_mwu", "p_holm"]]
    table = table.rename(columns={"n_a": "n_pycma", "n_b": "n_vec", "best_a": "best_pycma",
                                  "best_b": "best_vec", "median_a": "median_pycma",
                                  "median_b": "median_vec", "a12_b_beats_a": "A12_vec_beats"})
    with pd.option_context("display.width", 200, "display.max_columns", 20):
        print(table.to_string(index=False, float_format=lambda v: f"{v:.4g}"))
    if args.out:
        table.to_csv(args.out, index=False)


if __name__ == "__main__":
    main()
