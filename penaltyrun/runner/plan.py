"""Plan jobs: one job per (problem, case, parameterization, optimizer, start).

Per-job seeds derive from the root seed and the job's key through numpy's
``SeedSequence``, so adding cells or starts never changes the seeds of existing jobs.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_int

#: Most starts of one cell (``runner.n_starts``): a larger cell is refused with one line
#: (its job list alone would fill the memory; split it into several seeds instead).
MAX_N_STARTS = 100_000


@dataclass(frozen=True)
class Job:
    """Everything one optimization run needs (plain data, picklable).

    Attributes
    ----------
    problem, case, param, optimizer : str
        Problem name, case (resolved), parameterization kind, optimizer name.
    start : int
        Start index within the cell, 0-based.
    seed : int
        Seed of this job (derived, see :func:`job_seed`).
    problem_params : dict
        Problem parameter overrides.
    param_options : dict
        Parameterization options (``eig_bounds``, ``cayley_bound``).
    optimizer_options : dict
        Optimizer settings.
    meta : dict
        Run-level metadata copied into the record (config hash, version, commit, config).
    holdout : bool
        Evaluate the best candidate on the problem's held-out set (if it defines one).
    warm_start_share : float
        0: off. Otherwise (full maps only) the share of ``max_evals`` spent first on the
        diagonal map, whose best matrix then seeds the full search.
    problem_module : str
        Module of a problem outside penaltyrun (a problem config's ``module:``), or "".
    cutoff : bool
        Exact cutoff (``runner.cutoff``): optimizers hand thresholds to problems that take
        them. Not part of :attr:`settings_hash`: the result is the same either way.
    root_seed : int or None
        ``runner.seed`` the job's seed derives from (part of :attr:`settings_hash`).
    module_hash : str
        Hash of the source of ``problem_module`` and of the modules a problem parameter
        names (:func:`user_code_hash`), or "" (a problem of penaltyrun, an in-memory one).
        Part of :attr:`settings_hash`: a module edited between an interrupted run and its
        resume is a new configuration.
    """

    problem: str
    case: str
    param: str
    optimizer: str
    start: int
    seed: int
    problem_params: dict[str, Any] = field(default_factory=dict)
    param_options: dict[str, Any] = field(default_factory=dict)
    optimizer_options: dict[str, Any] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    holdout: bool = True
    warm_start_share: float = 0.0
    problem_module: str = ""
    cutoff: bool = True
    root_seed: int | None = None
    module_hash: str = ""

    @property
    def settings_hash(self) -> str:
        """Hash of everything that changes the result: problem, map and optimizer options,
        the root seed (``runner.seed``), the held-out setting, the warm start and the
        source of a problem module outside penaltyrun.

        Part of :attr:`job_id`, so a resumed run never mistakes a job finished with other
        settings (another seed, without held-out data, ...) for one of its own.
        """
        hashed: list[Any] = [self.problem_params, self.param_options, self.optimizer_options,
                             {"root_seed": self.root_seed, "holdout": self.holdout,
                              "problem_module": self.problem_module}]
        if self.warm_start_share:
            hashed.append({"warm_start_share": self.warm_start_share})
        if self.module_hash:
            hashed.append({"module_source": self.module_hash})
        return config_hash(hashed)[:8]

    @property
    def job_id(self) -> str:
        """Stable identifier, also the job's file name in the run directory."""
        return (f"{self.problem}-{self.case}-{self.param}-{self.optimizer}-"
                f"{self.settings_hash}-s{self.start:03d}")

    def to_dict(self) -> dict[str, Any]:
        """Plain-dict form (JSON-serializable)."""
        return asdict(self)


def warm_stage_budget(share: float, max_evals: int) -> int:
    """Evaluations of the diagonal stage of a job of ``max_evals`` warm-started with
    ``share`` (``runner.warm_start_share``): that share of them, at least one."""
    return max(1, int(share * max_evals))


def job_seed(root_seed: int, key: str) -> int:
    """Seed of one job from the root seed and the job key (stable across runs/machines)."""
    digest = int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little")
    return int(np.random.SeedSequence([int(root_seed), digest]).generate_state(1)[0])


def config_hash(obj: Any) -> str:
    """Short SHA-256 of a JSON-serializable object (canonical key order)."""
    text = json.dumps(obj, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def plan_jobs(problem: str, case: str, param: str, optimizer: str, *, n_starts: int,
              root_seed: int, problem_params: Mapping[str, Any] | None = None,
              param_options: Mapping[str, Any] | None = None,
              optimizer_options: Mapping[str, Any] | None = None,
              meta: Mapping[str, Any] | None = None, holdout: bool = True,
              warm_start_share: float = 0.0, problem_module: str | None = None,
              cutoff: bool = True, module_hash: str = "") -> list[Job]:
    """One job per start of a single (problem, case, param, optimizer) cell.

    The cell is positional, everything else keyword-only (a run from a config plans through
    :meth:`penaltyrun.runner.spec.RunSpec.plan`).

    Parameters
    ----------
    problem, case, param, optimizer : str
        The cell: problem name, resolved case, parameterization (map), optimizer.
    n_starts : int
        Starts (jobs), at most :data:`MAX_N_STARTS`.
    root_seed : int
        The run's root seed; each job's seed is :func:`job_seed` of it and the job's key.
    problem_params, param_options, optimizer_options : mapping, optional
        Problem parameter overrides, the parameterization node, the optimizer settings.
    meta : mapping, optional
        Run-level metadata copied into every record.
    holdout : bool
        Judge each job's best candidate on the held-out scenarios.
    warm_start_share : float
        Share of the budget for a diagonal warm start; full maps only (a diagonal job has
        nothing to warm).
    problem_module : str, optional
        Module of a problem outside penaltyrun.
    cutoff : bool
        Let the problem stop hopeless candidates early (not part of the job's identity).
    module_hash : str
        :func:`~penaltyrun.runner.usercode.user_code_hash` of the user code (part of the job
        ids).

    Raises
    ------
    ConfigError
        If ``n_starts`` is not a positive integer of at most :data:`MAX_N_STARTS`.
    """
    check_n_starts(n_starts)
    jobs = []
    for start in range(n_starts):
        key = f"{problem}/{case}/{param}/{optimizer}/{start}"
        jobs.append(Job(problem, case, param, optimizer, start, job_seed(root_seed, key),
                        dict(problem_params or {}), dict(param_options or {}),
                        dict(optimizer_options or {}), dict(meta or {}), bool(holdout),
                        0.0 if param == "diagonal" else float(warm_start_share),
                        str(problem_module or ""), bool(cutoff), int(root_seed),
                        str(module_hash or "")))
    return jobs


def check_n_starts(n_starts: Any) -> None:
    """Refuse ``runner.n_starts`` unless it is an integer in [1, :data:`MAX_N_STARTS`].

    Raises
    ------
    ConfigError
        Naming the key and the bound.
    """
    if not is_int(n_starts) or n_starts < 1:
        raise ConfigError("runner.n_starts", f"must be a positive integer, got {n_starts!r}")
    if n_starts > MAX_N_STARTS:
        raise ConfigError("runner.n_starts", f"{n_starts} is above the limit of "
                          f"{MAX_N_STARTS} starts per cell; split the cell into runs with "
                          "different runner.seed values")


def order_longest_first(jobs: Iterable[Job], expected_s: Mapping[str, float] | None = None
                        ) -> list[Job]:
    """Jobs sorted by expected run time, longest first (ties and unknowns keep their order).

    Dispatching the longest jobs first shortens the wall time of a pool of workers (the
    longest-processing-time rule: within 4/3 of the best possible schedule).

    Parameters
    ----------
    jobs : iterable of Job
    expected_s : mapping, optional
        ``job_id`` → expected CPU time (s), e.g. from
        :func:`penaltyrun.runner.forecast.forecast_cell`. Jobs missing from it (or all jobs,
        when it is None) keep their place after the known ones.
    """
    jobs = list(jobs)
    if not expected_s:
        return jobs
    known = [j for j in jobs if expected_s.get(j.job_id) is not None]
    unknown = [j for j in jobs if expected_s.get(j.job_id) is None]
    return sorted(known, key=lambda j: -float(expected_s[j.job_id])) + unknown
