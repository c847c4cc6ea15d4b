"""Benchmark: swarm-level Dask distribution (``runner.evaluate_on=dask``) on a LocalCluster.

1. Per-batch overhead for each problem family: one batch of random full-map candidates
   evaluated in this process (CPU time) and as 1 and 2 chunks on two worker processes
   (wall time); the overhead is the wall time of a distributed batch beyond its longest
   chunk's CPU time (scheduler round trip, serialization, queueing), next to the bare
   round trip of an empty task and the bytes sent per chunk.
2. Speed-up with 2 workers for one seeded Q-law PSO start (default case D, evaluations of
   ~0.3-1 s): the serial start against the same start with every batch in 2 chunks, the
   records compared bitwise. Wall-time speed-up, and the speed-up on idle cores from CPU
   times (serial CPU over the critical path: each batch's longest chunk plus the CPU that
   client, scheduler and workers spend per batch beyond the chunks).

On a shared machine wall times measure the queue for the CPU as much as penaltyrun, so the
overhead is also given in CPU seconds of every process involved (an upper bound of its
latency on idle cores, where the round trip's steps run one after another).

Usage::

    python bench/bench_swarm.py [--problems zermelo qlaw ...] [--case D] [--particles 10]
                                [--iters 3] [--batch 20] [--repeats 9]
"""

from __future__ import annotations

import argparse
import logging
import pickle
import statistics
import time
from datetime import date

import numpy as np
from machine import machine

from penaltyrun.runner import plan_jobs, run_job, swarm
from penaltyrun.runner.dask_swarm import DaskBatch, DaskEvaluation

FAMILIES = {"zermelo": "default", "attitude_lyapunov": "detumble", "attitude_lqr": "detumble",
            "lyapunov_transfer": "C", "qlaw": "C"}


def cpu_now(client) -> float:
    """CPU seconds used so far by this process (client and, for a LocalCluster, the
    scheduler) plus every worker process."""
    return time.process_time() + sum(client.run(time.process_time).values())


def idle_rate(client, seconds: float = 3.0) -> float:
    """CPU seconds per wall second that client, scheduler and workers use while idle (event
    loops, heartbeats); subtracted from the overhead so that it counts the batch's work."""
    cpu0, w0 = cpu_now(client), time.perf_counter()
    time.sleep(seconds)
    return (cpu_now(client) - cpu0) / (time.perf_counter() - w0)


def _batch(prob_layout, n: int, seed: int = 1) -> np.ndarray:
    lb, ub = prob_layout[1].bounds()
    return lb + np.random.default_rng(seed).random((n, lb.size)) * (ub - lb)


