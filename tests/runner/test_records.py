"""Job records: atomic writes, unreadable records moved aside on resume."""

import json

from penaltyrun.runner import pending_jobs, plan_jobs, read_record
from penaltyrun.runner.records import CORRUPT_DIR, JOBS_DIR, job_path, write_record


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n, 1, {}, {}, {}, {})


def test_write_is_atomic_and_readable(tmp_path):
    job = _jobs(1)[0]
    path = write_record(tmp_path, job, {"job_id": job.job_id, "status": "ok"})
    assert read_record(path) == {"job_id": job.job_id, "status": "ok"}
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporary file left


def test_unreadable_records_are_moved_aside_and_rerun(tmp_path, caplog):
    jobs = _jobs(4)
    for job in jobs:
        write_record(tmp_path, job, {"job_id": job.job_id, "status": "ok"})
    truncated = job_path(tmp_path, jobs[0])
    truncated.write_text(truncated.read_text()[:10])
    job_path(tmp_path, jobs[1]).write_bytes(b"\x00\xff garbage")
    job_path(tmp_path, jobs[2]).write_text(json.dumps([1, 2]))  # JSON, but not a record
    todo = pending_jobs(jobs, tmp_path, resume=True, retry_failed=True)
    assert [j.job_id for j in todo] == [j.job_id for j in jobs[:3]]
    corrupt = sorted(p.name for p in (tmp_path / JOBS_DIR / CORRUPT_DIR).iterdir())
    assert len(corrupt) == 3 and corrupt[0].startswith(jobs[0].job_id)
    assert str(truncated) in caplog.text and "unreadable" in caplog.text
    assert not truncated.exists()
    # a second resume finds nothing corrupt any more
    assert pending_jobs(jobs, tmp_path, resume=True) == todo
