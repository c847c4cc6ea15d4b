"""Fixtures of the command-line tests: an external dask cluster on 127.0.0.1."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass

import pytest


@dataclass(frozen=True)
class DaskCluster:
    """A ``dask scheduler`` and its ``dask worker`` processes, each in a session of its own.

    Attributes
    ----------
    address : str
        The scheduler's ``tcp://127.0.0.1:port``.
    scheduler : subprocess.Popen
        The scheduler process.
    workers : list of subprocess.Popen
        The worker processes (one thread each, no nanny).
    """

    address: str
    scheduler: subprocess.Popen
    workers: list[subprocess.Popen]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(*args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_" + args[0],
                             *args[1:]], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)


@pytest.fixture
def dask_cluster() -> Iterator[DaskCluster]:
    """A scheduler and two workers, both connected before the test starts; every process
    still running at the end is killed (SIGKILL to its session). Skips without
    ``distributed``."""
    distributed = pytest.importorskip("distributed")
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [_start("scheduler", "--host", "127.0.0.1", "--port", str(port),
                    "--no-dashboard")]
    try:
        procs += [_start("worker", address, "--nthreads", "1", "--no-nanny",
                         "--no-dashboard") for _ in range(2)]
        with distributed.Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=120)
        yield DaskCluster(address, procs[0], procs[1:])
    finally:
        for proc in procs:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=10)
