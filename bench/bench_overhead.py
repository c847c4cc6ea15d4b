"""Per-job, start-up and per-call costs: each path before and after, measured in one run.

Four ratios, each from pairs interleaved in one process (or one pair of child processes),
CPU time (``time.process_time``; a child's from ``os.wait4``), min and median:

1. **tiny job** (Zermelo, ``optimizer=baseline``: one evaluation, its detail and its 24
   held-out starts): CPU per job outside the integration kernels. Before: BLAS limited by
   ``threadpool_limits`` entered per job and the held-out set run one kernel call per start
   (both kept callable here); after: :func:`penaltyrun.runner.job.run_job` as shipped.
2. **refused override** (``runner.n_starts=0``, a range; ``param=bogus``, a choice): CPU of
   the whole ``penaltyrun`` process.
   Before: the same command-line checks in the order they ran before (Hydra imported with
   the command line, the value refused by the preflight after the config was composed and
   the problem modules imported); after: ``python -m penaltyrun.cli``.
3. **problem=lqr evaluate_batch** per call at n = 2, 4, 8 states (2 inputs, 3 starts, 10
   candidates: a CMA-ES generation): before, the batched numpy Riccati solve and cost and the
   grading on the whole batch (kept callable here); after, as shipped. Beside them, the
   batch's eigensolves alone (the arithmetic floor of an evaluation).
4. **Zermelo held-out set** of one gain: one kernel call per start (before) against one call
   for all starts.

Usage: ``python bench/bench_overhead.py [--pairs 30]``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from datetime import date
from functools import partial
from typing import Any

import numpy as np
from machine import machine

#: The command-line checks as they ran before: Hydra imported with the command line, the
#: value refused by the preflight after composing the config (problems imported there).
OLD_REFUSAL = """
import sys
import hydra  # imported by penaltyrun.cli at module level before
import penaltyrun.cli.app
from penaltyrun.cli import args as cliargs
from penaltyrun.cli import userconf
from penaltyrun.errors import ConfigError
from penaltyrun.cli.preflight import preflight

argv, keep = cliargs.pop_keep(cliargs.options_first(userconf.normalize_argv(sys.argv[1:])))
try:
    args = cliargs.check_options(argv)
    cliargs.check_sweeps(args.overrides, args.multirun)
    with cliargs.hydra_errors():
        preflight(argv)
except ConfigError as exc:
    print(f"penaltyrun: error: {exc}", file=sys.stderr)
    sys.exit(2)
