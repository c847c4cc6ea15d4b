"""Forecast of a run before it starts: evaluations per job, CPU hours and wall hours.

For one cell (problem, case, parameterization, optimizer settings) the forecast takes

* the evaluation budget of each job from the optimizer's settings
  (:func:`penaltyrun.optim.planned_evals`: swarm × iterations, population × generations,
  capped by ``max_evals``; an upper bound, since a stall rule may end a search earlier),
  plus the evaluations after the search: the best candidate's detailed evaluation and its
  held-out set (one per scenario, about the cost of a training evaluation);
* the CPU time of one evaluation, from timing a few batches of candidates drawn uniformly
  from the decision box (``time.process_time``, after one untimed warm-up evaluation that
  compiles or loads the kernels). Each batch has the optimizer's batch size (its swarm or
  population, :func:`optimizer_batch`), because that is how the run calls the problem:
  the per-call overhead (Python, decoding, an LQR gain's Riccati solve) is shared by the
  batch, so one candidate alone can cost several times its share in a large swarm. A
  batch is shrunk so that one timed call takes about :data:`BATCH_CALL_S` at most. Random
  candidates are the optimizer's first iteration; later candidates may be cheaper
  (converging transfers end early) or dearer, which is why the spread is printed with the
  mean;
* the wall time for a number of cores from the jobs' CPU times through a *wall model*:
  :func:`job_level_wall` (each job on one core, dispatched longest first, as the runner
  does). A model distributing one job's candidates over several cores (swarm level) can be
  added to :data:`WALL_MODELS` with the same signature.
"""

from __future__ import annotations

import heapq
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from penaltyrun import optim
from penaltyrun.optim.base import uniform_box
from penaltyrun.problems.hooks import hooks
from penaltyrun.runner import interrupts
from penaltyrun.runner.options import available_cores
from penaltyrun.runner.plan import Job, job_seed, warm_stage_budget
from penaltyrun.runner.setup import build, build_layout

logger = logging.getLogger(__name__)

#: Cluster sizes every forecast also reports (cores, one job per core).
CLUSTER_CORES = (64, 512)
#: CPU seconds one timed batch may take at most (the batch is shrunk for slow problems).
BATCH_CALL_S = 1.0

#: Wall model: (CPU seconds of each job, cores) → wall seconds.
WallModel = Callable[[Sequence[float], int], float]


def job_level_wall(job_cpu_s: Sequence[float], cores: int) -> float:
    """Wall time of jobs run whole, one per core, longest first (s).

    Simulates the dispatch of :func:`penaltyrun.runner.execute`: the jobs sorted longest
    first, each given to the first core that falls free. Jobs cannot be split, so this is
    at least :func:`wall_bound` (and within 4/3 of the best schedule).

    Parameters
    ----------
    job_cpu_s : sequence of float
        CPU time of each job (s), one core each.
    cores : int
        Cores (worker processes), ≥ 1.
    """
    if cores < 1:
        raise ValueError(f"cores must be ≥ 1, got {cores}")
    free = [0.0] * min(cores, max(1, len(job_cpu_s)))
    for cpu in sorted(job_cpu_s, reverse=True):
        heapq.heappush(free, heapq.heappop(free) + float(cpu))
    return max(free)


def wall_bound(job_cpu_s: Sequence[float], cores: int) -> float:
    """Lower bound of any job-level schedule: max(longest job, total / cores) (s)."""
    if not job_cpu_s:
        return 0.0
    return max(max(job_cpu_s), sum(job_cpu_s) / cores)


#: Wall models by name; issue 15 (swarm-level distribution) adds its own here.
WALL_MODELS: dict[str, WallModel] = {"job": job_level_wall}


