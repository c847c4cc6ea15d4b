"""The run of one cell: plan its jobs, run them, collect ``results.parquet``.

The command line's ``mode=optimize`` (:func:`penaltyrun.cli.app.run_optimize`) and
:func:`penaltyrun.tune` both end here, so both give the same jobs, per-job seeds, record
files, Parquet file, provenance and resume behaviour. A cell is described by a
:class:`~penaltyrun.runner.spec.RunSpec` (typed plain data): the command line builds it from
its composed config (:func:`penaltyrun.cli.spec.run_spec`), the API from the same YAML files
(:mod:`penaltyrun.api.compose`).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from penaltyrun import __version__

if TYPE_CHECKING:
    from penaltyrun.runner.spec import RunSpec

logger = logging.getLogger("penaltyrun")

#: Called with the cell's jobs; returns a context manager yielding the per-record callback.
ProgressFactory = Callable[[list[Any]], Any]


def run_meta(spec: RunSpec, run_dir: Path) -> dict[str, Any]:
    """Run-level metadata copied into every record: ``config_hash`` (of
    :attr:`RunSpec.hashed`), the config text, the package version, the git commit of the
    source and the run id (the run folder's name)."""
    from penaltyrun import runner
    from penaltyrun.runner.provenance import git_commit

    return {"config_hash": runner.config_hash(spec.hashed), "config": spec.config_text,
            "package_version": __version__, "git_commit": git_commit(),
            "run_id": Path(run_dir).name}


def run_cell(spec: RunSpec, run_dir: Path, progress: ProgressFactory | None = None) -> Path:
    """Plan and run the jobs of one cell, then write ``results.parquet`` (and the report
    when ``runner.report`` is true).

    Parameters
    ----------
    spec : RunSpec
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
    from penaltyrun import io, optim, runner
    from penaltyrun.runner import lock

    prob, _, _ = spec.build()
    optim.check_gradient_available(spec.optimizer, spec.optimizer_options, prob)
    run_dir = Path(run_dir)
    if spec.runner.report:  # a report folder the run could not write into: before any job
        from penaltyrun.report import outdir

        outdir.check(_report_folder(spec, run_dir), "report.output", run_dir)
    jobs = spec.plan(prob.case, run_meta(spec, run_dir))
    rc = spec.runner
    logger.info("%d jobs (%s / %s / %s / %s) → %s", len(jobs), prob.name, prob.case,
                spec.param, spec.optimizer, run_dir)
    expected = runner.log_forecast(jobs, rc.forecast_samples, int(rc.seed),
                                   rc.local_workers(), rc.job_timeout)
    bar = progress(jobs) if progress is not None else contextlib.nullcontext(None)
    try:
        with bar as on_record:
            runner.execute(jobs, run_dir, rc, on_record=on_record, expected_s=expected,
                           stale=[run_dir / io.RESULTS_FILE])
    except BaseException:  # the run is over: a later run in this process may take the folder
        lock.release(run_dir)
        raise
    path = io.collect(run_dir, [job.job_id for job in jobs])
    if rc.report:
        from penaltyrun import report  # matplotlib, scipy.stats: only when a report is written

        trust_own_modules(spec.problem, spec.problem_module, spec.problem_params)
        out = _report_folder(spec, run_dir)
        report.build_report(path, out, paper=bool(spec.report_paper))
        logger.info("report written to %s", out)
    return path


def _report_folder(spec: RunSpec, run_dir: Path) -> Path:
    """Where the report of a run goes: ``report.output``, else ``<run_dir>/report``."""
    return Path(spec.report_output) if spec.report_output else run_dir / "report"


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


__all__ = ["run_cell", "run_meta", "trust_own_modules"]
