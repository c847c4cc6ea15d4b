"""Swarm-level evaluation: chunks are bitwise the whole batch, shares of the cluster, the
worker-side cache, and (LocalCluster of 2 processes) seeded PSO and CMA-ES starts whose
Parquet rows equal the serial run's."""

import importlib.util
import logging

import numpy as np
import pandas as pd
import pytest

from penaltyrun import io, runner
from penaltyrun.runner import swarm
from penaltyrun.runner.spec import RunnerOptions

CHEAP = [("zermelo", "default"), ("attitude_lyapunov", "detumble"),
         ("attitude_lqr", "detumble"), ("qlaw", "C"), ("lyapunov_transfer", "C")]
TIMING = ["wall_time_s", "started_at", "finished_at", "trace_cpu_s"]
needs_dask = pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                                reason="dask.distributed not installed (optional extra)")


def job(problem="zermelo", case="default", optimizer="pso", options=None, **kw):
    return runner.plan_jobs(problem, case, "full", optimizer, n_starts=1, root_seed=11,
                            optimizer_options=options or {"n_particles": 12, "iters": 6},
                            meta={"config_hash": "x"}, **kw)[0]


@pytest.mark.parametrize(("problem", "case"), CHEAP)
def test_chunks_give_bitwise_the_batch_costs(problem, case):
    spec = swarm.ProblemSpec(problem, case, "full")
    prob, layout = spec.build()
    lb, ub = layout.bounds()
    Z = lb + np.random.default_rng(3).random((7, lb.size)) * (ub - lb)
    whole = swarm.LocalEvaluation().objective(None, prob, layout, "full")(Z)
    swarm.register(spec)
    try:
        parts = [swarm.evaluate_chunk(spec.key, part) for part in np.array_split(Z, 3)]
        swarm.evaluate_chunk(spec.key, Z[:1])
        assert swarm.BUILDS[spec.key] == 1  # built once, then cached
    finally:
        swarm.forget(spec.key)
    assert np.array_equal(np.concatenate([p[0] for p in parts]), whole)
    assert all(p[1] >= 0.0 for p in parts)


def test_unregistered_spec_is_a_clear_error():
    with pytest.raises(KeyError, match="not registered on this worker"):
        swarm.cached("0123456789abcdef")


def test_spec_key_follows_the_settings():
    a = swarm.ProblemSpec.of(job())
    assert a == swarm.ProblemSpec("zermelo", "default", "full")
    assert a.key == swarm.ProblemSpec.of(job()).key
    assert swarm.ProblemSpec.of(job(), "diagonal").key != a.key
    other = runner.plan_jobs("zermelo", "default", "full", "pso", n_starts=1, root_seed=11,
                             problem_params={"wind": 0.5})[0]
    assert swarm.ProblemSpec.of(other).key != a.key


@needs_dask
@pytest.mark.parametrize(("n_jobs", "threads", "chunks", "expected"), [
    (1, 2, "auto", (1, 2)), (240, 512, "auto", (240, 2)), (240, 4096, "auto", (240, 17)),
    (240, 64, "auto", (64, 1)), (3, 8, 2, (3, 2)), (10, 8, 2, (4, 2)), (10, 2, 4, (1, 4)),
])
def test_shares_fill_the_cluster(n_jobs, threads, chunks, expected):
    from penaltyrun.runner.dask_swarm import shares

    assert shares(n_jobs, threads, chunks) == expected


class _Cap:
    """Stands in for a DaskEvaluation: a chunk cap and the auto flag."""

    def __init__(self, cap, auto=True):
        self.cap, self.auto = cap, auto

    def chunk_cap(self):
        return self.cap


