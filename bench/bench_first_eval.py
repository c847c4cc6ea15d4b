"""Benchmark: first evaluation in a fresh process, with a cold and with a warm numba cache.

For each problem, a fresh Python process imports penaltyrun, builds the problem and evaluates
one batch of identity matrices; it prints the CPU and wall time from start to result. Each
problem runs twice against a private, initially empty numba cache directory
(``NUMBA_CACHE_DIR``): the first process compiles every kernel and writes the cache, the second
loads it (what every worker of a sweep after the first one sees). The ratio cold/warm is the
compilation a worker no longer pays.

Usage::

    python bench/bench_first_eval.py [--problems zermelo attitude_lyapunov ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

from machine import machine

PROBLEMS = ("zermelo", "attitude_lyapunov", "attitude_lqr", "lyapunov_transfer", "qlaw")

CHILD = """
import json, sys, time
c0, w0 = time.process_time(), time.perf_counter()
import numpy as np
from penaltyrun.problems import make
prob = make(sys.argv[1], sys.argv[2], {})
mats = {m.name: np.eye(m.size)[None] for m in prob.matrices}
prob.evaluate_batch(mats)
print(json.dumps({"cpu": time.process_time() - c0, "wall": time.perf_counter() - w0}))
"""


def first_eval(problem: str, case: str, cache_dir: str) -> dict:
    """CPU and wall seconds of import + build + first batch evaluation in a new process."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", CHILD, problem, case], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=list(PROBLEMS))
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    print(f"{'problem':>18} {'cold cpu s':>10} {'cold wall s':>11} {'warm cpu s':>10} "
          f"{'warm wall s':>11} {'cpu ratio':>9}")
    for problem in args.problems:
        case = "C" if problem in ("qlaw", "lyapunov_transfer") else "default"
        if problem.startswith("attitude"):
            case = "detumble"
        with tempfile.TemporaryDirectory(prefix="numba-cache-") as cache_dir:
            cold = first_eval(problem, case, cache_dir)
            warm = first_eval(problem, case, cache_dir)
        print(f"{problem:>18} {cold['cpu']:10.2f} {cold['wall']:11.2f} {warm['cpu']:10.2f} "
              f"{warm['wall']:11.2f} {cold['cpu'] / warm['cpu']:9.1f}", flush=True)


if __name__ == "__main__":
    main()
