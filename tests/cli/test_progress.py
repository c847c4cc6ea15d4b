"""Progress over jobs: a tqdm bar on a terminal, plain log lines elsewhere."""

import fcntl
import io
import os
import select
import struct
import subprocess
import sys
import termios

import pytest

from penaltyrun.cli import progress
from penaltyrun.errors import ConfigError

RUN = ["runner.n_starts=2", "optimizer.n_particles=4", "optimizer.iters=2",
       "runner.report=false"]


def test_bar_counts_jobs_with_eta_and_statuses():
    out = io.StringIO()
    with progress.job_bar(5, initial=2, enabled=True, file=out) as on_record:
        for status in ("ok", "diverged", "ok"):
            on_record({"status": status})
    text = out.getvalue()
    assert "5/5" in text and "jobs" in text and "ok=2" in text and "diverged=1" in text
    assert "<" in text  # elapsed<remaining: the ETA


def test_bar_eta_is_the_dispatchs_given_the_workers(monkeypatch):
    """4 jobs of 30 s on 2 workers: after the first one, 30 s are left (tqdm's rate would
    say 90 s: one job per 30 s)."""
    def bar_after(n_records):  # the bar as drawn last (on closing)
        clock = iter([0.0, 30.0, 30.0, 60.0, 60.0])
        monkeypatch.setattr(progress.time, "perf_counter", lambda: next(clock))
        out = io.StringIO()
        with progress.job_bar(4, enabled=True, file=out, workers=2) as on_record:
            for _ in range(n_records):
                on_record({"status": "ok", "wall_time_s": 30.0})
        return out.getvalue().split("\r")[-1]

    first = bar_after(1)
    assert "1/4" in first and "ETA=00:30" in first and "<" not in first
    assert "ETA=00:00" in bar_after(4)


def test_slots_from_runner_settings():
    assert progress.slots({"workers": 2}, 10) == 2
    assert progress.slots({"workers": 2}, 1) == 1
    assert progress.slots({"workers": 3, "backend": "dask", "scheduler": "tcp://h:1"},
                          10) is None


def test_no_bar_when_disabled_or_nothing_to_do():
    with progress.job_bar(3, enabled=False) as on_record:
        assert on_record is None
    with progress.job_bar(3, initial=3, enabled=True) as on_record:
        assert on_record is None


def test_wanted():
    assert progress.wanted("auto", io.StringIO()) is False
    assert progress.wanted(True) and not progress.wanted(False)
    with pytest.raises(ConfigError, match="runner.progress"):
        progress.wanted("sometimes")


def test_pipe_gets_log_lines_and_no_bar(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", *RUN,
                           f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    logs = proc.stdout + proc.stderr
    assert "[2/2]" in logs and "ETA" in logs
    assert "job/s" not in logs and "s/job" not in logs


def test_terminal_gets_the_bar(tmp_path):
    main, sub = os.openpty()
    fcntl.ioctl(sub, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 120, 0, 0))  # a real size
    proc = subprocess.Popen([sys.executable, "-m", "penaltyrun.cli", *RUN,
                             f"hydra.run.dir={tmp_path / 'run'}"], cwd=tmp_path,
                            stdin=sub, stdout=sub, stderr=sub)
    os.close(sub)
    chunks = []
    while True:
        ready, _, _ = select.select([main], [], [], 300)
        if not ready:
            break
        try:
            data = os.read(main, 4096)
        except OSError:  # the terminal closes when the child exits
            break
        if not data:
            break
        chunks.append(data)
    assert proc.wait(timeout=60) == 0
    os.close(main)
    text = b"".join(chunks).decode(errors="replace")
    assert "jobs: 100%" in text and "2/2" in text, text
    assert "[2/2]" in text  # the log lines still come, above the bar
