"""Job records: atomic writes, unreadable records moved aside on resume."""

import json

import numpy as np

from penaltyrun.runner import pending_jobs, plan_jobs, read_record
from penaltyrun.runner.records import CORRUPT_DIR, JOBS_DIR, job_path, write_record
from penaltyrun.runner.validate import SCHEMA_VERSION


def _jobs(n):
    return plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=n, root_seed=1)


def _record(job, **fields):
    """A minimal valid record of ``job``."""
    return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
            "param": job.param, "optimizer": job.optimizer, "start": job.start,
            "seed": job.seed, "status": "ok", "best_cost": 1.0, **fields}


def test_write_is_atomic_and_readable(tmp_path):
    job = _jobs(1)[0]
    path = write_record(tmp_path, job, _record(job))
    back = read_record(path)
    assert {k: back[k] for k in _record(job)} == _record(job)
    assert back["schema_version"] == SCHEMA_VERSION
    assert json.loads(back["packages"])["numpy"] == np.__version__
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporary file left


def test_unreadable_records_are_moved_aside_and_rerun(tmp_path, caplog):
    jobs = _jobs(4)
    for job in jobs:
        write_record(tmp_path, job, _record(job))
    truncated = job_path(tmp_path, jobs[0])
    truncated.write_text(truncated.read_text()[:10])
    job_path(tmp_path, jobs[1]).write_bytes(b"\x00\xff garbage")
    job_path(tmp_path, jobs[2]).write_text(json.dumps([1, 2]))  # JSON, but not a record
    todo = pending_jobs(jobs, tmp_path, resume=True, retry_failed=True)
    assert [j.job_id for j in todo] == [j.job_id for j in jobs[:3]]
    corrupt = sorted(p.name for p in (tmp_path / JOBS_DIR / CORRUPT_DIR).iterdir())
    assert len(corrupt) == 3 and corrupt[0].startswith(jobs[0].job_id)
    assert str(truncated) in caplog.text and "unreadable" in caplog.text
    assert "not a JSON object" in caplog.text
    assert not truncated.exists()
    # a second resume finds nothing corrupt any more
    assert pending_jobs(jobs, tmp_path, resume=True) == todo


def test_a_record_nested_too_deep_for_the_json_parser_is_unreadable(tmp_path):
    from penaltyrun.runner.records import load_record

    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    record, why = load_record(path)
    assert record is None and why.startswith("unreadable (maximum recursion depth")


def test_a_record_that_is_not_its_jobs_own_is_moved_aside_and_rerun(tmp_path, caplog):
    """Named after the job and valid, but its seed, start or settings are another job's
    (edited by hand, or copied from another configuration and renamed): not reused."""
    jobs = _jobs(4)
    edits = [{"seed": 12345}, {"start": 3},
             {"optimizer_settings": {**jobs[2].optimizer_options, "max_evals": 400}}, {}]
    for job, edit in zip(jobs, edits):
        write_record(tmp_path, job, {**_record(job),
                                     "optimizer_settings": job.optimizer_options, **edit})
    todo = pending_jobs(jobs, tmp_path, resume=True)
    assert [j.job_id for j in todo] == [j.job_id for j in jobs[:3]]
    for words in ("its seed 12345 is not the job's", "its start 3 is not the job's",
                  "its optimizer_settings"):
        assert words in caplog.text
    assert len(list((tmp_path / JOBS_DIR / CORRUPT_DIR).iterdir())) == 3
