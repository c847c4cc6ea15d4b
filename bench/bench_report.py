"""Benchmark: ``penaltyrun-report`` over results folders, this tree against a base commit.

Each measurement is a fresh process, timed by the parent from ``os.wait4``: CPU time (user +
system of that process and the workers it waited for), wall time and peak resident memory.
Three kinds of process run on the same input:

* ``read``: only :func:`penaltyrun.io.read_results` of the input (every column: the cost of
  loading the records, the floor any report pays);
* ``report``: the whole ``penaltyrun-report INPUT -o TMP`` of this tree;
* ``base``: the same report run by the code of ``--base`` (default ``main``), checked out into
  a temporary git worktree and put first on ``PYTHONPATH`` (skipped with ``--no-base``).

Before the timed runs each tree's report runs once untimed (skipped with ``--no-warm``):
numba caches its compiled kernels beside each tree's sources, and a fresh base worktree's
first report would otherwise pay for compiling every kernel it uses where this tree's,
already compiled, does not.

``report`` and ``base`` runs are interleaved (``--repeats`` pairs) so that both see the same
load of a shared machine; the script prints every run, then the min and median ratios
base/report and report/read. ``--workers N [N ...]`` runs this tree's report once per
worker count in each repeat (``penaltyrun-report --workers N``), interleaved; the CPU time
then includes the workers' (their fork server is stopped and reaped before the report
process ends), the peak RSS is that of the largest single process.

``--large N`` instead writes N synthetic job rows (12 cells of one problem case, the
writer of the report's memory tests, ``tests/report/large_results.py``) and times the
report of them (read lazily above 100 000 rows, progress bar and section cache off) with the
allocators' defaults and with the process settings of ``penaltyrun-report``
(:func:`penaltyrun.io.memory.lean_process_memory`), and the base's report of the same file
(``--repeats`` pairs interleaved; ``--no-base`` skips it); with ``--steps`` it prints
instead the resident memory as each step of the report begins and the bytes per row of the
frame the report holds, with both process settings.

``--bca`` times the BCa interval of one cell (:func:`penaltyrun.report.stats.bca_ci`, its
jackknife in closed form) against :func:`scipy.stats.bootstrap` (its jackknife evaluates
the statistic on n samples of n − 1) for samples of 1 000 to 5 000 values, and checks that
the intervals agree.

``--cache`` times the report twice with one cache folder, initially empty: drawn (and kept
in the cache), then copied from it, and compares the two reports (``--same``). Every other
report this script times uses a fresh empty cache, so it draws every section.

``--row-groups N`` writes N synthetic rows twice, in penaltyrun's row groups
(:data:`penaltyrun.io.schema.ROW_GROUP_ROWS` rows) and as one group (pyarrow's default for
up to a million rows), and times reading the report's per-row columns of one row in the
middle of each (:func:`penaltyrun.io.lazy.fill_columns`, as a lazily read report reads a
best start), each in a fresh process.

``--same A B`` compares two report folders: the same file names, every table and text file
byte for byte, every figure pixel for pixel (how "the same report" is checked when the
code that draws it changes).

Usage::

    python bench/bench_report.py [--input studies] [--base e37fb9b] [--repeats 1] [--no-base]
                                 [--no-warm]
    python bench/bench_report.py --no-base --workers 1 2
    python bench/bench_report.py --large 1000000 [--base main] [--repeats 1]
    python bench/bench_report.py --large 300000 --steps
    python bench/bench_report.py --cache
    python bench/bench_report.py --bca
    python bench/bench_report.py --row-groups 1000000
    python bench/bench_report.py --same REPORT_A REPORT_B
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
from contextlib import nullcontext
from pathlib import Path

from base_tree import base_worktree
from machine import machine

ROOT = Path(__file__).resolve().parent.parent

#: The interpreter of every timed process. ``-P``: ``python -c`` would otherwise put the
#: working directory first on ``sys.path``, before ``PYTHONPATH``, so that a process meant
#: to run the base worktree's code, started from this repository, ran this tree's instead.
PYTHON = (sys.executable, "-P")
#: Prints where the package a timed process runs comes from (checked before timing).
WHERE = "import penaltyrun\nprint(penaltyrun.__file__)\n"
READ = ("import sys\nfrom penaltyrun.io import read_results\n"
        "print(len(read_results(sys.argv[1])), 'rows')\n")
REPORT = ("import sys\nfrom multiprocessing import forkserver\n"
          "from penaltyrun.cli import report_main\n"
          "try:\n    report_main([sys.argv[1], '-o', sys.argv[2], *sys.argv[3:]])\n"
          "finally:\n    forkserver._forkserver._stop()\n")
#: Why :data:`REPORT` stops the fork server (private API, no-op when none was started): the
#: report's workers are children of the fork server, which reaps them; stopped and reaped in
#: turn, its CPU time (its workers' included) reaches the report process's children and so
#: the ``os.wait4`` of the benchmark. Peak RSS stays that of the largest single process.
#: :data:`REPORT` with the allocators' defaults (the command line sets them up to give
#: freed memory back: :func:`penaltyrun.io.memory.lean_process_memory`).
REPORT_DEFAULT_MEMORY = REPORT.replace(
    "import sys\n", "import sys\nimport penaltyrun.io.memory as r\n"
    "r.lean_process_memory = lambda: None\n", 1)
#: The report of ``sys.argv[1]`` with the resident memory (now and peak) printed as each
#: step of its progress bar begins, and the bytes per row of the frame it holds.
STEPS = """
import resource, sys, time
from pathlib import Path
import penaltyrun.report.build as build
from penaltyrun.report.progress import Steps

