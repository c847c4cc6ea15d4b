"""Run one job and turn it into one flat record (never raises)."""

from __future__ import annotations

import logging
import sys
import time
import traceback
from dataclasses import replace
from datetime import datetime, timezone
from functools import partial
from typing import Any

import numpy as np

from penaltyrun import optim
from penaltyrun.jobrecord import DIVERGED, FAILED, OK, warm_stop
from penaltyrun.optim.gradient import first_order, z_gradient
from penaltyrun.problems import diagnostics
from penaltyrun.problems.base import CUTOFF_STATUS, gradient_support
from penaltyrun.runner import interrupts
from penaltyrun.runner.plan import Job, warm_stage_budget
from penaltyrun.runner.setup import build, build_layout
from penaltyrun.runner.swarm import LocalEvaluation

__all__ = ["HEARTBEAT_S", "Heartbeat", "run_job"]

logger = logging.getLogger(__name__)

#: Seconds between the progress lines of a long job (see :class:`Heartbeat`).
HEARTBEAT_S = 60.0
#: BLAS threads while a job runs. The runner already runs one job per core, and the
#: matrices are small (at most tens of rows): a multithreaded BLAS there only spins. Measured
#: on 2 shared cores: one 27 × 27 ``eigh`` (CMA-ES, every generation) cost 3.4 ms of CPU
#: with OpenBLAS's default threads and 0.056 ms with one thread.
BLAS_THREADS = 1


def _jsonable(value: Any) -> Any:
    """Convert numpy containers/scalars to plain Python for JSON."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):  # a numeric array's tolist() is plain Python already
        return _jsonable(value.tolist()) if value.dtype == object else value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value  # non-finite floats stay floats (json writes Infinity / NaN and reads them)


class Heartbeat:
    """Batched objective that logs a progress line at most every ``interval_s`` seconds.

    A low-thrust job can run for an hour between the runner's per-job lines; this says it
    is alive, how many candidates it has evaluated out of how many at most (and how many
    the exact cutoff stopped early), the best cost so far and, at the pace so far, the time
    left if the whole budget is spent.

    Parameters
    ----------
    func : callable
        Batched objective Z (B, dim) → costs (B,) or a
        :class:`~penaltyrun.problems.base.BatchEvaluation` (whose ``cutoff`` statuses are
        counted); called as ``func(Z, thresholds)`` when ``accepts_thresholds``.
    label : str
        Job id shown in the line.
    interval_s : float, optional
        Seconds between lines (default :data:`HEARTBEAT_S`).
    total : int, optional
        Most evaluations the job can spend (:func:`penaltyrun.optim.planned_evals`);
        ``None``: no bound known.
    accepts_thresholds : bool, optional
        Hand the optimizer's thresholds to ``func`` (exact cutoff; see
        :mod:`penaltyrun.optim.base`). Without it ``func`` always gets ``None``.
    """

    def __init__(self, func: Any, label: str, interval_s: float | None = None,
                 total: int | None = None, accepts_thresholds: bool = False) -> None:
        self.func = func
        self.label = label
        self.total = total
        self.interval_s = float(HEARTBEAT_S if interval_s is None else interval_s)
        self.accepts_thresholds = bool(accepts_thresholds)
        self.n_evals = 0
        self.n_cutoff = 0
        self.best = float("inf")
        self.t0 = self.last = time.perf_counter()

    def __call__(self, Z: np.ndarray, thresholds: np.ndarray | None = None) -> np.ndarray:
        res = self.func(Z, thresholds) if self.accepts_thresholds else self.func(Z)
        cost = np.asarray(getattr(res, "cost", res), dtype=float)
        self.n_evals += cost.size
        status = getattr(res, "status", None)
        if status is not None:
            self.n_cutoff += int(np.sum(np.asarray(status) == CUTOFF_STATUS))
        finite = cost[np.isfinite(cost)]
        if finite.size:
            self.best = min(self.best, float(finite.min()))
        now = time.perf_counter()
        if now - self.last >= self.interval_s:
            self.last = now
            logger.info("%s: running, %s (%d stopped early by the cutoff) in %.0f s, best "
                        "cost so far %.6g", self.label, self.progress(now - self.t0),
                        self.n_cutoff, now - self.t0, self.best)
        return res if getattr(res, "objective", None) is not None else cost

    def progress(self, elapsed_s: float) -> str:
        """``120 of 2500 evaluations (4.8 %, ≤ 95 s left at this pace)``."""
        if not self.total:
            return f"{self.n_evals} evaluations (no bound)"
        left = max(0, self.total - self.n_evals) * elapsed_s / max(1, self.n_evals)
        return (f"{self.n_evals} of {self.total} evaluations "
                f"({100.0 * self.n_evals / self.total:.1f} %, ≤ {left:.0f} s left at this pace)")


def identity_columns(job: Job) -> dict[str, Any]:
    """Columns every record of ``job`` has, whatever became of the job (also a record
    written for it when its worker died or was killed at ``runner.job_timeout``): its key,
    seed and settings, and the run's metadata. A report groups jobs into cells and
    variants by these."""
    return {"job_id": job.job_id, "problem": job.problem, "case": job.case,
            "param": job.param, "optimizer": job.optimizer, "start": job.start,
            "seed": job.seed, "optimizer_settings": _jsonable(job.optimizer_options),
            "problem_params": _jsonable(job.problem_params),
            "param_options": _jsonable(job.param_options),
            **({"module_hash": job.module_hash} if job.module_hash else {}), **job.meta}


def numba_cache_dir() -> str:
    """Where numba keeps penaltyrun's compiled kernels: ``NUMBA_CACHE_DIR`` if set, else
    the ``__pycache__`` folders of :mod:`penaltyrun.dynamics`."""
    import os
    from pathlib import Path

    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    from penaltyrun import dynamics

    return str(Path(dynamics.__file__).parent)


def describe_job_error(exc: BaseException) -> str:
    """First line of a failed job's error: ``Type: message``; an error raised while numba
    loads its on-disk cache (a damaged ``.nbi`` / ``.nbc`` file) names the cache directory
    and how to clear it."""
    text = f"{type(exc).__name__}: {exc}"
    frames = traceback.extract_tb(exc.__traceback__)
    if any("numba" in f.filename and "caching" in f.filename for f in frames):
        where = numba_cache_dir()
        text += (f" (numba's cache of compiled kernels under {where} is damaged: clear it "
                 f"with `find {where} -name '*.nbi' -delete -o -name '*.nbc' -delete`, then "
                 "run the failed jobs again)")
    return text


def _objective(evaluation: Any, job: Job, prob: Any, layout: Any, param: str,
               settings: Any) -> Heartbeat:
    """Batched objective of ``prob`` over ``layout``'s box (parameterization ``param``),
    evaluated by ``evaluation``, with progress lines counting against the most evaluations
    ``settings`` can spend. The optimizer's thresholds reach the problem when the
    evaluation's objective takes them (``accepts_thresholds``: exact cutoff)."""
    func = evaluation.objective(job, prob, layout, param)
    return Heartbeat(func, job.job_id, total=optim.planned_evals(settings, layout.dim),
                     accepts_thresholds=bool(getattr(func, "accepts_thresholds", False)))