@dataclass(frozen=True)
class Timing:
    """CPU time per evaluation of random candidates of the box, timed in batches.

    Attributes
    ----------
    samples_s : tuple of float
        CPU time per evaluation of each timed batch (the batch's time over its size) (s).
    warmup_s : float
        CPU time of the untimed first evaluation (compiling or loading kernels) (s).
    error : str
        Why no timing is available ("" if it is).
    batch : int
        Candidates per timed batch.
    """

    samples_s: tuple[float, ...] = ()
    warmup_s: float = float("nan")
    error: str = ""
    batch: int = 1

    @property
    def mean_s(self) -> float | None:
        """Mean CPU time of one evaluation (s), or None without samples."""
        return float(np.mean(self.samples_s)) if self.samples_s else None

    def describe(self) -> str:
        """``0.21 s (8 batches of 30: min 0.05, median 0.2, max 0.9)``."""
        if not self.samples_s:
            return self.error or "not timed"
        s = np.asarray(self.samples_s)
        what = "candidates" if self.batch == 1 else f"batches of {self.batch}"
        return (f"{s.mean():.3g} s ({s.size} {what}: min {s.min():.3g}, median "
                f"{np.median(s):.3g}, max {s.max():.3g})")


def optimizer_batch(settings: Any, dim: int) -> int:
    """Candidates the optimizer of ``settings`` passes to the problem per call (≥ 1): its
    settings' own ``batch_size`` (swarm size of ``pso`` and ``pso_matlab``, population of
    ``cmaes`` and ``de``, 1 for the others)."""
    return max(1, int(settings.batch_size(dim)))


def time_candidates(problem: Any, layout: Any, n: int, seed: int, batch: int = 1) -> Timing:
    """Time ``n`` batches of random candidates of ``layout``'s box on ``problem``.

    Parameters
    ----------
    problem : Problem
    layout : DecisionLayout
    n : int
        Batches timed (after one untimed warm-up candidate); 0 returns no timing.
    seed : int
        Seed of the candidates.
    batch : int
        Candidates per call (the optimizer's batch size); shrunk so that one call takes
        about :data:`BATCH_CALL_S` at most, judged from one candidate timed alone.

    Returns
    -------
    Timing
        ``samples_s`` are per-evaluation times (a batch's CPU time over its size). A
        candidate that raises ends the timing with ``error`` set (the run records such
        failures itself; the forecast never stops a run).
    """
    if n <= 0:
        return Timing(error="not timed (runner.forecast_samples=0)")
    lb, ub = layout.bounds()
    rng = np.random.default_rng(seed)

    def per_eval(Z: np.ndarray) -> float:
        mats, scalars = layout.split(Z)
        t0 = time.process_time()
        problem.evaluate_batch(mats, scalars or None)
        return (time.process_time() - t0) / Z.shape[0]

    try:
        warm = per_eval(uniform_box(rng, lb, ub, 1))
        if batch > 1:
            alone = per_eval(uniform_box(rng, lb, ub, 1))
            batch = max(1, min(batch, int(BATCH_CALL_S / max(alone, 1e-9))))
        return Timing(tuple(per_eval(uniform_box(rng, lb, ub, batch)) for _ in range(n)),
                      warm, batch=batch)
    except Exception as exc:  # reported in the forecast; the run itself records failures
        interrupts.reraise_run_signal(exc)
        return Timing(error=f"timing failed: {type(exc).__name__}: {exc}")


def warm_gradient(problem: Any, layout: Any, seed: int) -> None:
    """One untimed exact gradient at a random candidate of ``layout``'s box: loads the
    gradient's compiled kernels (the maps' Jacobians) here, before the workers are forked,
    as the timed evaluations do for the cost, so that no job's CPU trace pays for them. A
    failure is left to the jobs, which record it."""
    from penaltyrun.optim.gradient import z_gradient

    lb, ub = layout.bounds()
    try:
        z_gradient(problem, layout, uniform_box(np.random.default_rng(seed), lb, ub, 1)[0])
    except Exception as exc:  # the run records failures itself; the forecast never stops it
        interrupts.reraise_run_signal(exc)
        logger.debug("gradient warm-up failed: %s: %s", type(exc).__name__, exc)


def extra_evals(problem: Any, holdout: bool) -> int:
    """Evaluations after the search: the best candidate's detail (1) plus, with
    ``holdout``, one per held-out scenario of ``problem`` (0 if it has none)."""
    return 1 + (hooks(problem).n_holdout() if holdout else 0)