def rss():
    return int(open("/proc/self/statm").read().split()[1]) * resource.getpagesize() / 2**20

def peak():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

if sys.argv[3] == "lean":  # the command line's process settings (penaltyrun-report)
    from penaltyrun.io.memory import lean_process_memory
    lean_process_memory()
begin, step = time.process_time(), Steps.step
def logged(self, name):
    print(f"| {name} | {time.process_time() - begin:.1f} | {rss():.0f} | {peak():.0f} |",
          flush=True)
    return step(self, name)
Steps.step = logged
read = build.read_results
def measured(*args, **kwargs):
    df = read(*args, **kwargs)
    print(f"frame: {df.memory_usage(deep=True).sum() / max(len(df), 1):.0f} bytes per row; "
          f"after reading {rss():.0f} MB", flush=True)
    return df
build.read_results = measured
print(f"before reading: {rss():.0f} MB (imports)")
print("| step begins | CPU s | RSS MB | peak MB |\\n|---|---|---|---|")
build.build_report(Path(sys.argv[1]), Path(sys.argv[2]), basin_points=0, progress=False)
print(f"| end | {time.process_time() - begin:.1f} | {rss():.0f} | {peak():.0f} |")
"""


def measure(code: str, args: list[str], pythonpath: str | None = None,
            cache_dir: str | None = None) -> dict[str, float]:
    """CPU s, wall s and peak RSS MB of ``python -c code *args`` (its output discarded),
    its report cache ``cache_dir`` (default: a fresh empty folder, so that every section is
    drawn)."""
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    with tempfile.TemporaryDirectory() as empty:
        env["PENALTYRUN_CACHE_DIR"] = cache_dir or empty
        t0 = time.perf_counter()
        proc = subprocess.Popen([*PYTHON, "-c", code, *args], env=env,
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


def _check_tree(tree: Path) -> None:
    """Stop unless a timed process given ``tree`` on ``PYTHONPATH`` imports its package."""
    where = subprocess.run([*PYTHON, "-c", WHERE], env={**os.environ, "PYTHONPATH": str(tree)},
                           check=True, capture_output=True, text=True).stdout.strip()
    if not Path(where).resolve().is_relative_to(Path(tree).resolve()):
        raise SystemExit(f"a process meant to run {tree} imported {where}")


def _row(name: str, m: dict[str, float]) -> str:
    return f"| {name} | {m['cpu']:.1f} | {m['wall']:.1f} | {m['rss']:.0f} |"


def large(rows: int, steps: bool = False, base_tree: Path | None = None, repeats: int = 1,
          warm: bool = True, base_label: str = "base") -> None:
    """Print CPU, wall and peak RSS of the report of ``rows`` synthetic job rows; with
    ``steps`` instead its memory as each step begins (one process, see :data:`STEPS`).
    With ``base_tree`` the base's report of the same file is timed too, ``repeats`` pairs
    interleaved with this tree's (each tree first reports 1 000 rows untimed unless not
    ``warm``: the first report compiles the kernels it uses)."""
    sys.path.insert(0, str(ROOT / "tests" / "report"))
    from large_results import write_large_results

    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; {rows} synthetic rows")
    with tempfile.TemporaryDirectory() as tmp:
        src = write_large_results(Path(tmp) / "results", rows)
        if steps:
            env = {**os.environ, "PYTHONPATH": str(ROOT)}
            for memory in ("default", "lean"):
                print(f"\nprocess memory settings: {memory}")
                subprocess.run([*PYTHON, "-c", STEPS, str(src), f"{tmp}/report",
                                memory], env=env, check=True)
            return
        quiet = "'-o', sys.argv[2], '--progress', 'false', '--no-cache'"
        lean, default = (code.replace("'-o', sys.argv[2]", quiet)
                         for code in (REPORT, REPORT_DEFAULT_MEMORY))
        trees = [ROOT] if base_tree is None else [ROOT, base_tree]
        if warm:
            small = write_large_results(Path(tmp) / "small", 1000)
            for tree in trees:
                measure(lean, [str(small), f"{tmp}/warm"], str(tree))
                shutil.rmtree(f"{tmp}/warm", ignore_errors=True)
        runs: dict[str, list[dict[str, float]]] = {"default": [], "lean": [], "base": []}
        runs["default"].append(measure(default, [str(src), f"{tmp}/report"], str(ROOT)))
        shutil.rmtree(f"{tmp}/report", ignore_errors=True)
        for _ in range(repeats):
            for name, tree in zip(("lean", "base"), trees):
                runs[name].append(measure(lean, [str(src), f"{tmp}/report"], str(tree)))
                shutil.rmtree(f"{tmp}/report", ignore_errors=True)
    print("| run | CPU s | wall s | peak RSS MB |\n|---|---|---|---|")
    for name, label in (("default", "process memory settings default"),
                        ("lean", "process memory settings lean"),
                        ("base", f"base {base_label}, process memory settings lean")):
        for m in runs[name]:
            print(_row(f"report of {rows} rows, {label}", m))
    if runs["base"]:
        for key, unit in (("cpu", "CPU"), ("wall", "wall"), ("rss", "peak RSS")):
            ratios = [b[key] / r[key] for b, r in zip(runs["base"], runs["lean"])]
            print(f"{unit}: base/report min {min(ratios):.2f}x median "
                  f"{statistics.median(ratios):.2f}x")


#: Read the report's per-row columns of row ``sys.argv[2]`` of the file ``sys.argv[1]``.
ONE_ROW = ("import sys\nimport numpy as np\nfrom pathlib import Path\n"
           "from penaltyrun.io.lazy import read_rows\n"
           "from penaltyrun.report.rows import ROW_COLUMNS\n"
           "read_rows(Path(sys.argv[1]), np.array([int(sys.argv[2])]), ROW_COLUMNS)\n")


#: Write ``sys.argv[2]`` synthetic rows into the folder ``sys.argv[1]`` twice: in
#: penaltyrun's row groups (``grouped/``) and as one row group (``one/``).
WRITE_TWO = ("import sys\nfrom pathlib import Path\nimport pyarrow.parquet as pq\n"
             "from large_results import write_large_results\n"
             "rows = int(sys.argv[2])\n"
             "grouped = write_large_results(Path(sys.argv[1]) / 'grouped', rows)\n"
             "one = Path(sys.argv[1]) / 'one' / grouped.name\n"
             "one.parent.mkdir()\n"
             "pq.write_table(pq.read_table(grouped), one, row_group_size=rows)\n")


def row_groups(rows: int) -> None:
    """Print CPU, wall and peak RSS of reading one row of ``rows`` synthetic rows written
    in penaltyrun's row groups and as one row group, and of a process that only imports
    what the reading does (the files are written by another process, so that the
    measured processes are not forks of a large one)."""
    import pyarrow.parquet as pq

    from penaltyrun.io.schema import RESULTS_FILE, ROW_GROUP_ROWS

    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; {rows} synthetic rows")
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([*PYTHON, "-c", WRITE_TWO, tmp, str(rows)], check=True,
                       env={**os.environ, "PYTHONPATH": os.pathsep.join(
                           [str(ROOT), str(ROOT / "tests" / "report")])})
        print("| file | row groups | CPU s | wall s | peak RSS MB |\n|---|---|---|---|---|")
        imports = ONE_ROW.rsplit("\n", 2)[0] + "\n"
        m = measure(imports, [], str(ROOT))
        print(f"| (imports only) | | {m['cpu']:.2f} | {m['wall']:.2f} | {m['rss']:.0f} |")
        for name, folder in ((f"groups of {ROW_GROUP_ROWS}", "grouped"), ("one group", "one")):
            path = Path(tmp) / folder / RESULTS_FILE
            m = measure(ONE_ROW, [str(path), str(rows // 2)], str(ROOT))
            groups = pq.read_metadata(path).num_row_groups
            print(f"| {name} | {groups} | {m['cpu']:.2f} | {m['wall']:.2f} | {m['rss']:.0f} |")


def cached(src: str) -> None:
    """Print CPU, wall and peak RSS of the report of ``src`` drawn into an empty cache and
    then from that cache (default workers), and whether the two are the same."""
    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; input {src}")
    with tempfile.TemporaryDirectory() as tmp:
        runs = {"read": measure(READ, [src], str(ROOT))}
        for name, out in (("report drawn into an empty cache", "drawn"),
                          ("report from the cache", "cached")):
            runs[name] = measure(REPORT, [src, f"{tmp}/{out}"], str(ROOT), f"{tmp}/cache")
        print("| run | CPU s | wall s | peak RSS MB |\n|---|---|---|---|")
        for name, m in runs.items():
            print(_row(name, m))
        same(Path(tmp) / "drawn", Path(tmp) / "cached")


def bca() -> None:
    """Print the CPU of the BCa intervals (median and mean) of lognormal samples, this
    tree's closed-form jackknife against scipy's, and the largest relative difference."""
    import numpy as np
    from scipy import stats

    from penaltyrun.report.stats import bca_ci

    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; BCa, 9999 resamples")
    print("| n | statistic | bca_ci CPU s | scipy.stats.bootstrap CPU s | max rel. diff |")
    print("|---|---|---|---|---|")
    for n in (1000, 2000, 5000):
        x = np.random.default_rng(n).lognormal(0.0, 0.5, n)
        batch = max(2, 5_000_000 // n // 2 * 2) if n * 9999 > 5_000_000 else None
        for name, func in (("median", np.median), ("mean", np.mean)):
            t0 = time.process_time()
            lo, hi, _ = bca_ci(x, name, seed=1)
            t1 = time.process_time()
            ref = stats.bootstrap((x,), func, method="BCa", batch=batch,
                                  rng=np.random.default_rng(1)).confidence_interval
            t2 = time.process_time()
            diff = max(abs(lo - ref.low) / abs(ref.low), abs(hi - ref.high) / abs(ref.high))
            print(f"| {n} | {name} | {t1 - t0:.2f} | {t2 - t1:.2f} | {diff:.1e} |")


def same(a: Path, b: Path) -> bool:
    """Print how two report folders differ (names, text bytes, figure pixels); True if
    they hold the same files, tables and pixels."""
    import numpy as np
    from PIL import Image

    names = sorted(p.name for p in a.iterdir())
    other = sorted(p.name for p in b.iterdir())
    ok = names == other
    if not ok:
        print("files only in one folder:", sorted(set(names) ^ set(other)))
    pixels, texts = [], []
    for name in sorted(set(names) & set(other)):
        if name.endswith(".png"):
            x, y = (np.asarray(Image.open(d / name)) for d in (a, b))
            if x.shape != y.shape or not np.array_equal(x, y):
                pixels.append(f"{name}: {x.shape} / {y.shape}")
        elif (a / name).read_bytes() != (b / name).read_bytes():
            texts.append(name)
    n_png = sum(n.endswith(".png") for n in names)
    print(f"{len(names)} files ({n_png} figures); text files that differ: {texts or 'none'}; "
          f"figures whose pixels differ: {len(pixels)}")
    for line in pixels:
        print("  ", line)
    return ok and not pixels and not texts


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--input", default=str(ROOT / "studies"))
    parser.add_argument("--base", default="main", help="git revision of the 'before' code")
    parser.add_argument("--repeats", type=int, default=1, help="interleaved pairs")
    parser.add_argument("--no-base", action="store_true", help="time this tree only")
    parser.add_argument("--no-warm", action="store_true",
                        help="skip the untimed report of each tree before the timed ones")
    parser.add_argument("--large", type=int, metavar="N", help="report N synthetic rows")
    parser.add_argument("--steps", action="store_true",
                        help="with --large: resident memory as each report step begins")
    parser.add_argument("--bca", action="store_true", help="time the BCa intervals")
    parser.add_argument("--same", nargs=2, metavar=("A", "B"), type=Path,
                        help="compare two report folders")
    parser.add_argument("--cache", action="store_true",
                        help="the report drawn into an empty cache, then from it")
    parser.add_argument("--row-groups", type=int, metavar="N",
                        help="read one row of N synthetic rows, grouped and as one group")
    parser.add_argument("--workers", nargs="+", metavar="N",
                        help="this tree's report once per worker count (--workers N)")
    args = parser.parse_args()
    if args.bca:
        bca()
        return
    if args.same:
        raise SystemExit(0 if same(*args.same) else 1)
    if args.large:
        with tempfile.TemporaryDirectory() as tmp, \
                (nullcontext() if args.no_base or args.steps
                 else base_worktree(args.base, Path(tmp))) as base_tree:
            if base_tree is not None:
                _check_tree(base_tree)
            large(args.large, args.steps, base_tree, args.repeats, not args.no_warm,
                  args.base)
        return
    if args.row_groups:
        row_groups(args.row_groups)
        return
    if args.cache:
        cached(args.input)
        return
    print(f"# {machine()}; {time.strftime('%Y-%m-%d', time.gmtime())}; input {args.input}")
    with tempfile.TemporaryDirectory() as tmp, \
            (nullcontext() if args.no_base else base_worktree(args.base, Path(tmp))) as base_tree:
        if base_tree is not None:
            _check_tree(base_tree)
        _check_tree(ROOT)
        runs: dict[str, list[dict[str, float]]] = {"read": [], "report": [], "base": []}
        if not args.no_warm:
            for tree in (ROOT, base_tree):
                if tree is not None:
                    measure(REPORT, [args.input, f"{tmp}/warm"], str(tree))
                    shutil.rmtree(f"{tmp}/warm", ignore_errors=True)
        runs["read"].append(measure(READ, [args.input], str(ROOT)))
        for i in range(args.repeats):
            for n in args.workers or []:
                runs.setdefault(f"report --workers {n}", []).append(measure(
                    REPORT, [args.input, f"{tmp}/w{n}_{i}", "--workers", n], str(ROOT)))
                shutil.rmtree(f"{tmp}/w{n}_{i}", ignore_errors=True)
            if args.workers:
                continue
            runs["report"].append(measure(REPORT, [args.input, f"{tmp}/r{i}"], str(ROOT)))
            shutil.rmtree(f"{tmp}/r{i}", ignore_errors=True)
            if base_tree is not None:
                runs["base"].append(measure(REPORT, [args.input, f"{tmp}/b{i}"],
                                            str(base_tree)))
                shutil.rmtree(f"{tmp}/b{i}", ignore_errors=True)
    print("| run | CPU s | wall s | peak RSS MB |\n|---|---|---|---|")
    for name, ms in runs.items():
        for m in ms:
            print(_row(f"{name} ({args.base})" if name == "base" else name, m))
    read = runs["read"][0]
    if args.workers:
        first = runs[f"report --workers {args.workers[0]}"]
        for n in args.workers[1:]:
            for key, unit in (("cpu", "CPU"), ("wall", "wall"), ("rss", "peak RSS")):
                ratios = [a[key] / b[key] for a, b in zip(first, runs[f"report --workers {n}"])]
                print(f"{unit}: --workers {args.workers[0]} / --workers {n} min "
                      f"{min(ratios):.2f}x median {statistics.median(ratios):.2f}x")
        return
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