def _gradient(prob: Any, layout: Any) -> Any:
    """z → d cost / d z of ``prob`` over ``layout`` for the gradient optimizers; None when
    the problem has no gradient hook."""
    if gradient_support(prob):
        return None
    return partial(z_gradient, prob, layout)


def _first_order(prob: Any, layout: Any, z: np.ndarray) -> dict[str, Any]:
    """The record's first-order columns of the best z (:func:`first_order`); a gradient
    that raises is noted, never fails the job."""
    try:
        return first_order(prob, layout, z)
    except Exception as exc:  # noqa: BLE001 — a diagnostic: the job's result stands
        interrupts.reraise_run_signal(exc)
        logger.warning("gradient at the best candidate failed: %s", exc)
        return {"grad_norm": float("nan"), "active_bounds": [],
                "gradient_note": f"gradient failed: {exc}"}


def _not_converged(detail: dict[str, Any]) -> str:
    """The ``error`` of a job whose best candidate did not converge: its status, and the
    problem's own error text when its evaluation gives one (a user cost that raised)."""
    text = f"best candidate did not converge ({detail.get('status', 'unknown')})"
    error = detail.get("error")
    return f"{text}: {error}" if isinstance(error, str) and error else text


#: ``best_status`` of a best candidate that its problem called converged although its cost
#: is not a finite number (:func:`_finite_or_not_converged`).
NONFINITE_BEST = "nonfinite"


def _finite_or_not_converged(detail: dict[str, Any], best_cost: float) -> dict[str, Any]:
    """The best candidate's evaluation ``detail``, not converged (status
    :data:`NONFINITE_BEST`) when its own cost or the search's best cost is not finite: a
    problem that returns NaN or inf with ``converged`` true (a user module's bug) would
    otherwise be recorded converged at the optimizer's non-finite penalty."""
    cost = detail.get("cost", best_cost)
    try:
        finite = bool(np.isfinite(float(cost))) and bool(np.isfinite(float(best_cost)))
    except (TypeError, ValueError):
        finite = False
    if finite or not detail.get("converged", False):
        return detail
    return {**detail, "converged": False, "status": NONFINITE_BEST}


