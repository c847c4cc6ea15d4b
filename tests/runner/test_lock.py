"""One run per run directory: flock held by a process, released by the OS at its death."""

import subprocess
import sys
import textwrap

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.runner import lock

HOLD = textwrap.dedent("""
    import sys, time
    from penaltyrun.runner import lock
    lock.acquire(sys.argv[1])
    print("locked", flush=True)
    time.sleep(120)
""")


def test_second_process_is_refused_and_a_dead_holder_never_blocks(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", HOLD, str(tmp_path)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        assert lock.is_locked(tmp_path)
        with pytest.raises(ConfigError, match=rf"in use by another penaltyrun run \(pid "
                                              rf"{holder.pid}, started 20"):
            lock.acquire(tmp_path)
        with pytest.raises(ConfigError, match="hydra.run.dir"):
            lock.check_not_locked(tmp_path)
    finally:
        holder.kill()
        holder.wait()
    assert (tmp_path / lock.LOCK_FILE).exists()  # stale file of a dead process ...
    assert not lock.is_locked(tmp_path)
    lock.acquire(tmp_path)  # ... blocks nothing
    try:
        lock.acquire(tmp_path)  # re-entrant within one process
        assert lock.holder(tmp_path)["pid"] != holder.pid
    finally:
        lock.release(tmp_path)
    assert not lock.is_locked(tmp_path)
