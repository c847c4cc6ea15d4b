"""Item 8: the dask backend against an external ``dask scheduler`` with two ``dask worker``
processes on 127.0.0.1, one of them killed mid-run; then the last worker killed."""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import pandas as pd
import pytest

from penaltyrun.io import RESULTS_FILE

distributed = pytest.importorskip("distributed")

SLOW_JOBS = ["problem=zermelo", "param=diagonal", "optimizer.n_particles=200",
             "optimizer.iters=60", "optimizer.ftol_iter=100", "runner.report=false"]


def popen(*args, cwd):
    return subprocess.Popen([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def records(run):
    return [json.loads(p.read_text()) for p in sorted((run / "jobs").glob("*.json"))]


def wait_for_records(run, n=1, timeout=600):
    deadline = time.monotonic() + timeout
    while len(list((run / "jobs").glob("*.json"))) < n:
        assert time.monotonic() < deadline, "no job record appeared"
        time.sleep(0.2)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(*args):
    return subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_" + args[0],
                             *args[1:]], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


@pytest.fixture
def cluster():
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_start("scheduler", "--host", "127.0.0.1", "--port", str(port),
                    "--no-dashboard")]
    try:
        procs += [_start("worker", address, "--nthreads", "1", "--no-nanny",
                         "--no-dashboard") for _ in range(2)]
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
            pids = client.run(os.getpid)
        yield address, procs[1:], pids
    finally:
        for proc in procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=10)


@pytest.mark.slow
def test_external_cluster_survives_a_killed_worker_then_times_out(tmp_path, cluster):
    address, workers, _ = cluster
    run = tmp_path / "run"
    args = [*SLOW_JOBS, "runner.n_starts=4", "runner.backend=dask",
            f"runner.scheduler={address}", "runner.worker_timeout=10", f"hydra.run.dir={run}"]
    proc = popen(*args, cwd=tmp_path)
    wait_for_records(run)
    workers[0].kill()  # SIGKILL: its task is run again on the other worker
    out, err = proc.communicate(timeout=900)
    assert proc.returncode == 0, err
    assert sorted(r["start"] for r in records(run)) == [0, 1, 2, 3]
    assert {r["status"] for r in records(run)} == {"ok"}
    assert sum("[" in ln and "/4] " in ln for ln in (out + err).splitlines()) == 4  # once each
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 4

    # the last worker dies mid-run: one line and exit 4 after runner.worker_timeout
    run2 = tmp_path / "run2"
    proc = popen(*[a for a in args if not a.startswith("hydra.run.dir")],
                 "runner.n_starts=3", f"hydra.run.dir={run2}", cwd=tmp_path)
    wait_for_records(run2)
    workers[1].kill()
    t_kill = time.monotonic()
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 4, err
    assert time.monotonic() - t_kill >= 10
    assert "Traceback" not in err + out
    assert "no dask worker for 10 s" in err.strip().splitlines()[-1]
    assert "runner.resume=true" in err.strip().splitlines()[-1]
    assert 1 <= len(records(run2)) < 3
