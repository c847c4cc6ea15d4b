"""Tune the penalty matrices of a problem from Python: :func:`tune`.

One call runs one cell (problem, case, map, optimizer) with ``n_starts`` starts through the
same run core as ``penaltyrun mode=optimize`` (:func:`penaltyrun.api.core.run_cell`): the
same per-job seeds, budgets, record files, ``results.parquet``, provenance and resume.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from penaltyrun import problems
from penaltyrun.api.compose import API_RUNNER, compose, read_yaml, run_spec
from penaltyrun.api.core import run_cell, trust_own_modules
from penaltyrun.api.result import TuneResult, folder_argument
from penaltyrun.errors import ConfigError
from penaltyrun.problems.user_cost import from_cost

#: Methods an object must have to be tuned as an in-memory problem.
_PROBLEM_METHODS = ("evaluate_batch", "evaluate", "simulate")


def default_seed() -> int:
    """The command line's default root seed (``runner.seed`` in ``conf/config.yaml``)."""
    from penaltyrun.api.compose import CONF

    return int(read_yaml(CONF / "config.yaml")["runner"]["seed"])


def resolve_problem(problem: Any) -> tuple[str, str | None, Any]:
    """(name, module path, in-memory object or None) of ``tune``'s ``problem`` argument.

    A string is a problem name (built-in, registered or an entry point) or, when it has a
    dot and is no such name, the dotted path of a problem module (its last part is the
    problem's name). Anything else must be a problem object (e.g. from :func:`from_cost`).

    Raises
    ------
    ConfigError
        An unknown name, a module that cannot be imported or lacks the protocol, or an
        object that is not a problem.
    """
    if isinstance(problem, str):
        if not all(part.isidentifier() for part in problem.split(".")):
            raise ConfigError("problem", f"unknown problem {problem!r}: give a problem name, "
                              "a dotted module path or a problem object",
                              allowed=problems.available())
        if "." in problem and problem not in problems.available():
            name = problem.rsplit(".", 1)[1]
            problems.builtin_name_refused(name, "problem", "a module's problem name is the "
                                          "last part of its path; rename the module")
            problems.module(name, problem)  # import it now: one clear error if it fails
            return name, problem, None
        problems.module(problem)
        return problem, None, None
    missing = [m for m in ("name", "case", "matrices", "scalars", *_PROBLEM_METHODS)
               if not hasattr(problem, m)]
    if missing:
        raise ConfigError("problem", f"expected a problem name, a module path or a problem "
                          f"object (penaltyrun.from_cost), got a {type(problem).__name__} "
                          f"that lacks {', '.join(missing)}")
    problems.builtin_name_refused(str(problem.name), "problem", "give the object another "
                                  "name")
    return str(problem.name), f"{problems.OBJECT_PREFIX}{problem.name}", problem


@contextlib.contextmanager
def held(obj: Any) -> Iterator[None]:
    """Hold the in-memory problem ``obj`` for the block (nothing for ``None``)."""
    if obj is None:
        yield
        return
    with problems.hold(obj):
        yield


