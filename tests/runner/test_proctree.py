"""The process tree below a process (Linux /proc): found, stopped and killed, a process in
a session of its own included."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from penaltyrun.runner import proctree

pytestmark = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")

TREE = """
import os, subprocess, sys, time
child = subprocess.Popen(["sleep", "60"], start_new_session=True)
print(child.pid, flush=True)
time.sleep(60)
"""


def _state(pid: int) -> str | None:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


def test_the_tree_below_a_process_is_found_stopped_and_killed():
    top = subprocess.Popen([sys.executable, "-c", TREE], stdout=subprocess.PIPE, text=True)
    try:
        grandchild = int(top.stdout.readline())
        below = proctree.descendants(top.pid)
        assert grandchild in below  # in a session of its own, still below
        assert proctree.descendants(grandchild) == []
        fds = proctree.freeze_descendants(top.pid)
        assert len(fds) == len(below)
        deadline = time.monotonic() + 10  # a signal is delivered asynchronously
        while _state(grandchild) not in ("T", "t") and time.monotonic() < deadline:
            time.sleep(0.01)
        assert _state(grandchild) in ("T", "t")
        proctree.kill(fds)
        deadline = time.monotonic() + 10
        while _state(grandchild) not in (None, "Z") and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _state(grandchild) in (None, "Z")
        assert top.poll() is None  # the process itself is left to its owner
    finally:
        top.kill()
        top.wait()
    assert proctree.freeze_descendants(top.pid) == []  # nothing below a process that ended
