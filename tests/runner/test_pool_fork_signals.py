"""A worker forked while the main process has its own signal handlers never runs them.

The command line turns SIGTERM into an exception (``install_signal_handlers``). A forked
worker inherits that handler; the pool stops workers at any moment, also one forked an
instant before. Unless the signal is blocked across the fork, the handler can raise in the
new child before multiprocessing's guard that ends it, and the child then goes on running
the main process's code (a second runner; under pytest a second test session)."""

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from penaltyrun.runner import pool

ROOT = Path(__file__).resolve().parents[2]

#: Fork a worker and stop it at once, ``n`` times, with the command line's handlers set;
#: every process that gets past the loop prints its pid and the workers' exit codes.
STOP_AT_ONCE = textwrap.dedent("""
    import json, multiprocessing as mp, os, sys
    from penaltyrun.cli import install_signal_handlers
    from penaltyrun.runner.pool import _Worker

    def noop(job):
        return {}

    install_signal_handlers()
    ctx = mp.get_context("fork")
    codes = []
    for _ in range(int(sys.argv[1])):
        worker = _Worker(ctx, noop, 0.05)
        worker.stop()
        codes.append(worker.proc.exitcode)
    print(json.dumps({"pid": os.getpid(), "codes": codes}), flush=True)
""")


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask") or sys.platform == "win32",
                    reason="POSIX fork and signal masks")
def test_a_worker_stopped_right_after_its_fork_just_ends(tmp_path):
    n = 150
    proc = subprocess.run([sys.executable, "-c", STOP_AT_ONCE, str(n)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0, proc.stderr
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(lines) == 1, "a forked worker went on running the main process's loop"
    assert lines[0]["codes"] == [-signal.SIGTERM] * n  # ended by the signal, nothing raised
    assert "Traceback" not in proc.stderr and "Exception ignored" not in proc.stderr


def test_starting_a_worker_leaves_the_main_process_signal_mask_as_it_was():
    if not hasattr(signal, "pthread_sigmask"):
        pytest.skip("no signal masks on this platform")
    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    worker = pool._Worker(pool.mp.get_context(), lambda job: {}, 0.05)
    try:
        assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before
        assert worker.proc.is_alive()
    finally:
        worker.stop()


def test_signals_blocked_delivers_a_signal_sent_meanwhile_afterwards():
    if not hasattr(signal, "pthread_sigmask"):
        pytest.skip("no signal masks on this platform")
    seen = []
    old = signal.signal(signal.SIGHUP, lambda signum, frame: seen.append(signum))
    try:
        with pool.signals_blocked((signal.SIGHUP,)):
            signal.raise_signal(signal.SIGHUP)
            assert seen == []
        assert seen == [signal.SIGHUP]
    finally:
        signal.signal(signal.SIGHUP, old)
