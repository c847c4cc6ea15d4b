"""Job records are opened only as regular files: a FIFO or a link named like a record never
blocks a resume and is never followed."""

import os
import threading

import pytest

from penaltyrun.runner import pending_jobs, plan_jobs
from penaltyrun.runner.records import CORRUPT_DIR, job_path, load_record, write_record


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=n, root_seed=1)


def _record(job):
    return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
            "param": job.param, "optimizer": job.optimizer, "start": job.start,
            "seed": job.seed, "status": "ok", "best_cost": 1.0}


def test_f19_a_fifo_named_like_a_record_is_moved_aside_without_blocking(tmp_path, caplog):
    jobs = _jobs(2)
    write_record(tmp_path, jobs[0], _record(jobs[0]))
    fifo = job_path(tmp_path, jobs[1])
    os.mkfifo(fifo)
    result = {}
    worker = threading.Thread(target=lambda: result.setdefault(
        "todo", pending_jobs(jobs, tmp_path, resume=True)), daemon=True)
    worker.start()
    worker.join(10)
    assert not worker.is_alive(), "resume blocked on a FIFO"
    assert [j.job_id for j in result["todo"]] == [jobs[1].job_id]
    assert not fifo.exists() and len(list((fifo.parent / CORRUPT_DIR).iterdir())) == 1
    assert "not a regular file" in caplog.text and str(fifo) in caplog.text


def test_a_record_that_is_a_link_is_not_followed(tmp_path):
    job = _jobs(1)[0]
    elsewhere = tmp_path / "elsewhere.json"
    elsewhere.write_text('{"secret": 1}', encoding="utf-8")
    path = job_path(tmp_path, job)
    path.parent.mkdir(parents=True)
    path.symlink_to(elsewhere)
    record, reason = load_record(path)
    assert record is None and "symbolic link" in reason
    assert [j.job_id for j in pending_jobs([job], tmp_path, resume=True)] == [job.job_id]
    assert elsewhere.read_text(encoding="utf-8") == '{"secret": 1}'


def test_s7_an_atomic_write_never_follows_a_link_planted_at_its_temporary_name(tmp_path):
    """The temporary name of an atomic write is predictable (``.<name>.<pid>.tmp``): a link
    planted there is removed, never written through."""
    import pyarrow as pa

    from penaltyrun.io.schema import write_table_atomic
    from penaltyrun.runner.records import write_text_atomic

    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    run = tmp_path / "run"
    run.mkdir()
    for name in ("results.parquet", "record.json"):
        (run / f".{name}.{os.getpid()}.tmp").symlink_to(victim)
    write_table_atomic(pa.table({"x": [1]}), run / "results.parquet")
    write_text_atomic(run / "record.json", "{}")
    assert victim.read_text() == "precious"
    assert (run / "record.json").read_text() == "{}" and not list(run.glob(".*.tmp"))


def test_s7_an_unusable_record_is_never_moved_through_a_linked_corrupt_folder(tmp_path):
    from penaltyrun.errors import EnvironmentProblemError
    from penaltyrun.runner.records import CORRUPT_DIR, quarantine

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    jobs = tmp_path / "run" / "jobs"
    jobs.mkdir(parents=True)
    (jobs / CORRUPT_DIR).symlink_to(elsewhere, target_is_directory=True)
    record = jobs / "a.json"
    record.write_text("{")
    with pytest.raises(EnvironmentProblemError, match="symbolic link or not a folder"):
        quarantine(record)
    assert record.exists() and not list(elsewhere.iterdir())


def test_a_file_larger_than_any_record_is_never_read(tmp_path):
    """A sparse file of gigabytes (no disk space, all of it memory if read) named like a
    record: refused from its size, without reading it."""
    from penaltyrun.runner import records

    path = tmp_path / "huge.json"
    with open(path, "wb") as fh:
        fh.truncate(records.MAX_RECORD_BYTES + 1)
    record, why = load_record(path)
    assert record is None and "more than a job record holds" in why
