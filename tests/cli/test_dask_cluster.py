"""Item 8: the dask backend against an external ``dask scheduler`` with two ``dask worker``
processes on 127.0.0.1, one of them killed mid-run; then the last worker killed."""

import time

import pandas as pd
import pytest
from cli_subprocess import SLOW_JOBS, popen, records, wait_for_records

from penaltyrun.io import RESULTS_FILE

pytest.importorskip("distributed")


@pytest.mark.slow
def test_external_cluster_survives_a_killed_worker_then_times_out(tmp_path, dask_cluster):
    address, workers = dask_cluster.address, dask_cluster.workers
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