def _warm_started(job: Job, prob: Any, layout: Any, settings: Any, evaluation: Any
                  ) -> tuple[optim.OptimResult, dict[str, Any]]:
    """Diagonal stage, then the full search seeded with the best diagonal matrix.

    The diagonal stage has ``warm_start_share · max_evals``; its best matrices are
    encoded in the full map's coordinates (``DecisionLayout.join``) and handed to the
    optimizer as ``x0`` (a particle, a population member, the CMA-ES mean). The full stage
    has the rest of the planned budget, ``max_evals`` less the diagonal stage's share,
    whatever that stage left unspent (a polish that converged early, a stall rule): so each
    stage's search and polish get their shares of ``max_evals`` and the job's searches
    spend what a cold job's search of the same settings spends, the comparison the
    report's equal-budget test makes. Because the seed point is evaluated again, the job's
    best is never worse than its diagonal stage.

    Returns
    -------
    OptimResult
        The whole job: both stages' evaluations, one anytime trace, the full stage's best.
    dict
        The diagonal stage (share, evaluations and those of its polish, best cost,
        matrices) for the record.
    """
    budget = settings.max_evals
    diag_layout = build_layout(prob, "diagonal", job.param_options)
    diag_budget = warm_stage_budget(job.warm_start_share, budget)
    dlb, dub = diag_layout.bounds()
    diag_settings = replace(settings, max_evals=diag_budget)
    diag = optim.minimize(job.optimizer, _objective(evaluation, job, prob, diag_layout,
                                                    "diagonal", diag_settings), dlb, dub,
                          diag_settings, job.seed, gradient=_gradient(prob, diag_layout))
    mats, scalars = diag_layout.split(diag.best_z[None, :])
    diag_mats = {k: v[0] for k, v in mats.items()}
    diag_scalars = {k: float(v[0]) for k, v in scalars.items()}
    x0 = layout.join(diag_mats, diag_scalars)
    lb, ub = layout.bounds()
    full_settings = replace(settings, max_evals=max(1, budget - diag_budget))
    full = optim.minimize(job.optimizer, _objective(evaluation, job, prob, layout, job.param,
                                                    full_settings),
                          lb, ub, full_settings, job.seed, x0, _gradient(prob, layout))
    trace_evals = list(diag.trace_evals) + [diag.n_evals + n for n in full.trace_evals]
    trace_best = np.minimum.accumulate(list(diag.trace_best) + list(full.trace_best))
    diag_cpu = diag.trace_cpu_s[-1] if diag.trace_cpu_s else 0.0
    trace_cpu = list(diag.trace_cpu_s) + [diag_cpu + c for c in full.trace_cpu_s]
    result = optim.OptimResult(
        best_cost=full.best_cost, best_z=full.best_z, history=diag.history + full.history,
        n_evals=diag.n_evals + full.n_evals, n_iters=diag.n_iters + full.n_iters,
        stop_reason=warm_stop(diag.stop_reason, full.stop_reason),
        n_nonfinite=diag.n_nonfinite + full.n_nonfinite, trace_evals=trace_evals,
        trace_best=[float(c) for c in trace_best], trace_cpu_s=trace_cpu,
        n_gradients=diag.n_gradients + full.n_gradients,
        polish_evals=diag.polish_evals + full.polish_evals,
        grad_cost=full.grad_cost if full.grad_cost is not None else diag.grad_cost)
    warm = {"share": job.warm_start_share, "n_evals": diag.n_evals,
            "polish_evals": diag.polish_evals,
            "best_cost": diag.best_cost, "stop_reason": diag.stop_reason,
            "matrices": _jsonable(diag_mats), "scalars": diag_scalars}
    return result, warm


#: This process's thread-pool controller and the number of imported modules it was made
#: with (see :func:`blas_limit`).
_CONTROLLER: list[Any] = []


def blas_limit() -> Any:
    """A context limiting BLAS to :data:`BLAS_THREADS` threads, from one thread-pool
    controller per process.

    Finding the loaded BLAS libraries costs about 1 ms (``threadpool_limits`` does it on
    every call); limiting through a kept controller about 0.02 ms. The controller is found
    again when modules were imported since it was made (one may have loaded another BLAS,
    e.g. SciPy's), so every loaded library is limited, as with ``threadpool_limits``.
    """
    from threadpoolctl import ThreadpoolController

    if not _CONTROLLER or _CONTROLLER[1] != len(sys.modules):
        _CONTROLLER[:] = [ThreadpoolController(), len(sys.modules)]
    return _CONTROLLER[0].limit(limits=BLAS_THREADS, user_api="blas")