def tune(problem: Any, *, param: str = "full", optimizer: str = "cmaes", n_starts: int = 10,
         seed: int | None = None, optimizer_options: Mapping[str, Any] | None = None,
         case: str | None = None, params: Mapping[str, Any] | None = None,
         run_dir: str | Path | None = None, workers: int | str | None = None,
         resume: bool = False, job_timeout: float | None = None,
         param_options: Mapping[str, Any] | None = None,
         runner_options: Mapping[str, Any] | None = None) -> TuneResult:
    """Tune the penalty matrices of ``problem``: ``n_starts`` seeded optimizer starts.

    Parameters
    ----------
    problem : str or problem object
        A built-in problem name (``"zermelo"``, ``"attitude_lqr"``, ``"lqr"``, ...), the
        dotted path of a problem module (``"my_pkg.my_module"``, following
        :mod:`penaltyrun.problems.base`), or a problem object from :func:`from_cost`.
    param : str
        Parameterization of the matrices: ``"full"`` (K = Q Λ Qᵀ), ``"diagonal"``,
        ``"givens"``, ``"cayley"``, ... (the command line's ``param=`` choices).
    optimizer : str
        ``"cmaes"``, ``"pso"``, ``"de"``, ``"pso_matlab"``, ``"grid"``, ``"baseline"``
        or a budget profile (the command line's ``optimizer=`` choices).
    n_starts : int
        Independent starts (jobs) of the cell.
    seed : int, optional
        Root seed; each job's seed derives from it and the job's key. ``None``: the
        command line's default root seed, so both give the same jobs.
    optimizer_options : mapping, optional
        Optimizer settings over the optimizer's defaults, e.g. ``{"max_evals": 500}``.
    case : str, optional
        Problem case (``None``: the problem's default case).
    params : mapping, optional
        Problem parameter overrides (``problem.params.*`` on the command line).
    run_dir : str or Path, optional
        Run folder (records, ``results.parquet``); ``None``: a new temporary folder,
        kept after the call (its path is :attr:`TuneResult.run_dir`).
    workers : int or "auto", optional
        Parallel jobs: 1 runs them in this process, more on a process pool (an
        in-memory problem reaches the forked workers as it is); ``None``: ``"auto"``,
        one per core, as the command line. Results do not depend on it.
    resume : bool
        Skip the jobs already recorded in ``run_dir`` (a run stopped part-way).
    job_timeout : float, optional
        Wall-clock seconds a job may run before its worker process is killed and the job
        recorded ``timeout`` (s; ``runner.job_timeout``); with it even ``workers=1`` runs
        the jobs in a worker process. ``None``: no limit.
    param_options : mapping, optional
        Options of the map (``param.*`` on the command line): ``eig_bounds`` [lower,
        upper] over the problem's eigenvalue bounds, ``cayley_bound``.
    runner_options : mapping, optional
        Other ``runner.*`` settings of the command line (:class:`~penaltyrun.runner.spec.
        RunnerOptions`), e.g. ``{"warm_start": True}``, ``{"holdout": False}``,
        ``{"retry_failed": True}``, ``{"backend": "dask"}``; the arguments above set
        their own.

    Returns
    -------
    TuneResult
        The run's records, best start, summary and report.

    Raises
    ------
    ConfigError
        An unknown or invalid name or value, naming the key and what is allowed.
    RunInterruptedError
        Ctrl-C during the run; the finished jobs stay in ``run_dir`` for ``resume=True``.
    """
    name, module, obj = resolve_problem(problem)
    root_seed = default_seed() if seed is None else seed
    own = {"n_starts": n_starts, "seed": root_seed,
           "workers": "auto" if workers is None else workers, "resume": resume,
           "job_timeout": job_timeout}
    if runner_options is not None and not isinstance(runner_options, Mapping):
        raise ConfigError("runner_options", f"must be a mapping {{name: value}}, got "
                          f"{type(runner_options).__name__}")
    twice = sorted(set(runner_options or {}) & set(own))
    if twice:
        raise ConfigError(f"runner_options.{twice[0]}", f"pass {twice[0]}= as tune's own "
                          "argument")
    runner = {**API_RUNNER, **(runner_options or {}), **own}
    config = compose(name, module, case=case, param=param, optimizer=optimizer,
                     optimizer_options=optimizer_options, params=params, runner=runner,
                     param_options=param_options)
    spec = run_spec(config)
    if run_dir is None:
        run_dir = tempfile.mkdtemp(prefix="penaltyrun-")
    run_dir = folder_argument(run_dir, "run_dir")
    if run_dir.exists() and not run_dir.is_dir():
        raise ConfigError("run_dir", f"{run_dir} is a file; a run writes a folder: pass a "
                                     "folder path")
    with held(obj):
        path = run_cell(spec, run_dir)
    trust_own_modules(name, None if obj is not None else module, spec.problem_params)
    result = TuneResult(run_dir, path, problem=obj)
    result.records  # noqa: B018  (read now: the result is this run's, whatever runs next)
    return result


__all__ = ["default_seed", "from_cost", "resolve_problem", "tune"]
