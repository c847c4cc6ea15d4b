"""``optimizer=lbfgs`` on the plants of the study ``lqr_scaling``: this tree against a base
commit, CPU time to reach J*.

Per plant size and seed, one ``lbfgs`` start with the study's settings (map ``givens``, the
declared charge per gradient) run by this tree's code and one by the code of ``--base``
(checked out into a temporary git worktree and put first on ``PYTHONPATH``), each in its
own process with one BLAS thread, the two in turn (which goes first alternates with the
seed) so that a change of the machine's load hits both. Each process times its start with
``timing.cpu_to_target`` of this tree's ``bench/`` (the loop ``lqr_scaling_ratio.py`` uses):
CPU seconds (``time.process_time``) until the best cost first comes within 1e-6 of J*,
after the process has imported everything and loaded its compiled kernels. Prints per size
the median CPU of each, the evaluations to J* (a change of the code may change round-off
and so the path of L-BFGS-B) and the ratio base / this tree (min and median over the
seeds).

Usage: ``python bench/lbfgs_base.py [--base main] [--sizes 16 32] [--seeds 3]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from base_tree import ROOT, base_worktree
from machine import machine

BENCH = Path(__file__).resolve().parent

#: The child: one lbfgs start of the study's settings at size n, seed s; prints JSON.
ONE_START = """
import json, sys
sys.path.insert(0, sys.argv[3])
from lqr_scaling_ratio import budgets, problem, race
from penaltyrun.runner.job import blas_limit
n, seed = int(sys.argv[1]), int(sys.argv[2])
with blas_limit():
    prob = problem(n)
    race("lbfgs", prob, dict(budgets(n)["lbfgs"], max_evals=40), seed)  # imports, kernels
    cpu, evals, total = race("lbfgs", prob, budgets(n)["lbfgs"], seed)
print(json.dumps({"cpu": cpu, "evals": evals, "total": total}))
"""


def one_start(n: int, seed: int, tree: Path) -> dict[str, float]:
    """CPU s and evaluations to J* of one lbfgs start run by the package in ``tree``."""
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", ONE_START, str(n), str(seed), str(BENCH)],
                         env=env, check=True, capture_output=True, text=True, cwd=tree)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", default="main", help="git revision of the 'before' code")
    ap.add_argument("--sizes", type=int, nargs="+", default=[16, 32])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args()
    print(machine())
    print(f"{'n':>3} {'this tree s':>11} {'base s':>8} {'evals this / base':>18} "
          f"{'ratio base/this min':>19} {'median':>7}")
    with tempfile.TemporaryDirectory() as tmp, base_worktree(args.base, Path(tmp)) as base:
        for n in args.sizes:
            rows = []
            for seed in range(args.seeds):
                trees = [ROOT, base] if seed % 2 == 0 else [base, ROOT]
                runs = {tree: one_start(n, seed, tree) for tree in trees}
                rows.append((runs[ROOT]["cpu"], runs[base]["cpu"], runs[ROOT]["evals"],
                             runs[base]["evals"]))
            a = np.asarray(rows, float)
            ratio = a[:, 1] / a[:, 0]
            print(f"{n:>3} {np.median(a[:, 0]):11.3g} {np.median(a[:, 1]):8.3g} "
                  f"{np.median(a[:, 2]):8.6g} / {np.median(a[:, 3]):<8.6g}"
                  f"{ratio.min():19.3g} {np.median(ratio):7.3g}", flush=True)
    print(f"base: {args.base}; CPU to J* within 1e-6 (inf: not reached), median over "
          f"{args.seeds} seeds")


if __name__ == "__main__":
    main()
