"""Evaluation of a job's candidates, in this process or as chunks on Dask workers.

:func:`penaltyrun.runner.job.run_job` gets the optimizer's batch objective and the detailed
evaluation of its best candidate from an *evaluation*: :class:`LocalEvaluation` (this
process, the default) or :class:`~penaltyrun.runner.dask_swarm.DaskEvaluation` (each batch
split into chunks evaluated on Dask workers, ``runner.evaluate_on=dask``).

This module also holds the worker side of the Dask evaluation, which needs no ``distributed``
import: a per-process registry of :class:`ProblemSpec` (filled once per worker by a worker
plugin) and a cache of the problem and decision layout built from each, so a worker builds a
problem (and loads its compiled kernels from numba's on-disk cache) once per run, not once
per iteration. Chunks are contiguous row blocks of the batch; every problem's
``evaluate_batch`` is row-wise, so the gathered costs are bitwise those of the whole batch.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from penaltyrun import __version__, problems
from penaltyrun.penalty.layout import DecisionLayout
from penaltyrun.problems.base import Problem, accepts_thresholds, checked_batch
from penaltyrun.problems.hooks import hooks
from penaltyrun.runner.plan import Job, config_hash
from penaltyrun.runner.setup import build_layout

logger = logging.getLogger(__name__)

BatchFunc = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ProblemSpec:
    """The settings that build a job's problem and decision layout (plain data).

    Attributes
    ----------
    problem, case, param : str
        Problem name, resolved case, parameterization kind.
    problem_params, param_options : dict
        Problem parameter overrides; parameterization options.
    problem_module : str
        Module of a problem outside penaltyrun, or "".
    """

    problem: str
    case: str
    param: str
    problem_params: dict[str, Any] = field(default_factory=dict)
    param_options: dict[str, Any] = field(default_factory=dict)
    problem_module: str = ""

    @classmethod
    def of(cls, job: Job, param: str | None = None) -> ProblemSpec:
        """Spec of ``job``'s problem under parameterization ``param`` (default the job's;
        a warm start also needs the diagonal one)."""
        return cls(job.problem, job.case, param or job.param, dict(job.problem_params),
                   dict(job.param_options), job.problem_module)

    @property
    def key(self) -> str:
        """Hash of the spec and penaltyrun's version (the worker cache key)."""
        return config_hash([asdict(self), __version__])

    def build(self) -> tuple[Problem, DecisionLayout]:
        """The problem instance and its decision layout."""
        prob = problems.make(self.problem, self.case, self.problem_params,
                             self.problem_module or None)
        return prob, build_layout(prob, self.param, self.param_options)


def evaluate_best(prob: Problem, mats: Mapping[str, np.ndarray], scalars: Mapping[str, float],
                  holdout: bool) -> tuple[dict[str, Any], Any]:
    """Detailed evaluation of one candidate, and its held-out results when asked.

    Returns
    -------
    dict
        ``prob.evaluate`` (cost, converged, status, t_final, ...).
    dict or None
        ``prob.holdout`` when ``holdout`` and the problem has a held-out set, else None.
    """
    detail = prob.evaluate(mats, scalars or None)
    held = None
    judge = hooks(prob).holdout if holdout else None
    if judge is not None:
        held = judge(mats, scalars or None)
    return detail, held


class LocalEvaluation:
    """Evaluate every candidate in this process (``runner.evaluate_on=local``)."""

    def objective(self, job: Job, prob: Problem, layout: DecisionLayout, param: str
                  ) -> BatchFunc:
        """Batched objective Z (B, dim) → costs (B,) of ``prob`` over ``layout``.

        With ``job.cutoff`` and a problem whose ``evaluate_batch`` takes ``thresholds``, the
        objective is marked ``accepts_thresholds`` and, called with thresholds, returns the
        problem's :class:`~penaltyrun.problems.base.BatchEvaluation` (statuses included, so
        cut candidates can be counted) instead of the bare costs.
        """

        def evaluate(Z: np.ndarray, thresholds: np.ndarray | None = None) -> Any:
            mats, scalars = layout.split(Z)
            if thresholds is None:
                res = checked_batch(prob.evaluate_batch(mats, scalars or None), len(Z), prob)
                return res if getattr(res, "objective", None) is not None else res.cost
            return checked_batch(prob.evaluate_batch(mats, scalars or None,
                                                     thresholds=thresholds), len(Z), prob)

        evaluate.accepts_thresholds = bool(getattr(job, "cutoff", True)) and \
            accepts_thresholds(prob)
        return evaluate

    def best(self, job: Job, prob: Problem, mats: Mapping[str, np.ndarray],
             scalars: Mapping[str, float]) -> tuple[dict[str, Any], Any]:
        """Detailed (and held-out) evaluation of the job's best candidate."""
        return evaluate_best(prob, mats, scalars, job.holdout)


# --- worker side ------------------------------------------------------------------------

#: Specs registered in this process (by the worker plugin), by key.
_SPECS: dict[str, ProblemSpec] = {}
#: Problem and layout built from each registered spec, by key.
_CACHE: dict[str, tuple[Problem, DecisionLayout]] = {}
#: How many times this process built each key's problem (1 per worker and run).
BUILDS: dict[str, int] = {}
_LOCK = threading.Lock()


def register(spec: ProblemSpec) -> None:
    """Make ``spec`` known to this process (worker plugin ``setup``)."""
    with _LOCK:
        _SPECS[spec.key] = spec


def forget(key: str) -> None:
    """Drop ``key``'s spec and cached problem (worker plugin ``teardown``)."""
    with _LOCK:
        _SPECS.pop(key, None)
        _CACHE.pop(key, None)


def cached(key: str) -> tuple[Problem, DecisionLayout]:
    """Problem and layout of registered spec ``key``, built at the first call.

    Raises
    ------
    KeyError
        If no spec ``key`` was registered in this process.
    """
    with _LOCK:
        entry = _CACHE.get(key)
        if entry is None:
            if key not in _SPECS:
                raise KeyError(f"problem spec {key} is not registered on this worker")
            entry = _CACHE[key] = _SPECS[key].build()
            BUILDS[key] = BUILDS.get(key, 0) + 1
    return entry


def evaluate_chunk(key: str, Z: np.ndarray) -> tuple[np.ndarray, float]:
    """Costs of one chunk of candidates on a worker.

    Parameters
    ----------
    key : str
        Key of a registered :class:`ProblemSpec`.
    Z : ndarray, shape (b, dim)
        Decision vectors (a contiguous block of the batch).

    Returns
    -------
    ndarray, shape (b,), or BatchEvaluation
        Costs, as the local batch objective returns them (the whole evaluation when the
        problem's ``objective`` values differ from its costs).
    float
        CPU seconds of this thread spent evaluating (without building the problem).
    """
    prob, layout = cached(key)
    c0 = time.thread_time()
    mats, scalars = layout.split(np.asarray(Z, float))
    res = checked_batch(prob.evaluate_batch(mats, scalars or None), len(Z), prob)
    if getattr(res, "objective", None) is not None:  # an objective form: keep both arrays
        return res, time.thread_time() - c0
    cost = np.asarray(res.cost, dtype=float)
    return cost, time.thread_time() - c0


def evaluate_best_chunk(key: str, mats: Mapping[str, np.ndarray],
                        scalars: Mapping[str, float], holdout: bool
                        ) -> tuple[dict[str, Any], Any]:
    """:func:`evaluate_best` on a worker, with the cached problem of spec ``key``."""
    prob, _ = cached(key)
    return evaluate_best(prob, mats, scalars, holdout)
