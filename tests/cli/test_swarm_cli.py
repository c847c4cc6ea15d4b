"""Swarm-level distribution from the command line: one-line errors for bad settings, and
(slow) one start over two external ``dask worker`` processes on 127.0.0.1, one of them
killed mid-run: the start finishes with the serial run's result."""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest

BASE = ["param=full", "runner.report=false", "runner.n_starts=1"]


def cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize(("args", "message"), [
    (["runner.chunks=0"], "runner.chunks: must be auto or a positive integer, got 0"),
    (["runner.evaluate_on=dask", "runner.backend=dask", "runner.scheduler=tcp://127.0.0.1:{port}"],
     "runner.scheduler: cannot reach a scheduler at tcp://127.0.0.1:"),
])
def test_bad_swarm_settings_are_one_line_exit_2(tmp_path, args, message):
    args = [a.format(port=_free_port()) for a in args]
    proc = cli("problem=zermelo", *BASE, *args, f"hydra.run.dir={tmp_path / 'run'}", cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"penaltyrun: error: {message}")
    assert not (tmp_path / "run").exists()


def _start(*args):
    return subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_" + args[0],
                             *args[1:]], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


@pytest.mark.slow
def test_killed_worker_costs_only_its_chunk(tmp_path):
    distributed = pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_start("scheduler", "--host", "127.0.0.1", "--port", str(port),
                    "--no-dashboard")]
    opts = ["problem=qlaw", "case=C", "optimizer.n_particles=40", "optimizer.iters=40",
            "optimizer.ftol_iter=1000", "runner.holdout=false"]
    try:
        procs += [_start("worker", address, "--nthreads", "1", "--no-nanny",
                         "--no-dashboard") for _ in range(2)]
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
            by_pid = {p.pid: p for p in procs[1:]}
            workers = {addr: by_pid[pid] for addr, pid in client.run(os.getpid).items()}
            run = tmp_path / "dask"
            proc = subprocess.Popen(
                [sys.executable, "-m", "penaltyrun.cli", *BASE, *opts,
                 "runner.backend=dask", "runner.evaluate_on=dask", "runner.chunks=2",
                 f"runner.scheduler={address}", f"hydra.run.dir={run}"], cwd=tmp_path,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            # mid-iteration: a few batches done, a chunk running on the worker we kill
            deadline = time.monotonic() + 300
            victim = None
            while victim is None:
                assert time.monotonic() < deadline and proc.poll() is None
                built = sum(client.run(lambda: sum(__import__(
                    "penaltyrun.runner.swarm", fromlist=["BUILDS"]).BUILDS.values())).values())
                busy = [a for a, keys in client.processing().items() if keys]
                if built >= 2 and busy:
                    victim = workers[busy[0]]
                time.sleep(0.05)
            victim.kill()  # SIGKILL: its chunk is evaluated again on the other worker
            out, err = proc.communicate(timeout=900)
        assert proc.returncode == 0, err
        assert victim.wait(timeout=10) == -signal.SIGKILL
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait(timeout=10)
    serial = tmp_path / "serial"
    done = cli(*BASE, *opts, f"hydra.run.dir={serial}", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    [dist_rec] = [json.loads(p.read_text()) for p in (run / "jobs").glob("*.json")]
    [ser_rec] = [json.loads(p.read_text()) for p in (serial / "jobs").glob("*.json")]
    for key in ("best_cost", "best_z", "history", "n_evals", "trace_best", "matrices",
                "status", "job_id"):
        assert dist_rec[key] == ser_rec[key], key
