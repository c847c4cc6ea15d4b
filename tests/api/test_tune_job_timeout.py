"""``job_timeout`` (``runner.job_timeout``): a job that hangs is killed and recorded
``timeout``, the other jobs finish, and a resume with ``retry_failed`` runs it again."""

import json
import os
import time
from types import SimpleNamespace

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.runner.options import check_runner_options
from penaltyrun.runner.records import pending_jobs


def _hangs_once(flag):
    """Cost whose first call (in any process) sleeps for an hour."""
    def cost(K):
        try:
            os.close(os.open(flag, os.O_CREAT | os.O_EXCL))
        except FileExistsError:
            return float(np.trace(K))
        time.sleep(3600)
        return 0.0

    return cost


def test_a_hanging_job_costs_that_job_only_and_is_retried_on_resume(tmp_path):
    prob = penaltyrun.from_cost(_hangs_once(str(tmp_path / "flag")), {"K": (2, (0.1, 10.0))},
                                name="hangs")
    t0 = time.monotonic()
    res = penaltyrun.tune(prob, param="diagonal", optimizer="baseline", n_starts=3,
                          workers=1, job_timeout=1.5, run_dir=tmp_path / "run")
    assert time.monotonic() - t0 < 30  # nothing hangs
    df = res.records.sort_values("start")
    assert sorted(df["status"]) == ["ok", "ok", "timeout"]
    hung = df[df["status"] == "timeout"].iloc[0]
    assert hung["error"].startswith("JobTimeout: ") and np.isnan(hung["best_cost"])
    assert res.best.cost == pytest.approx(float(df["best_cost"].min()))

    report = res.report(tmp_path / "report") / "report.md"
    text = report.read_text(encoding="utf-8")
    assert f"- {hung['job_id']} (timeout): JobTimeout: " in text.split("## Failed jobs")[1]
    summary = res.summary()
    assert summary["n_starts"].tolist() == [3]
    assert summary["converged"].tolist() == [pytest.approx(2 / 3)]

    planned = [SimpleNamespace(  # the jobs as planned: what their records say of them
        job_id=r["job_id"], module_hash="", meta={}, problem=r["problem"], case=r["case"],
        param=r["param"], optimizer=r["optimizer"], start=r["start"], seed=r["seed"],
        optimizer_options=json.loads(r["optimizer_settings"]),
        problem_params=json.loads(r["problem_params"]),
        param_options=json.loads(r["param_options"])) for r in df.to_dict("records")]
    assert pending_jobs(planned, res.run_dir, resume=True) == []
    again = pending_jobs(planned, res.run_dir, resume=True, retry_failed=True)
    assert [job.job_id for job in again] == [hung["job_id"]]


@pytest.mark.parametrize("options, fragment", [
    ({"job_timeout": 0}, "null (no limit) or a positive number of seconds"),
    ({"job_timeout": "1h"}, "null (no limit) or a positive number of seconds"),
    ({"job_timeout": 60, "backend": "dask"}, "local process pool only"),
])
def test_bad_job_timeout_is_one_config_error(options, fragment):
    with pytest.raises(ConfigError, match="runner.job_timeout") as info:
        check_runner_options(options, connect=False)
    assert fragment in str(info.value)


def test_no_limit_and_a_limit_pass():
    check_runner_options({"job_timeout": None}, connect=False)
    check_runner_options({"job_timeout": 0.5, "backend": "local"}, connect=False)
