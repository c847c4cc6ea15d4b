"""Benchmark: ``penaltyrun-report`` over results folders, this tree against a base commit.

Each measurement is a fresh process, timed by the parent from ``os.wait4``: CPU time (user +
system of that process and the workers it waited for), wall time and peak resident memory.
Three kinds of process run on the same input:

* ``read``: only :func:`penaltyrun.io.read_results` of the input (every column: the cost of
  loading the records, the floor any report pays);
* ``report``: the whole ``penaltyrun-report INPUT -o TMP`` of this tree;
* ``base``: the same report run by the code of ``--base`` (default ``main``), checked out into
  a temporary git worktree and put first on ``PYTHONPATH`` (skipped with ``--no-base``).

``report`` and ``base`` runs are interleaved (``--repeats`` pairs) so that both see the same
load of a shared machine; the script prints every run, then the min and median ratios
base/report and report/read.

Usage::

    python bench/bench_report.py [--input studies] [--base e37fb9b] [--repeats 1] [--no-base]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from machine import machine

ROOT = Path(__file__).resolve().parent.parent

READ = ("import sys\nfrom penaltyrun.io import read_results\n"
        "print(len(read_results(sys.argv[1])), 'rows')\n")
REPORT = ("import sys\nfrom penaltyrun.cli import report_main\n"
          "report_main([sys.argv[1], '-o', sys.argv[2]])\n")


def measure(code: str, args: list[str], pythonpath: str | None = None) -> dict[str, float]:
    """CPU s, wall s and peak RSS MB of ``python -c code *args`` (its output discarded)."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-c", code, *args], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace")
    proc.stderr.close()
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"benchmark process failed ({proc.returncode}):\n{err[-2000:]}")
    return {"cpu": usage.ru_utime + usage.ru_stime, "wall": wall,
            "rss": usage.ru_maxrss / 1024}


def _row(name: str, m: dict[str, float]) -> str:
    return f"| {name} | {m['cpu']:.1f} | {m['wall']:.1f} | {m['rss']:.0f} |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--input", default=str(ROOT / "studies"))
    parser.add_argument("--base", default="main", help="git revision of the 'before' code")
    parser.add_argument("--repeats", type=int, default=1, help="interleaved pairs")
    parser.add_argument("--no-base", action="store_true", help="time this tree only")
    args = parser.parse_args()
    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; input {args.input}")
    with tempfile.TemporaryDirectory() as tmp:
        base_tree = None
        if not args.no_base:
            base_tree = Path(tmp) / "base"
            subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach",
                            str(base_tree), args.base], check=True, capture_output=True)
        try:
            runs: dict[str, list[dict[str, float]]] = {"read": [], "report": [], "base": []}
            runs["read"].append(measure(READ, [args.input], str(ROOT)))
            for i in range(args.repeats):
                runs["report"].append(measure(REPORT, [args.input, f"{tmp}/r{i}"], str(ROOT)))
                shutil.rmtree(f"{tmp}/r{i}", ignore_errors=True)
                if base_tree is not None:
                    runs["base"].append(measure(REPORT, [args.input, f"{tmp}/b{i}"],
                                                str(base_tree)))
                    shutil.rmtree(f"{tmp}/b{i}", ignore_errors=True)
        finally:
            if base_tree is not None:
                subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force",
                                str(base_tree)], check=False, capture_output=True)
    print("| run | CPU s | wall s | peak RSS MB |\n|---|---|---|---|")
    for name, ms in runs.items():
        for m in ms:
            print(_row(f"{name} ({args.base})" if name == "base" else name, m))
    read = runs["read"][0]
    for key, unit in (("cpu", "CPU"), ("wall", "wall"), ("rss", "peak RSS")):
        per_read = [m[key] / read[key] for m in runs["report"]]
        line = f"{unit}: report/read min {min(per_read):.1f}x median " \
               f"{statistics.median(per_read):.1f}x"
        if runs["base"]:
            ratios = [b[key] / r[key] for b, r in zip(runs["base"], runs["report"])]
            line += (f"; base/report min {min(ratios):.2f}x median "
                     f"{statistics.median(ratios):.2f}x")
        print(line)


if __name__ == "__main__":
    main()