def run_job(job: Job, evaluation: Any = None) -> dict[str, Any]:
    """Optimize one job and evaluate its best candidate in detail, with
    :data:`BLAS_THREADS` BLAS threads (see :func:`_run_job`)."""
    with blas_limit():
        return _run_job(job, evaluation)


def _run_job(job: Job, evaluation: Any = None) -> dict[str, Any]:
    """Optimize one job and evaluate its best candidate in detail.

    Parameters
    ----------
    job : Job
    evaluation : LocalEvaluation or DaskEvaluation, optional
        Where candidates are evaluated (default: in this process). The record does not
        depend on it (costs are bitwise the same), only its timing columns do.

    Returns
    -------
    dict
        One flat record (see :mod:`penaltyrun.io.schema` for the columns). A job that
        raises is returned with ``status="failed"`` and the error text; so is one whose
        code raises ``KeyboardInterrupt`` or ``SystemExit`` (a Ctrl-C or SIGTERM of the run
        is raised on, see :mod:`penaltyrun.runner.interrupts`).
    """
    started = datetime.now(timezone.utc)
    t0 = time.perf_counter()
    record: dict[str, Any] = {**identity_columns(job), "started_at": started.isoformat()}
    evaluation = LocalEvaluation() if evaluation is None else evaluation
    try:
        prob, layout, settings = build(job.problem, job.case, job.problem_params, job.param,
                                       job.param_options, job.optimizer,
                                       job.optimizer_options, job.problem_module or None)
        lb, ub = layout.bounds()
        x0 = None
        if job.optimizer == "baseline":
            eye = {name: settings.scale * np.eye(p.n) for name, p in layout.matrices}
            x0 = layout.join(eye, {name: 0.5 * (lo + hi) for name, (lo, hi) in layout.scalars})
        if job.warm_start_share:
            result, warm = _warm_started(job, prob, layout, settings, evaluation)
            record["warm_start"] = warm
        else:
            result = optim.minimize(job.optimizer,
                                    _objective(evaluation, job, prob, layout, job.param,
                                               settings), lb, ub, settings, job.seed, x0,
                                    _gradient(prob, layout))
        mats, scalars = layout.split(result.best_z[None, :])
        best_mats = {k: v[0] for k, v in mats.items()}
        best_scalars = {k: float(v[0]) for k, v in scalars.items()}
        detail, holdout = evaluation.best(job, prob, best_mats, best_scalars)
        detail = _finite_or_not_converged(detail, result.best_cost)
        converged = bool(detail.get("converged", False))
        record.update({
            "status": OK if converged else DIVERGED,
            "error": "" if converged else _not_converged(detail),
            "best_cost": float(result.best_cost),
            "best_converged": converged,
            "best_status": str(detail.get("status", "")),
            "t_final": float(detail.get("t_final", float("nan"))),
            "best_z": result.best_z.tolist(),
            "z_names": layout.names(),
            "matrices": _jsonable(best_mats),
            "scalars": best_scalars,
            "metrics": _jsonable(detail),
            "holdout": _jsonable(holdout),
            "n_evals": int(result.n_evals),
            "n_gradients": int(result.n_gradients),
            "polish_evals": int(result.polish_evals),
            "grad_cost": result.grad_cost,
            "n_iters": int(result.n_iters),
            "stop_reason": result.stop_reason,
            "n_nonfinite": int(result.n_nonfinite),
            "history": [float(h) for h in result.history],
            "trace_evals": [int(n) for n in result.trace_evals],
            "trace_best": [float(c) for c in result.trace_best],
            "trace_cpu_s": [float(c) for c in result.trace_cpu_s],
            "max_evals": getattr(settings, "max_evals", None),
        })
        record.update(_jsonable(diagnostics.record_columns(prob, best_mats, best_scalars)))
        record.update(_jsonable(_first_order(prob, layout, result.best_z)))
    except Exception as exc:  # a failing job is recorded, never crashes the run
        interrupts.reraise_run_signal(exc)
        text = describe_job_error(exc)
        logger.error("job %s failed: %s", job.job_id, text)
        record.update({"status": FAILED, "error": f"{text}\n{traceback.format_exc()}"})
    except (KeyboardInterrupt, SystemExit) as exc:
        if not interrupts.raised_by_job(exc):  # a Ctrl-C / SIGTERM of the run stops it
            raise
        text = interrupts.describe_exit_exception(exc)
        logger.error("job %s failed: %s", job.job_id, text)
        record.update({"status": FAILED, "error": text})
    record["wall_time_s"] = time.perf_counter() - t0
    record["finished_at"] = datetime.now(timezone.utc).isoformat()
    return record
