"""Plan jobs, run them (process pool or dask), one record file per finished job.

The names below are imported on first use, so that a light module of this package (record
checks, the run lock) can be used without importing the optimizers and problems.
"""

from __future__ import annotations

from penaltyrun import lazy

_NAMES = {
    "BACKENDS": "options", "execute": "executor", "SERIAL": "executor",
    "forecast_cell": "forecast", "log_forecast": "forecast",
    "JOB_STATUSES": "validate", "NO_RESULT_STATUSES": "validate", "run_job": "job",
    "check_runner_options": "options", "check_report_options": "options",
    "Job": "plan", "config_hash": "plan", "job_seed": "plan", "plan_jobs": "plan",
    "module_source_hash": "usercode", "user_code_hash": "usercode",
    "job_path": "records", "pending_jobs": "records", "read_record": "records",
    "build": "setup", "build_layout": "setup",
    "RunSpec": "spec", "RunnerOptions": "spec",
}

__all__ = sorted(_NAMES)

__getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())
