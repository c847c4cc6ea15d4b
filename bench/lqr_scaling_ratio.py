"""The plants of the study ``lqr_scaling``: CMA-ES / lbfgs CPU ratio to reach J*, and the cost
of one exact gradient relative to one evaluation, per plant size n.

The plants are the study's own (profiles ``penaltyrun/conf/experiment/lqr_scaling_n<n>.yaml``),
the map ``givens``, the budgets per start those of ``studies/lqr_scaling/study.yaml`` (CMA-ES:
``optimizer.max_evals``, capped by ``--cmaes-cap``; lbfgs: ``optimizer.starts``, ``maxiter``
and ``max_evals``), both in this process with one BLAS thread.

1. **Gradient / evaluation**: ``--pairs`` candidates uniform in the middle of the box; for
   each, the CPU time (``time.process_time``) of one single-candidate evaluation (as
   L-BFGS-B asks for it) and of one gradient (:func:`penaltyrun.optim.gradient.z_gradient`),
   interleaved; min and median of the per-pair ratios.
2. **CMA-ES / lbfgs**: ``--seeds`` seeds; per seed one lbfgs start then one CMA-ES start
   (interleaved, so a change of the machine's load hits both), each through an objective
   that notes the CPU time and evaluations at which the best cost first comes within
   ``RTOL`` of J*. Per seed the ratio CMA-ES CPU / lbfgs CPU; a CMA-ES start that did not
   reach J* enters with the CPU of its whole run (the ratio is then a lower bound, marked
   ``>``). Prints min and median over the seeds and, for a size where CMA-ES did not reach
   J* in every seed, the goal's ratio the other way round, an upper bound: "CMA-ES did not
   reach J* within B evaluations, X s; lbfgs used Y s: ratio < Y/X" (medians over the
   seeds where lbfgs reached J*).

3. **The rows cache** (``--rows-cache``): per seed, before the two starts above, one more
   lbfgs start on the same problem with its single-candidate rows cache off (every
   evaluation and every gradient solves its point, as before the cache); prints the CPU to
   reach J* without and with the cache and their ratio (min and median over the seeds).

Usage: ``OPENBLAS_NUM_THREADS=1 python bench/lqr_scaling_ratio.py [--sizes 4 8 16 32]
[--race-sizes 4 8 16] [--seeds 3] [--pairs 15] [--cmaes-cap 20000] [--rows-cache]``.
"""

from __future__ import annotations

import argparse
import copy
from pathlib import Path

import numpy as np
import yaml
from machine import machine
from timing import cpu_to_target, gradient_vs_evaluation

from penaltyrun.problems import lqr
from penaltyrun.runner.job import blas_limit
from penaltyrun.runner.setup import build_layout

RTOL = 1e-6
ROOT = Path(__file__).resolve().parents[1]
PROFILES = ROOT / "penaltyrun" / "conf" / "experiment"
STUDY = ROOT / "studies" / "lqr_scaling" / "study.yaml"


def problem(n: int) -> lqr.LQRProblem:
    """The study's plant of n states."""
    data = yaml.safe_load((PROFILES / f"lqr_scaling_n{n}.yaml").read_text())
    return lqr.make_problem("default", data["problem"]["params"])


def budgets(n: int) -> dict[str, dict[str, object]]:
    """The study's optimizer settings of the full map at size n, by optimizer."""
    out: dict[str, dict[str, object]] = {}
    for command in yaml.safe_load(STUDY.read_text())["commands"]:
        args = dict(a.split("=", 1) for a in command["args"])
        if args["+experiment"] != f"lqr_scaling_n{n}" or "givens" not in args["param"]:
            continue
        out[args["optimizer"]] = {k.removeprefix("optimizer."): yaml.safe_load(v)
                                  for k, v in args.items() if k.startswith("optimizer.")}
    return out


def gradient_ratio(prob: lqr.LQRProblem, pairs: int) -> tuple[float, float, float, float]:
    """(evaluation ms, gradient ms, ratio min, ratio median) over ``pairs`` candidates."""
    layout = build_layout(prob, "givens", {})
    lb, ub = layout.bounds()
    rng = np.random.default_rng(0)
    timing = gradient_vs_evaluation(
        prob, layout, lb + (ub - lb) * rng.uniform(0.3, 0.7, size=(pairs, lb.size)))
    return (1e3 * float(np.median(timing.evaluation)), 1e3 * float(np.median(timing.gradient)),
            float(timing.ratio.min()), float(np.median(timing.ratio)))


def without_rows_cache(prob: lqr.LQRProblem) -> lqr.LQRProblem:
    """``prob`` with its single-candidate rows cache off: every call of ``rows`` computes
    (the problem before the cache)."""
    clone = copy.copy(prob)
    clone.rows = lambda Q, R, X0, thresholds=None, metrics=False: clone._rows(  # type: ignore[method-assign]
        Q, R, X0, thresholds, metrics)
    return clone