@needs_dask
def test_auto_chunks_shrink_when_a_chunk_would_be_too_short():
    from penaltyrun.runner.dask_swarm import DaskBatch

    batch = DaskBatch(_Cap(8), "k")
    assert batch.n_chunks(30) == 8 and batch.n_chunks(3) == 3
    batch.calibrate(30, cpu_s=30 * 1e-4, max_cpu_s=4e-4, wall_s=6e-3)  # 0.1 ms a candidate
    assert batch.n_chunks(30) == 1  # 3 ms of work: one chunk
    slow = DaskBatch(_Cap(8), "k")
    slow.calibrate(30, cpu_s=30 * 1.0, max_cpu_s=4.0, wall_s=4.1)  # 1 s a candidate
    assert slow.n_chunks(30) == 8
    assert slow.critical_cpu_s == 4.0 and slow.overhead_s == pytest.approx(0.1)
    fixed = DaskBatch(_Cap(8, auto=False), "k")
    fixed.calibrate(30, cpu_s=30 * 1e-4, max_cpu_s=4e-4, wall_s=6e-3)
    assert fixed.n_chunks(30) == 8


@needs_dask
def test_auto_cap_shares_the_threads_among_running_starts():
    from penaltyrun.runner.dask_swarm import DaskEvaluation

    evaluation = DaskEvaluation(None, "auto", threads=8)
    evaluation.active = 3
    assert evaluation.chunk_cap() == 2
    evaluation.active = 1  # the last start of the run gets the whole cluster
    assert evaluation.chunk_cap() == 8
    assert DaskEvaluation(None, 5, threads=8).chunk_cap() == 5


@pytest.fixture(scope="module")
def local_cluster():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                       dashboard_address=None, silence_logs=logging.WARNING)
    client = distributed.Client(cluster)
    yield cluster.scheduler_address, client
    client.close()
    cluster.close()


def _rows(jobs, run_dir, **kw):
    runner.execute(jobs, run_dir, RunnerOptions(**{"workers": 1, **kw}))
    df = pd.read_parquet(io.collect(run_dir, [j.job_id for j in jobs]))
    return df.drop(columns=TIMING + ["run_id"]).reset_index(drop=True)


@needs_dask
@pytest.mark.parametrize(("optimizer", "options"), [
    ("pso", {"n_particles": 12, "iters": 6}),
    ("cmaes", {"popsize": 9, "max_evals": 60}),
])
def test_swarm_level_run_is_bitwise_the_serial_run(tmp_path, local_cluster, optimizer,
                                                   options):
    address, client = local_cluster
    jobs = [job(optimizer=optimizer, options=options)]
    key = swarm.ProblemSpec.of(jobs[0]).key
    before = client.run(lambda: dict(swarm.BUILDS))
    serial = _rows(jobs, tmp_path / "serial")
    dist = _rows(jobs, tmp_path / "dask", backend="dask", scheduler=address,
                 evaluate_on="dask", chunks=2)
    pd.testing.assert_frame_equal(dist, serial)
    assert dist.loc[0, "status"] == "ok" and dist.loc[0, "n_evals"] >= 54
    after = client.run(lambda: dict(swarm.BUILDS))
    built = [after[w].get(key, 0) - before[w].get(key, 0) for w in after]
    assert built == [1, 1]  # each worker built the problem once for all the iterations


@needs_dask
def test_warm_started_jobs_share_the_cluster(tmp_path, local_cluster):
    address, _ = local_cluster
    jobs = runner.plan_jobs("zermelo", "default", "full", "pso", n_starts=3, root_seed=5,
                            optimizer_options={"n_particles": 8, "iters": 4, "max_evals": 40},
                            warm_start_share=0.3)
    serial = _rows(jobs, tmp_path / "serial")
    dist = _rows(jobs, tmp_path / "dask", backend="dask", scheduler=address,
                 evaluate_on="dask", chunks="auto")
    pd.testing.assert_frame_equal(dist.sort_values("job_id").reset_index(drop=True),
                                  serial.sort_values("job_id").reset_index(drop=True))


def test_bad_swarm_settings_name_the_key(tmp_path):
    from penaltyrun.errors import ConfigError

    with pytest.raises(ConfigError, match=r"runner.chunks: must be auto or a positive"):
        runner.execute([job()], tmp_path,
                       RunnerOptions(backend="dask", evaluate_on="dask", chunks=0))
    with pytest.raises(ConfigError, match=r"runner.evaluate_on: .*allowed: local, dask"):
        runner.execute([job()], tmp_path, RunnerOptions(evaluate_on="gpu"))
    with pytest.raises(ConfigError, match="runner.evaluate_on: dask needs runner.backend"):
        runner.execute([job()], tmp_path, RunnerOptions(evaluate_on="dask"))
