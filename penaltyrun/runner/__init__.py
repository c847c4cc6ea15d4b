"""Plan jobs, run them (process pool or dask), one record file per finished job."""

from penaltyrun.runner.execute import BACKENDS, check_settings, execute
from penaltyrun.runner.forecast import forecast_cell, log_forecast
from penaltyrun.runner.job import JOB_STATUSES, run_job
from penaltyrun.runner.options import check_runner_options
from penaltyrun.runner.plan import Job, config_hash, job_seed, plan_jobs
from penaltyrun.runner.records import job_path, pending_jobs, read_record
from penaltyrun.runner.setup import build, build_layout

__all__ = ["BACKENDS", "JOB_STATUSES", "Job", "build", "build_layout", "check_runner_options",
           "check_settings", "config_hash", "execute", "forecast_cell", "job_path", "job_seed",
           "log_forecast", "pending_jobs", "plan_jobs", "read_record", "run_job"]
