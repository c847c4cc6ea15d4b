"""Plan jobs, run them (process pool or dask), one record file per finished job."""

from penaltyrun.runner.execute import BACKENDS, check_settings, execute, job_path, pending_jobs
from penaltyrun.runner.job import JOB_STATUSES, run_job
from penaltyrun.runner.plan import Job, config_hash, job_seed, plan_jobs
from penaltyrun.runner.setup import build, build_layout

__all__ = ["BACKENDS", "JOB_STATUSES", "Job", "build", "build_layout", "check_settings",
           "config_hash", "execute", "job_path", "job_seed", "pending_jobs", "plan_jobs", "run_job"]
