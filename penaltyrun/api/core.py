"""The run of one cell: plan its jobs, run them, collect ``results.parquet``.

The command line's ``mode=optimize`` (:func:`penaltyrun.cli.run_optimize`) and
:func:`penaltyrun.tune` both end here, so both give the same jobs, per-job seeds, record
files, Parquet file, provenance and resume behaviour. A cell is described by a
:class:`CellSpec` (plain data): the command line builds it from its composed config, the
API from the same YAML files (:mod:`penaltyrun.api.compose`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from penaltyrun import __version__
from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_number

logger = logging.getLogger("penaltyrun")

#: Called with the cell's jobs; returns a context manager yielding the per-record callback.
ProgressFactory = Callable[[list[Any]], Any]


@dataclass(frozen=True)
class CellSpec:
    """Everything one cell's run needs (plain data; the typed form of a composed config).

    Attributes
    ----------
    problem, param, optimizer : str
        Problem name, parameterization (map) name, optimizer name.
    case : str or None
        Problem case (``None``: the problem's default case).
    problem_params : dict
        Problem parameter overrides (nulls already dropped).
    param_options : dict
        The parameterization node (``name``, ``eig_bounds``, ``cayley_bound``).
    optimizer_options : dict
        Optimizer settings (without ``name``).
    problem_module : str or None
        Module of a problem outside penaltyrun (``object:<name>`` for an in-memory one).
    runner : dict
        ``runner.*`` options (see :mod:`penaltyrun.runner.options`).
    hashed : dict
        The resolved ``problem``, ``case``, ``param`` and ``optimizer`` nodes and the root
        ``seed``: the run's ``config_hash`` (studies deduplicate runs by it).
    config_text : str
        The whole config as YAML, recorded with every job.
    report_output : str or None
        Report folder after the run (``None``: ``<run_dir>/report``), if ``runner.report``.
    report_paper : bool
        Put the paper's numbers beside the run's in that report.
    """

    problem: str
    case: str | None
    param: str
    optimizer: str
    problem_params: dict[str, Any] = field(default_factory=dict)
    param_options: dict[str, Any] = field(default_factory=dict)
    optimizer_options: dict[str, Any] = field(default_factory=dict)
    problem_module: str | None = None
    runner: dict[str, Any] = field(default_factory=dict)
    hashed: dict[str, Any] = field(default_factory=dict)
    config_text: str = ""
    report_output: str | None = None
    report_paper: bool = True

    def build(self) -> tuple[Any, Any, Any]:
        """Validated (problem, decision layout, optimizer settings) of the cell."""
        from penaltyrun import runner

        return runner.build(self.problem, self.case, self.problem_params, self.param,
                            self.param_options, self.optimizer, self.optimizer_options,
                            self.problem_module)


def warm_start_share(runner: Mapping[str, Any], optimizer: str,
                     optimizer_options: Mapping[str, Any]) -> float:
    """Share of the budget spent on the diagonal stage (0: no warm start).

    Raises
    ------
    ConfigError
        A warm start without ``optimizer.max_evals``, or a share outside (0, 1).
    """
    if not runner.get("warm_start", False):
        return 0.0
    if not isinstance(runner["warm_start"], bool):
        raise ConfigError("runner.warm_start",
                          f"must be true or false, got {runner['warm_start']!r}")
    share = runner.get("warm_start_share", 0.3)
    if not is_number(share) or not 0 < share < 1:
        raise ConfigError("runner.warm_start_share", f"must be in (0, 1), got {share!r}")
    if optimizer_options.get("max_evals") is None:
        raise ConfigError("runner.warm_start", "needs an evaluation budget: set "
                          "optimizer.max_evals (the diagonal stage spends "
                          "warm_start_share of it)")
    if optimizer in ("grid", "baseline"):
        raise ConfigError("runner.warm_start", f"not for optimizer {optimizer!r}",
                          allowed=("pso", "de", "cmaes"))
    return float(share)


def plan_cell(spec: CellSpec, case: str, meta: Mapping[str, Any] | None = None) -> list[Any]:
    """The jobs of the cell (one per start); ``case`` is the problem's resolved case."""
    from penaltyrun import runner

    rc = spec.runner
    return runner.plan_jobs(
        spec.problem, case, spec.param, spec.optimizer, rc["n_starts"], int(rc["seed"]),
        spec.problem_params, spec.param_options, spec.optimizer_options, dict(meta or {}),
        holdout=bool(rc.get("holdout", True)),
        warm_start_share=warm_start_share(rc, spec.optimizer, spec.optimizer_options),
        problem_module=spec.problem_module, cutoff=bool(rc.get("cutoff", True)),
        module_hash=runner.user_code_hash(spec.problem_module, spec.problem_params))


def local_workers(runner: Mapping[str, Any]) -> int | None:
    """Worker processes of the cell on this machine (``workers``, ``auto`` resolved);
    ``None`` for a remote dask scheduler (cluster size unknown here)."""
    from penaltyrun.runner.options import resolve_workers

    if runner.get("backend", "local") == "dask" and runner.get("scheduler"):
        return None
    return resolve_workers(runner.get("workers", "auto"))


def run_meta(spec: CellSpec, run_dir: Path) -> dict[str, Any]:
    """Run-level metadata copied into every record: ``config_hash`` (of
    :attr:`CellSpec.hashed`), the config text, the package version, the git commit of the
    source and the run id (the run folder's name)."""
    from penaltyrun import runner
    from penaltyrun.runner.provenance import git_commit

    return {"config_hash": runner.config_hash(spec.hashed), "config": spec.config_text,
            "package_version": __version__, "git_commit": git_commit(),
            "run_id": Path(run_dir).name}


def run_cell(spec: CellSpec, run_dir: Path, progress: ProgressFactory | None = None) -> Path:
    """Plan and run the jobs of one cell, then write ``results.parquet`` (and the report
    when ``runner.report`` is true).

    Parameters
    ----------
    spec : CellSpec
    run_dir : Path
        Run folder: ``jobs/<job_id>.json`` records, ``results.parquet``, ``report/``.
    progress : callable, optional
        ``progress(jobs)`` returns a context manager that yields a callback called with
        each record as it is written (the command line's progress bar); ``None``: none.

    Returns
    -------
    Path
        ``run_dir/results.parquet``.

    Raises
    ------
    ConfigError
        An invalid name or value (naming the key), or ``run_dir`` used by another run.
    RunInterruptedError, RunAbortedError, EnvironmentProblemError
        As :func:`penaltyrun.runner.execute`; finished jobs stay on disk for a resume.
    """
    from penaltyrun import io, runner
    from penaltyrun.runner import lock

    prob, _, _ = spec.build()
    runner.check_runner_options(spec.runner, connect=False)
    run_dir = Path(run_dir)
    jobs = plan_cell(spec, prob.case, run_meta(spec, run_dir))
    rc = spec.runner
    logger.info("%d jobs (%s / %s / %s / %s) → %s", len(jobs), prob.name, prob.case,
                spec.param, spec.optimizer, run_dir)
    expected = runner.log_forecast(jobs, int(rc.get("forecast_samples", 8)), int(rc["seed"]),
                                   local_workers(rc), rc.get("job_timeout"))
    bar = progress(jobs) if progress is not None else contextlib.nullcontext(None)
    try:
        with bar as on_record:
            _execute(jobs, run_dir, rc, on_record, expected)
    except BaseException:  # the run is over: a later run in this process may take the folder
        lock.release(run_dir)
        raise
    path = io.collect(run_dir, [job.job_id for job in jobs])
    if rc.get("report", False):
        from penaltyrun import report  # matplotlib, scipy.stats: only when a report is written

        trust_own_modules(spec.problem, spec.problem_module, spec.problem_params)
        out = Path(spec.report_output) if spec.report_output else run_dir / "report"
        report.build_report(path, out, paper=bool(spec.report_paper))
        logger.info("report written to %s", out)
    return path


def trust_own_modules(problem: str, module_path: str | None,
                      params: Mapping[str, Any]) -> None:
    """Let the report of this process import the modules a run's own config names: the
    problem's ``module`` and an LQR plant's ``plant`` / ``dynamics`` (``module:function``).
    Results read later import no module named in them
    (:mod:`penaltyrun.problems.trust`); the config the user runs names these on purpose.

    Raises
    ------
    ConfigError
        A name that is not a dotted module name.
    """
    from penaltyrun import problems

    if module_path and not str(module_path).startswith(problems.OBJECT_PREFIX):
        problems.register(problem, str(module_path))  # an in-memory one is named by hold()
    for key in ("plant", "dynamics"):
        value = params.get(key)
        if isinstance(value, str):
            problems.trust.allow_module(value.partition(":")[0])


def _execute(jobs: list[Any], run_dir: Path, rc: Mapping[str, Any],
             on_record: Callable[[dict[str, Any]], None] | None,
             expected: Mapping[str, float]) -> None:
    """:func:`penaltyrun.runner.execute` with the ``runner.*`` options ``rc``."""
    from penaltyrun import runner

    runner.execute(jobs, run_dir, workers=rc.get("workers", "auto"),
                   backend=rc.get("backend", "local"), scheduler=rc.get("scheduler"),
                   resume=bool(rc.get("resume", False)),
                   retry_failed=bool(rc.get("retry_failed", False)), on_record=on_record,
                   max_retries=rc.get("max_retries", 1),
                   worker_timeout=float(rc.get("worker_timeout", 60)), expected_s=expected,
                   evaluate_on=rc.get("evaluate_on", "local"),
                   chunks=rc.get("chunks", "auto"),
                   stall_timeout=float(rc.get("stall_timeout", 600)),
                   job_timeout=rc.get("job_timeout"))


__all__ = ["CellSpec", "local_workers", "plan_cell", "run_cell", "run_meta",
           "warm_start_share"]