def job_evals(job: Job, problem: Any, settings: Any, dim: int) -> int | None:
    """Most evaluations the search of ``job`` can spend (``None``: nothing bounds it).

    A warm-started job spends its diagonal stage and full stage within ``max_evals``.
    """
    if not job.warm_start_share or settings.max_evals is None:
        return optim.planned_evals(settings, dim)
    diag_dim = build_layout(problem, "diagonal", job.param_options).dim
    diag_cap = warm_stage_budget(job.warm_start_share, settings.max_evals)
    diag = optim.planned_evals(replace(settings, max_evals=diag_cap), diag_dim)
    full = optim.planned_evals(settings, dim)
    return min(settings.max_evals, (diag or diag_cap) + (full or settings.max_evals))


@dataclass(frozen=True)
class CellForecast:
    """Forecast of the jobs of one cell.

    Attributes
    ----------
    label : str
        ``problem/case/param/optimizer``.
    jobs : tuple of Job
    evals : int or None
        Search evaluations per job, at most (``None``: no bound).
    extra : int
        Evaluations per job after the search (detail, held-out set).
    timing : Timing
    """

    label: str
    jobs: tuple[Job, ...]
    evals: int | None
    extra: int
    timing: Timing

    @property
    def job_cpu_s(self) -> float | None:
        """Expected CPU time of one job (s), or None (no bound or no timing)."""
        mean = self.timing.mean_s
        if self.evals is None or mean is None:
            return None
        return (self.evals + self.extra) * mean

    @property
    def total_evals(self) -> int | None:
        """Evaluations of all the cell's jobs, at most."""
        return None if self.evals is None else len(self.jobs) * (self.evals + self.extra)

    def expected_s(self) -> dict[str, float]:
        """``job_id`` → expected CPU time (s), for longest-first dispatch."""
        cpu = self.job_cpu_s
        return {} if cpu is None else {job.job_id: cpu for job in self.jobs}


def forecast_cell(jobs: Sequence[Job], samples: int, root_seed: int = 0,
                  timing: Timing | None = None) -> CellForecast:
    """Forecast the jobs of one cell (they share problem, case, map and optimizer).

    Parameters
    ----------
    jobs : sequence of Job
        The cell's jobs (non-empty).
    samples : int
        Random candidates to time (0: budgets only).
    root_seed : int
        Root seed; the candidates' seed derives from it and the cell.
    timing : Timing, optional
        A timing already measured for the same problem, case and map (not measured again).
    """
    job = jobs[0]
    problem, layout, settings = build(job.problem, job.case, job.problem_params, job.param,
                                      job.param_options, job.optimizer,
                                      job.optimizer_options, job.problem_module or None)
    label = f"{job.problem}/{job.case}/{job.param}/{job.optimizer}"
    if timing is None:
        timing = time_candidates(problem, layout, samples,
                                 job_seed(root_seed, f"forecast/{label}"),
                                 optimizer_batch(settings, layout.dim))
    if samples > 0 and settings.uses_gradient:
        warm_gradient(problem, layout, job_seed(root_seed, f"forecast-gradient/{label}"))
    return CellForecast(label, tuple(jobs), job_evals(job, problem, settings, layout.dim),
                        extra_evals(problem, job.holdout), timing)


def hours(seconds: float | None, days: bool = True) -> str:
    """``12.3 h`` (``(31.2 d)`` added from 48 h with ``days``); below 0.1 h in minutes or
    seconds; ``?`` for None."""
    if seconds is None or not math.isfinite(seconds):
        return "?"
    h = seconds / 3600.0
    if h < 0.1:
        return f"{seconds / 60:.2g} min" if seconds >= 60 else f"{seconds:.2g} s"
    text = f"{h:.3g} h" if h < 1000 else f"{h:,.0f} h"
    return text + (f" ({h / 24:.1f} d)" if days and h >= 48 else "")


