"""Benchmark: CPU split of a CMA-ES start (problem vs optimizer) before and after the
vectorized CMA-ES, and the optimizer's own cost per evaluation against the two PSOs.

One start of each method on the attitude Lyapunov PD cell (``attitude_lyapunov``, case
``detumble``, default map GEAGSP; ``optimizer.max_evals`` evaluations each, default 3000 as
the ``cmaes`` preset), run through :func:`penaltyrun.optim.minimize` with one BLAS thread as
the runner does:

* ``cmaes/pycma``: the former path, IPOP restarts around the ``cma`` package
  (``cmaes_pycma.py``);
* ``cmaes``: penaltyrun's CMA-ES (:mod:`penaltyrun.optim.cma_core`);
* ``pso`` (pyswarms) and ``pso_matlab``, each with ``optimizer.max_evals`` as its cap.

The problem's CPU is the time inside the objective (decode and kernel); the optimizer's is
the rest of the start (its own work and the evaluation counting). CPU time
(``time.process_time``); the methods run interleaved, one start each per repeat with the
repeat's seed and a rotating order, and every figure is given as min and median over the
repeats; the ratios are paired by repeat.

Usage::

    python bench/bench_cmaes.py [--param geagsp] [--case detumble] [--evals 3000]
                                [--repeats 9]
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import time
from collections.abc import Callable
from datetime import date

import numpy as np
from cmaes_pycma import run_pycma
from machine import machine
from threadpoolctl import threadpool_limits

import penaltyrun.optim as optim
from penaltyrun.optim import make_settings, minimize
from penaltyrun.optim.cmaes import CMAESSettings, run_cmaes
from penaltyrun.runner import swarm

#: The former path needs pycma (the dev extra); without it the bench times the others.
METHODS = (("cmaes/pycma",) if importlib.util.find_spec("cma") else ()) + (
    "cmaes", "pso", "pso_matlab")


def objective(case: str, param: str) -> tuple[Callable, np.ndarray, np.ndarray, list[float]]:
    """The cell's batched objective (as the runner builds it), its box, and the CPU
    accumulator the objective adds its own time to."""
    prob, layout = swarm.ProblemSpec("attitude_lyapunov", case, param, {},
                                     {"name": param}).build()
    inner = swarm.LocalEvaluation().objective(None, prob, layout, param)
    spent = [0.0]

    def timed(Z: np.ndarray) -> np.ndarray:
        t0 = time.process_time()
        out = inner(Z)
        spent[0] += time.process_time() - t0
        return out

    lb, ub = layout.bounds()
    return timed, lb, ub, spent


def one_start(method: str, func: Callable, lb: np.ndarray, ub: np.ndarray,
              spent: list[float], evals: int, seed: int) -> tuple[float, float, int]:
    """(total CPU s, problem CPU s, evaluations) of one start."""
    name = method.split("/")[0]
    optim.OPTIMIZERS["cmaes"] = optim.Optimizer(
        CMAESSettings, run_pycma if method == "cmaes/pycma" else run_cmaes)
    settings = make_settings(name, {"max_evals": evals})
    spent[0] = 0.0
    t0 = time.process_time()
    res = minimize(name, func, lb, ub, settings, seed)
    return time.process_time() - t0, spent[0], res.n_evals


def fmt(values: list[float], unit: str = "", digits: int = 3) -> str:
    return (f"min {min(values):.{digits}g}{unit}  median "
            f"{statistics.median(values):.{digits}g}{unit}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="detumble")
    ap.add_argument("--param", default="geagsp")
    ap.add_argument("--evals", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args()
    print(f"# {machine()}; {date.today()}")
    print(f"# attitude_lyapunov / {args.case} / {args.param}, {args.evals} evaluations per "
          f"start, {args.repeats} interleaved repeats, CPU time")
    if "cmaes/pycma" not in METHODS:
        print("# cma (pycma) is not installed (pip install -e '.[dev]'): no before/after")
    func, lb, ub, spent = objective(args.case, args.param)
    out: dict[str, list[tuple[float, float, int]]] = {m: [] for m in METHODS}
    with threadpool_limits(limits=1, user_api="blas"):
        for m in METHODS:  # warm-up: numba kernels (compiled or loaded), imports
            one_start(m, func, lb, ub, spent, 200, 0)
        for r in range(args.repeats):
            for m in METHODS[r % len(METHODS):] + METHODS[:r % len(METHODS)]:
                out[m].append(one_start(m, func, lb, ub, spent, args.evals, r + 1))
    optim.OPTIMIZERS["cmaes"] = optim.Optimizer(CMAESSettings, run_cmaes)
    opt_us = {m: [(t - p) / n * 1e6 for t, p, n in v] for m, v in out.items()}
    print(f"\n{'method':12s} {'start CPU s':>26s} {'optimizer share':>26s} "
          f"{'optimizer µs/evaluation':>30s} {'problem µs/evaluation':>30s}")
    for m, v in out.items():
        print(f"{m:12s} {fmt([t for t, _, _ in v]):>26s} "
              f"{fmt([(t - p) / t * 100 for t, p, _ in v], ' %'):>26s} "
              f"{fmt(opt_us[m]):>30s} {fmt([p / n * 1e6 for _, p, n in v]):>30s}")
    print("\nratios, paired by repeat (min, median):")
    pairs = [("cmaes/pycma", "cmaes"), ("pso", "cmaes"), ("pso_matlab", "cmaes")]
    for a, b in pairs[0 if "cmaes/pycma" in METHODS else 1:]:
        ratio = [x / y for x, y in zip(opt_us[a], opt_us[b])]
        print(f"  optimizer CPU per evaluation, {a} / {b}: {fmt(ratio, '×')}")
    if "cmaes/pycma" in METHODS:
        ratio = [x[0] / y[0] for x, y in zip(out["cmaes/pycma"], out["cmaes"])]
        print(f"  CPU of a start, cmaes/pycma / cmaes: {fmt(ratio, '×')}")
    share = statistics.median((t - p) / t for t, p, _ in out["cmaes"]) * 100
    print(f"\noptimizer share of a CMA-ES start (median): {share:.1f} % (goal: under 25 %)")


if __name__ == "__main__":
    main()