"""


def summary(before: list[float], after: list[float]) -> str:
    ratios = [b / a for b, a in zip(before, after)]
    return (f"before min {min(before):.4g} / median {statistics.median(before):.4g}, "
            f"after min {min(after):.4g} / median {statistics.median(after):.4g}; "
            f"ratio min {min(ratios):.2f}× / median {statistics.median(ratios):.2f}×")


def interleaved(before: Callable[[], float], after: Callable[[], float], pairs: int
                ) -> tuple[list[float], list[float]]:
    """``pairs`` measurements of each, alternating which goes first."""
    b, a = [], []
    for i in range(pairs):
        if i % 2:
            a.append(after())
            b.append(before())
        else:
            b.append(before())
            a.append(after())
    return b, a


def cpu_of(func: Callable[[], Any], repeats: int = 1) -> float:
    t0 = time.process_time()
    for _ in range(repeats):
        func()
    return (time.process_time() - t0) / repeats


# ------------------------------------------------------------------------ 1. tiny job

class KernelClock:
    """CPU spent in the Zermelo integration kernels, summed over the wrapped calls."""

    def __init__(self) -> None:
        self.total = 0.0

    def wrap(self, func: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kw: Any) -> Any:
            t0 = time.process_time()
            try:
                return func(*args, **kw)
            finally:
                self.total += time.process_time() - t0
        return timed


def holdout_one_call_per_start(prob: Any, mats: Any, sc: Any) -> dict[str, np.ndarray]:
    """The Zermelo held-out runs as computed before: one kernel call per start."""
    from penaltyrun.problems.base import check_spd

    K = check_spd("matrices.K", mats["K"], 2)
    out: dict[str, list] = {k: [] for k in ("cost", "energy", "converged", "status",
                                            "t_final", "final_distance")}
    for x0 in sc["x0"]:
        t_end, energy, dist, status = prob._run(K[None], x0)
        be = prob._graded(t_end, energy, dist, status, float(np.hypot(*x0)))
        for key, value in (("cost", be.cost[0]), ("energy", energy[0]),
                           ("converged", be.converged[0]), ("status", be.status[0]),
                           ("t_final", t_end[0]), ("final_distance", dist[0])):
            out[key].append(value)
    res = {k: np.asarray(v) for k, v in out.items()}
    res["status"] = np.asarray(out["status"], dtype=object)
    return res


@contextlib.contextmanager
def patched(obj: Any, name: str, value: Any) -> Iterator[None]:
    """``obj.name = value`` for the block (a class keeps its own descriptor, e.g. a
    staticmethod, when restored)."""
    old = vars(obj)[name] if name in vars(obj) else getattr(obj, name)
    setattr(obj, name, value)
    try:
        yield
    finally:
        setattr(obj, name, old)


def bench_job(pairs: int) -> str:
    from threadpoolctl import threadpool_limits

    from penaltyrun.problems import zermelo
    from penaltyrun.runner import job as job_module
    from penaltyrun.runner.plan import plan_jobs

    job = plan_jobs("zermelo", "default", "full", "baseline", n_starts=1, root_seed=0)[0]
    clock = KernelClock()
    zermelo.simulate_batch = clock.wrap(zermelo.simulate_batch)
    zermelo.closed_batch = clock.wrap(zermelo.closed_batch)
    job_module.run_job(job)  # compile / load the kernels

    def outside(run: Callable[[], dict[str, Any]]) -> float:
        clock.total = 0.0
        t0 = time.process_time()
        record = run()
        assert record["status"] == "ok", record.get("error")
        return (time.process_time() - t0 - clock.total) * 1e3

    def before() -> float:
        def run() -> dict[str, Any]:
            with threadpool_limits(limits=job_module.BLAS_THREADS, user_api="blas"):
                return job_module._run_job(job)
        with patched(zermelo.Zermelo, "_holdout_runs", holdout_one_call_per_start):
            return outside(run)

    def after() -> float:
        return outside(lambda: job_module.run_job(job))

    b, a = interleaved(before, after, pairs)
    return f"tiny job, CPU outside kernels (ms): {summary(b, a)}"


# ------------------------------------------------------------------ 2. refused override

def child_cpu(args: list[str], key: str) -> float:
    """CPU seconds (user + system) of a child process run to its end, which must refuse
    ``key`` with exit code 2."""
    with open(os.devnull, "w") as null:
        proc = subprocess.Popen(args, stdout=null, stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(proc.pid, 0)
        err = proc.stderr.read()
        proc.stderr.close()
    assert os.waitstatus_to_exitcode(status) == 2 and f"error: {key}:" in err, err
    return usage.ru_utime + usage.ru_stime


def bench_refusal(pairs: int, argv: list[str], key: str) -> str:
    b, a = interleaved(
        lambda: child_cpu([sys.executable, "-c", OLD_REFUSAL, *argv], key),
        lambda: child_cpu([sys.executable, "-m", "penaltyrun.cli", *argv], key), pairs)
    return f"refused override {argv[-1]}, process CPU (s): {summary(b, a)}"


# -------------------------------------------------------------------- 3. problem=lqr

def _graded_before(self: Any, J: np.ndarray, t_end: np.ndarray, x_final: np.ndarray,
                   X0: np.ndarray, codes: np.ndarray, excess: np.ndarray,
                   free: bool) -> np.ndarray:
    """The grading of problem=lqr as it was: every penalty on the whole batch."""
    from penaltyrun.problems.lqr.problem import HARD_FACTOR

    ratio = np.linalg.norm(x_final, axis=2) / np.linalg.norm(X0, axis=1)
    tol = self.params.settle_tol
    if tol is not None and not free:
        codes[(codes == "converged") & ~(ratio <= tol)] = "not_settled"
    codes[(codes == "converged") & (excess > 0)] = "constraint"
    P = self.penalty
    with np.errstate(all="ignore"):
        cost = np.where(codes == "not_settled", J + P * (1.0 + ratio / (1.0 + ratio)), J)
        graded = np.where(np.isfinite(excess), excess / (1.0 + excess), 1.0)
        cost = np.where(codes == "constraint", J + P * (1.0 + graded), cost)
        run_t = float(self.params.free_time_cap) if free else self.t_max
        late = (run_t - t_end) / run_t
        cost = np.where(np.isin(codes, ("diverged", "step_failure")), J + P * (2.0 + late),
                        cost)
    finite_J = np.where(np.isfinite(J), J, 0.0)
    return np.where(np.isfinite(cost) & (codes != "nonfinite"), cost,
                    HARD_FACTOR * P + finite_J)


def _aggregate_before(res: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from penaltyrun.problems.lqr.problem import STATUSES

    rank = np.vectorize(STATUSES.index, otypes=[int])(res["status"])
    worst = np.asarray([STATUSES[r] for r in rank.max(axis=1)], dtype=object)
    return res["cost"].mean(axis=1), worst == "converged", worst


@contextlib.contextmanager
def lqr_before() -> Iterator[None]:
    """problem=lqr's batched numpy path, as before."""
    from penaltyrun.dynamics import linear, riccati
    from penaltyrun.problems.lqr import problem

    with patched(riccati, "COMPILED_MAX_STATES", 0), \
            patched(linear, "COMPILED_MAX_STATES", 0), \
            patched(problem.LQRProblem, "_graded", _graded_before), \
            patched(problem.LQRProblem, "_aggregate", staticmethod(_aggregate_before)):
        yield