def summary_lines(cell: CellForecast, workers: int | None,
                  model: WallModel = job_level_wall) -> list[str]:
    """The forecast of one run as log lines (jobs and budget, timing, CPU and wall hours).

    Parameters
    ----------
    cell : CellForecast
    workers : int or None
        Worker processes on this machine (``None``: a remote dask cluster of unknown size).
    model : callable
        Wall model (see :data:`WALL_MODELS`).
    """
    n = len(cell.jobs)
    evals = "no bound (set optimizer.max_evals)" if cell.evals is None else \
        f"≤ {cell.evals:,} evaluations + {cell.extra} after the search (detail, held-out set)"
    lines = [f"forecast: {n} jobs × {evals}",
             f"forecast: CPU per evaluation {cell.timing.describe()}; untimed first "
             f"evaluation (compiling or loading kernels) {cell.timing.warmup_s:.3g} s"]
    cpu = cell.job_cpu_s
    if cpu is None:
        lines.append("forecast: no CPU estimate without a bound and a timing")
        return lines
    cpus = [cpu] * n
    here = "" if workers is None else \
        f", wall ≈ {hours(model(cpus, local_slots(workers)))} on {workers} workers"
    clusters = ", ".join(f"{c} cores {hours(model(cpus, c))}" for c in CLUSTER_CORES)
    lines.append(f"forecast: ≈ {hours(cpu * n)} CPU{here}; one job per core: {clusters}")
    return lines


def local_slots(workers: int) -> int:
    """Jobs that really run at once with ``workers`` processes on this machine's cores."""
    return max(1, min(int(workers), available_cores()))


def _forecast_lines(jobs: Sequence[Job], samples: int, root_seed: int,
                    workers: int | None) -> tuple[list[str], dict[str, float]]:
    """The forecast's log lines and the jobs' expected CPU times (s)."""
    cell = forecast_cell(jobs, samples, root_seed)
    return list(summary_lines(cell, workers)), cell.expected_s()


def log_forecast(jobs: Sequence[Job], samples: int, root_seed: int,
                 workers: int | None, time_limit_s: float | None = None) -> dict[str, float]:
    """Log the forecast of a run's jobs (one cell) and return their expected CPU times.

    The forecast is advice: when it fails, one warning says why and the run goes on.

    Parameters
    ----------
    jobs : sequence of Job
    samples : int
        Random candidates to time (0: no forecast).
    root_seed : int
    workers : int, optional
        Cores of the wall-time line (``None``: unknown).
    time_limit_s : float, optional
        ``runner.job_timeout`` (s): the sample evaluations then run in a process of their
        own, killed after this many seconds (a problem that hangs, or ends its process,
        costs the forecast only). ``None``: in this process, without a limit.

    Returns
    -------
    dict
        ``job_id`` → expected CPU time (s); empty when ``samples`` is 0, jobs is empty or
        the forecast failed.
    """
    if samples <= 0 or not jobs:
        return {}
    from penaltyrun.runner import isolated

    args = (list(jobs), samples, root_seed, workers)
    try:
        if time_limit_s is not None and isolated.can_isolate():
            lines, expected = isolated.call_isolated(_forecast_lines, args, time_limit_s,
                                                     "runner.job_timeout")
        else:
            with interrupts.sigint_marked():  # told apart while the marking holds
                try:
                    lines, expected = _forecast_lines(*args)
                except (KeyboardInterrupt, SystemExit) as exc:
                    if not interrupts.raised_by_job(exc):  # a Ctrl-C or SIGTERM of the run
                        raise
                    logger.warning("forecast: not available (%s raised by the problem's "
                                   "code)", type(exc).__name__)
                    return {}
    except isolated.IsolatedCallError as exc:
        logger.warning("forecast: not available (sample evaluations in a process of their "
                       "own: %s)", exc)
        return {}
    except Exception as exc:  # the forecast is advice: it never stops a run
        interrupts.reraise_run_signal(exc)
        logger.warning("forecast: not available (%s: %s)", type(exc).__name__, exc)
        return {}
    for line in lines:
        logger.info("%s", line)
    return expected