def overhead(client, problem: str, case: str, n: int, repeats: int, idle: float
             ) -> dict[str, float]:
    """Local CPU per batch, distributed wall per batch (1 and 2 chunks), overhead, bytes."""
    spec = swarm.ProblemSpec(problem, case, "full")
    built = spec.build()
    Z = _batch(built, n)
    local = swarm.LocalEvaluation().objective(None, built[0], built[1], "full")
    local(Z)  # compile / load kernels
    cpu = []
    for _ in range(repeats):
        c0 = time.process_time()
        local(Z)
        cpu.append(time.process_time() - c0)
    out = {"cpu_batch": statistics.median(cpu), "bytes": len(pickle.dumps(Z[: n // 2]))}
    for chunks in (1, 2):
        evaluation = DaskEvaluation(client, chunks, threads=2)
        key = evaluation.register(spec)
        walls, overs = [], []
        with evaluation.baton.held():
            batch = DaskBatch(evaluation, key)
            assert np.array_equal(batch(Z), local(Z))  # warm-up: workers build the problem
            cpus = []
            for _ in range(repeats):
                before = (batch.wall_s, batch.critical_cpu_s, batch.cpu_s, cpu_now(client))
                batch(Z)
                wall = batch.wall_s - before[0]
                walls.append(wall)
                overs.append(wall - (batch.critical_cpu_s - before[1]))
                spent = cpu_now(client) - before[3] - idle * wall
                cpus.append(spent - (batch.cpu_s - before[2]))
            over_cpu = statistics.median(cpus)
        evaluation.close()
        out[f"wall_{chunks}"] = statistics.median(walls)
        out[f"over_{chunks}"] = statistics.median(overs)
        out[f"over_cpu_{chunks}"] = over_cpu
    return out


def round_trip(client, repeats: int, idle: float) -> tuple[float, float]:
    """Median wall seconds, and mean CPU seconds (all processes, idle use subtracted), of
    submitting and gathering one empty task."""
    walls = []
    cpu0, w0 = cpu_now(client), time.perf_counter()
    for _ in range(repeats):
        t0 = time.perf_counter()
        client.submit(int, 0, pure=False).result()
        walls.append(time.perf_counter() - t0)
    spent = cpu_now(client) - cpu0 - idle * (time.perf_counter() - w0)
    return statistics.median(walls), spent / repeats


def throughput(client, n: int = 200) -> float:
    """Wall seconds per task of ``n`` empty tasks submitted at once and gathered (the
    scheduler's per-task cost when many chunks are in flight)."""
    t0 = time.perf_counter()
    client.gather([client.submit(int, i, pure=False) for i in range(n)])
    return (time.perf_counter() - t0) / n


def qlaw_start(client, case: str, particles: int, iters: int, overhead_cpu: float) -> None:
    """Serial vs 2-chunk distributed seeded PSO start; prints times and the speed-ups."""
    job = plan_jobs("qlaw", case, "full", "pso", n_starts=1, root_seed=20251130,
                    optimizer_options={"n_particles": particles, "iters": iters, "ftol_iter": 100},
                    holdout=False)[0]
    # load the kernels in this process first
    run_job(plan_jobs("qlaw", case, "full", "baseline", n_starts=1, root_seed=1,
                      holdout=False)[0])
    c0, w0 = time.process_time(), time.perf_counter()
    serial = run_job(job)
    cpu_s, wall_s = time.process_time() - c0, time.perf_counter() - w0
    evaluation = DaskEvaluation(client, 2, threads=2)
    key = evaluation.register(swarm.ProblemSpec.of(job))
    with evaluation.baton.held():  # warm-up: the workers build the problem, load kernels
        DaskBatch(evaluation, key)(np.tile(_batch(swarm.ProblemSpec.of(job).build(), 1), (2, 1)))
    batches: list[DaskBatch] = []
    make = evaluation.objective
    evaluation.objective = lambda *a: batches.append(make(*a)) or batches[-1]
    cpu0, w0 = cpu_now(client), time.perf_counter()
    dist = evaluation.run_job(job)
    wall_d, cpu_d = time.perf_counter() - w0, cpu_now(client) - cpu0
    evaluation.close()
    same = all(serial[k] == dist[k] for k in ("best_cost", "best_z", "history", "n_evals"))
    b = batches[0]
    extra = cpu_d - b.cpu_s  # every process's CPU beyond the chunks, idle loops included
    # critical path: each batch's longest chunk and overhead, and the best's evaluation
    crit = b.critical_cpu_s + b.n_batches * max(overhead_cpu, 0.0) + b.cpu_per_eval
    print(f"\nQ-law case {case}, full map, PSO {particles} particles x {iters} iterations: "
          f"{serial['n_evals']} evaluations in {b.n_batches} batches, "
          f"{b.cpu_per_eval:.3f} s CPU per evaluation (worker mean)")
    print(f"  serial:          wall {wall_s:7.2f} s   CPU {cpu_s:7.2f} s")
    print(f"  dask, 2 chunks:  wall {wall_d:7.2f} s   CPU {cpu_d:7.2f} s (chunks {b.cpu_s:.2f} s); "
          f"critical path {b.critical_cpu_s:.2f} s CPU (longest chunk of each batch)")
    print(f"  wall overhead per batch on this machine: {b.overhead_s * 1e3:.0f} ms")
    print(f"  speed-up (wall, this loaded machine): {wall_s / wall_d:5.2f}x")
    work = b.cpu_s + b.cpu_per_eval  # the start's evaluations, as the serial run does them
    print(f"  speed-up on 2 idle cores, from the distributed run's CPU times (its evaluations "
          f"{work:.2f} s / critical path {crit:.2f} s = longest chunks + {b.n_batches} x "
          f"{max(overhead_cpu, 0.0) * 1e3:.0f} ms overhead from the table + the best's "
          f"evaluation): {work / crit:5.2f}x")
    print(f"  same with the serial run's CPU ({cpu_s:.2f} s, another process: ±15 % here): "
          f"{cpu_s / crit:5.2f}x; lower bound, all {extra:.2f} s of extra CPU of every process "
          f"on the critical path: {cpu_s / (b.critical_cpu_s + extra):5.2f}x")
    print(f"  imbalance: longest chunk / mean chunk = "
          f"{b.critical_cpu_s / (b.cpu_s / 2):.3f} (2 chunks)")
    print(f"  records bitwise equal: {same}")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="+", default=list(FAMILIES))
    ap.add_argument("--case", default="D", help="Q-law case of the speed-up start")
    ap.add_argument("--particles", type=int, default=10)
    ap.add_argument("--iters", type=int, default=3)
    ap.add_argument("--batch", type=int, default=20, help="candidates per overhead batch")
    ap.add_argument("--repeats", type=int, default=9)
    args = ap.parse_args(argv)
    import distributed

    print(f"machine: {machine()}; date {date.today()}")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None,
                                  silence_logs=logging.WARNING) as cluster, \
            distributed.Client(cluster) as client:
        client.run(lambda: __import__("penaltyrun.runner.swarm"))
        idle = idle_rate(client)
        wall, cpu = round_trip(client, 20, idle)
        print(f"empty task round trip: {wall * 1e3:.1f} ms wall (median of 20), "
              f"{cpu * 1e3:.1f} ms CPU (all processes); 200 empty tasks at once: "
              f"{throughput(client) * 1e3:.2f} ms wall per task; idle use "
              f"{idle * 1e3:.0f} ms CPU per s (subtracted)", flush=True)
        print(f"\nbatches of {args.batch} candidates; wall columns on this machine, "
              "'ovh CPU' = CPU of client, scheduler and workers beyond the chunks (2 chunks)")
        print(f"{'problem':>18} {'case':>8} {'CPU/eval ms':>11} {'local CPU ms':>12} "
              f"{'dask 1ch ms':>11} {'dask 2ch ms':>11} {'ovh wall ms':>11} "
              f"{'ovh CPU ms':>10} {'ovh CPU/local':>13} {'bytes/chunk':>11}")
        over: dict[str, float] = {}
        for problem in args.problems:
            case = FAMILIES[problem]
            r = overhead(client, problem, case, args.batch, args.repeats, idle)
            over[problem] = r["over_cpu_2"]
            print(f"{problem:>18} {case:>8} {r['cpu_batch'] / args.batch * 1e3:11.3f} "
                  f"{r['cpu_batch'] * 1e3:12.2f} {r['wall_1'] * 1e3:11.2f} "
                  f"{r['wall_2'] * 1e3:11.2f} {r['over_2'] * 1e3:11.2f} "
                  f"{r['over_cpu_2'] * 1e3:10.2f} {r['over_cpu_2'] / r['cpu_batch']:13.2f} "
                  f"{r['bytes']:11d}", flush=True)
        if args.particles > 0:
            ovh = over.get("qlaw", statistics.median(over.values()) if over else 0.0)
            qlaw_start(client, args.case, args.particles, args.iters, ovh)


if __name__ == "__main__":
    main()