def race(name: str, prob: lqr.LQRProblem, options: dict[str, object], seed: int
         ) -> tuple[float, float, float]:
    """(CPU s to reach J* within RTOL or inf, evaluations to reach or inf, CPU s of the
    whole run)."""
    return cpu_to_target(name, prob, build_layout(prob, "givens", {}), options, seed,
                         prob.optimum * (1.0 + RTOL))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 16, 32])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--pairs", type=int, default=15)
    ap.add_argument("--race-sizes", type=int, nargs="*", default=None,
                    help="sizes of the CMA-ES / lbfgs race (default: every size; given "
                         "without sizes: no race)")
    ap.add_argument("--rows-cache", action="store_true",
                    help="also time lbfgs without the problem's rows cache (per seed)")
    ap.add_argument("--cmaes-cap", type=int, default=None,
                    help="cap of CMA-ES's evaluations per start (default: the study's)")
    args = ap.parse_args()
    print(machine())
    print(f"{'n':>3} {'dim':>4} {'eval ms':>8} {'grad ms':>8} {'grad/eval min':>13} "
          f"{'median':>7} | {'lbfgs s':>8} {'cmaes s':>9} {'cmaes evals':>11} "
          f"{'reached c/l':>11} {'ratio min':>10} {'median':>10}")
    notes: list[str] = []
    with blas_limit():
        for n in args.sizes:
            prob = problem(n)
            settings = budgets(n)
            if args.cmaes_cap:
                settings["cmaes"]["max_evals"] = min(int(settings["cmaes"]["max_evals"]),
                                                     args.cmaes_cap)
            ev_ms, gr_ms, g_min, g_med = gradient_ratio(prob, args.pairs)
            dim = build_layout(prob, "givens", {}).dim
            if args.race_sizes is not None and n not in args.race_sizes:
                print(f"{n:>3} {dim:>4} {ev_ms:8.3f} {gr_ms:8.3f} {g_min:13.2f} {g_med:7.2f} |"
                      " (no race)", flush=True)
                continue
            rows, cache = [], []
            for seed in range(args.seeds):
                if args.rows_cache:
                    off, _, _ = race("lbfgs", without_rows_cache(prob), settings["lbfgs"], seed)
                lb_cpu, _, _ = race("lbfgs", prob, settings["lbfgs"], seed)
                if args.rows_cache:
                    cache.append((off, lb_cpu))
                cm_cpu, cm_ev, cm_total = race("cmaes", prob, settings["cmaes"], seed)
                rows.append((lb_cpu, min(cm_cpu, cm_total), cm_ev, np.isfinite(cm_cpu)))
            a = np.asarray(rows, float)
            ok = np.isfinite(a[:, 0])
            ratio = a[ok, 1] / a[ok, 0]
            bound = ">" if not np.all(a[:, 3].astype(bool)) else " "
            reached = f"{int(a[:, 3].sum())}/{int(ok.sum())}"
            lo, mid = (ratio.min(), np.median(ratio)) if ratio.size else (np.nan, np.nan)
            print(f"{n:>3} {dim:>4} {ev_ms:8.3f} {gr_ms:8.3f} {g_min:13.2f} {g_med:7.2f} | "
                  f"{np.median(a[:, 0]):8.3g} {np.median(a[:, 1]):9.3g} "
                  f"{np.median(a[:, 2]):11.6g} {reached:>11} {bound}{lo:9.3g} "
                  f"{bound}{mid:9.3g}", flush=True)
            if cache:
                c = np.asarray(cache, float)
                notes.append(f"n = {n}: lbfgs CPU to J* without / with the rows cache, median "
                             f"{np.median(c[:, 0]):.3g} / {np.median(c[:, 1]):.3g} s; ratio "
                             f"min {np.min(c[:, 0] / c[:, 1]):.3g}, median "
                             f"{np.median(c[:, 0] / c[:, 1]):.3g}")
            missed = ~a[:, 3].astype(bool)
            if missed.any() and ok.any():
                y, x = np.median(a[ok, 0]), np.median(a[ok, 1])
                notes.append(f"n = {n}: CMA-ES did not reach J* within "
                             f"{settings['cmaes']['max_evals']} evaluations in "
                             f"{int(missed.sum())} of {len(a)} seeds, {x:.3g} s (median); lbfgs "
                             f"used {y:.3g} s: ratio lbfgs / CMA-ES < {y:.3g}/{x:.3g} = "
                             f"{y / x:.3g}")
    print(f"CMA-ES budget per start: the study's (capped at --cmaes-cap); reached c/l: seeds "
          f"where CMA-ES / lbfgs came within {RTOL:g} of J*; ratios over the seeds where lbfgs "
          "did; '>': some CMA-ES starts never reached J*, their whole run's CPU enters the "
          "ratio (a lower bound)")
    for note in notes:
        print(note)


if __name__ == "__main__":
    main()