def _lqr_pair(prob: Any, mats: dict[str, np.ndarray], repeats: int
              ) -> tuple[Callable[[], float], Callable[[], float]]:
    """CPU µs per evaluate_batch call of the path before, and of the path shipped."""
    def before() -> float:
        with lqr_before():
            return cpu_of(lambda: prob.evaluate_batch(mats), repeats) * 1e6

    def after() -> float:
        return cpu_of(lambda: prob.evaluate_batch(mats), repeats) * 1e6

    return before, after


def _lapack_only(prob: Any, mats: dict[str, np.ndarray]) -> None:
    """The eigensolves of one evaluation alone (Hamiltonian, closed-loop spectrum twice),
    batched: the arithmetic an evaluation cannot avoid."""
    A, B = prob.plant.A, prob.plant.B
    n = A.shape[0]
    Q = prob.state_penalty(mats["Q"])
    S = B @ np.linalg.inv(mats["R"]) @ B.T
    H = np.zeros((Q.shape[0], 2 * n, 2 * n))
    H[:, :n, :n], H[:, :n, n:], H[:, n:, :n], H[:, n:, n:] = A, -S, -Q, -A.T
    np.linalg.eig(H)
    A_cl = A - S @ Q  # a batch of the same shape and kind as the closed loops
    np.linalg.eigvals(A_cl)
    np.linalg.eig(A_cl)


def bench_lqr(pairs: int, repeats: int = 40) -> list[str]:
    from penaltyrun import problems

    lines = []
    for n in (2, 4, 8):
        rng = np.random.default_rng(n)
        A, B = rng.normal(size=(n, n)) / np.sqrt(n), rng.normal(size=(n, 2))
        prob = problems.make("lqr", None, {"A": A.tolist(), "B": B.tolist(),
                                           "x0": rng.normal(size=(3, n)).tolist(),
                                           "t_max": 10.0})
        L = rng.normal(size=(10, n, n))
        Q = L @ np.swapaxes(L, 1, 2) / n + 1e-3 * np.eye(n)
        L = rng.normal(size=(10, 2, 2))
        R = L @ np.swapaxes(L, 1, 2) / 2 + 0.1 * np.eye(2)
        mats = {"Q": Q, "R": R}
        new = prob.evaluate_batch(mats)
        with lqr_before():
            old = prob.evaluate_batch(mats)
        assert new.status.tolist() == old.status.tolist()
        diff = float(np.max(np.abs(new.cost - old.cost) / np.abs(old.cost)))

        before, after = _lqr_pair(prob, mats, repeats)
        floor = min(cpu_of(partial(_lapack_only, prob, mats), repeats) * 1e6
                    for _ in range(pairs))
        b, a = interleaved(before, after, pairs)
        lines.append(f"lqr evaluate_batch n={n}, 10 candidates (µs per call): "
                     f"{summary(b, a)}; largest relative cost difference {diff:.1e}; "
                     f"LAPACK eigensolves alone {floor:.0f} µs")
    return lines


# ----------------------------------------------------------------- 4. Zermelo held-out

def bench_holdout(pairs: int, repeats: int = 20) -> str:
    from penaltyrun import problems
    from penaltyrun.problems.zermelo import PAPER_K_FULL

    prob = problems.make("zermelo", None, {})
    sc = prob.holdout_scenarios()
    mats = {"K": np.asarray(PAPER_K_FULL, dtype=float)}
    new = prob._holdout_runs(mats, sc)
    old = holdout_one_call_per_start(prob, mats, sc)
    assert all(new[k].tolist() == old[k].tolist() for k in old)
    b, a = interleaved(
        lambda: cpu_of(lambda: holdout_one_call_per_start(prob, mats, sc), repeats) * 1e3,
        lambda: cpu_of(lambda: prob._holdout_runs(mats, sc), repeats) * 1e3, pairs)
    return (f"zermelo held-out set, {len(sc['x0'])} starts (ms per gain): {summary(b, a)}; "
            "results bit for bit equal")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=30, help="interleaved pairs per ratio")
    parser.add_argument("--process-pairs", type=int, default=7,
                        help="interleaved pairs of child processes (refused override)")
    args = parser.parse_args()
    from threadpoolctl import threadpool_limits

    print(f"{machine()}; {date.today().isoformat()}; CPU time; before / after")
    print(bench_refusal(args.process_pairs, ["problem=zermelo", "runner.n_starts=0"],
                        "runner.n_starts"), flush=True)
    print(bench_refusal(args.process_pairs, ["param=bogus"], "param"), flush=True)
    print(bench_job(args.pairs), flush=True)
    with threadpool_limits(limits=1, user_api="blas"):
        print(bench_holdout(args.pairs), flush=True)
        for line in bench_lqr(args.pairs):
            print(line, flush=True)


if __name__ == "__main__":
    main()
