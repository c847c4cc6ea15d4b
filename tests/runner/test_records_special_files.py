"""Job records are opened only as regular files: a FIFO or a link named like a record never
blocks a resume and is never followed."""

import os
import threading

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
