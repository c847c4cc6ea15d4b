"""Command line: ``penaltyrun`` (Hydra app: optimize / evaluate / report / plan) and
``penaltyrun-report`` (report from Parquet files).

``penaltyrun --help`` is penaltyrun's own (:mod:`penaltyrun.cli.helptext`), ``--hydra-help``
Hydra's; flags, sweeps without ``-m`` and Hydra's own errors are checked by
:mod:`penaltyrun.cli.args`. ``mode=evaluate`` writes nothing unless ``--keep`` or
``hydra.run.dir`` is given.

Every user error (unknown names, bad values, malformed matrices) ends with one readable
line ``penaltyrun: error: <key>: <message> (allowed: ...)`` on stderr and exit code 2.
Ctrl-C (SIGINT), SIGTERM and SIGHUP end a run with one line saying how to resume it and
exit code 128 + signal number (130, 143, 129). Exit codes: :data:`EXIT_CODES`.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from penaltyrun import __version__
from penaltyrun.cli import args as cliargs
from penaltyrun.cli import helptext, modes, quickcheck, spec, userconf
from penaltyrun.cli.preflight import preflight
from penaltyrun.cli.streams import (
    ensure_utf8_mode,
    flush_stdout,
    print_error,
    print_for_reader,
    stdout_broken,
    stdout_error_line,
    watch_stdout,
)
from penaltyrun.errors import (
    EXIT_ABORTED,
    EXIT_ENVIRONMENT,
    EXIT_JOBS_FAILED,
    EXIT_USAGE,
    ConfigError,
    EnvironmentProblemError,
    ResultsUnreadableError,
    RunAbortedError,
    RunInterruptedError,
    SignalInterrupt,
    describe_os_error,
    signal_name,
)

if TYPE_CHECKING:
    from omegaconf import DictConfig

    from penaltyrun.runner.spec import RunnerOptions

logger = logging.getLogger("penaltyrun")

#: Runs of this process (several in a multirun) that ended with failed jobs.
FAILED_RUNS: list[str] = []


_plain = spec.plain
problem_params, problem_module = spec.problem_params, spec.problem_module


def run_optimize(cfg: DictConfig) -> Path:
    """Plan and run the jobs of one cell (:func:`penaltyrun.api.core.run_cell`), then print
    the run's summary line."""
    from hydra.core.hydra_config import HydraConfig

    from penaltyrun.api import core

    cell = spec.run_spec(cfg)
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    path = core.run_cell(cell, run_dir,
                         progress=lambda jobs: _progress(cell.runner, jobs, run_dir))
    summarize(path, run_dir)
    return path


def _progress(rc: RunnerOptions, jobs: list[Any], run_dir: Path) -> Any:
    """tqdm bar over the jobs on a terminal (``runner.progress``), else plain log lines."""
    from penaltyrun.cli import progress

    done = progress.finished_before(jobs, run_dir, rc.resume, rc.retry_failed)
    return progress.job_bar(len(jobs), done, progress.wanted(rc.progress),
                            workers=progress.slots(rc.as_dict(), len(jobs) - done))


def summarize(path: Path, run_dir: Path) -> dict[str, int]:
    """Print the run's summary line (ok / diverged / failed / timeout counts, where the
    errors are); a run with failed or timed-out jobs is remembered in :data:`FAILED_RUNS`
    (exit code 3)."""
    from penaltyrun import io
    from penaltyrun.jobrecord import DIVERGED, FAILED, JOB_STATUSES, NO_RESULT_STATUSES, OK, TIMEOUT

    df = io.read_results(path)
    counts = {status: int((df["status"] == status).sum()) for status in JOB_STATUSES}
    line = (f"penaltyrun: {len(df)} jobs: {counts[OK]} ok, {counts[DIVERGED]} diverged, "
            f"{counts[FAILED]} failed")
    if counts[TIMEOUT]:
        line += f", {counts[TIMEOUT]} timeout"
    if any(counts[status] for status in NO_RESULT_STATUSES):
        first = df[df["status"].isin(NO_RESULT_STATUSES)].iloc[0]
        cause = str(first["error"] or "").strip().splitlines()[:1] or ["no error text"]
        line += (f"; errors in {run_dir}/jobs/<job_id>.json and {path} (column error), "
                 f"e.g. {first['job_id']}: {cause[0]}; rerun "
                 f"{'failed and timed-out' if counts[TIMEOUT] else 'failed'} jobs with "
                 f"runner.resume=true runner.retry_failed=true")
        FAILED_RUNS.append(str(run_dir))
    print(line, file=sys.stderr, flush=True)
    return counts


def run_evaluate(cfg: DictConfig) -> dict[str, Any]:
    """Evaluate the matrices given in ``matrices.*`` (or the decision vector ``z``; with
    ``+gradient=true`` also d cost / d z) and print one JSON line."""
    from hydra.core.hydra_config import HydraConfig

    from penaltyrun import problems
    from penaltyrun.api.evaluation import evaluate_candidate
    from penaltyrun.io import strict_json

    prob = problems.make(cfg.problem.name, cfg.case, problem_params(cfg), problem_module(cfg))
    param = _plain(cfg.param) or {}
    result = evaluate_candidate(prob, _plain(cfg.matrices) or {}, _plain(cfg.scalars) or {},
                                _plain(cfg.get("z")), str(param.get("name", "full")),
                                {k: v for k, v in param.items() if k != "name"},
                                bool(cfg.get("gradient", False)))
    print(json.dumps(strict_json(result), default=str, allow_nan=False), flush=True)
    hydra_cfg = HydraConfig.get()
    if hydra_cfg.output_subdir is None:  # cliargs.evaluate_overrides: nothing was written
        print(cliargs.EVALUATE_NOTHING_WRITTEN, file=sys.stderr, flush=True)
    else:  # --keep or hydra.run.dir given
        print(f"penaltyrun: evaluate: Hydra's config and log kept in "
              f"{hydra_cfg.runtime.output_dir}", file=sys.stderr, flush=True)
    return result


def _trust_config_modules(cfg: DictConfig) -> None:
    """The modules the user's own config names (``problem.module``, an LQR plant's
    ``plant`` / ``dynamics``) may be imported by the report of this process."""
    from penaltyrun.api import core

    core.trust_own_modules(str(cfg.problem.name), problem_module(cfg), problem_params(cfg))


def run_report(cfg: DictConfig) -> Path:
    """Tables and figures from Parquet results under ``report.input``."""
    from penaltyrun import report

    if not cfg.report.input:
        raise ConfigError("report.input", "missing; pass report.input=<results.parquet or "
                          "folder>")
    src = Path(cfg.report.input)
    if not src.exists():
        raise ConfigError("report.input", f"{src} does not exist")
    out = Path(cfg.report.output) if cfg.report.output else \
        (src.parent if src.is_file() else src) / "report"
    _trust_config_modules(cfg)
    report.build_report(src, out, paper=bool(cfg.report.paper))
    print(f"report written to {out}")
    return out


def guard(func: Callable[[], Any]) -> Any:
    """Run ``func``; turn user errors into one line on stderr and exit code 2, a run that
    cannot go on into one line and exit code 4, and Ctrl-C / SIGTERM / SIGHUP into one line
    and exit code 128 + signal number (finished jobs are on disk already)."""
    try:
        return func()
    except _hydra_exception():  # (MissingConfigException is an OSError): one line by
        raise  # cliargs.hydra_errors
    except (ConfigError, FileNotFoundError, ResultsUnreadableError) as exc:
        print(f"penaltyrun: error: {exc}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    except RunAbortedError as exc:
        print(f"penaltyrun: error: {exc}", file=sys.stderr)
        sys.exit(EXIT_ABORTED)
    except EnvironmentProblemError as exc:
        print_error(str(exc))
        sys.exit(EXIT_ENVIRONMENT)
    except OSError as exc:  # any other file operation the machine refused
        broken = stdout_broken()
        print_error(stdout_error_line(broken) if broken is not None
                     else describe_os_error(exc, doing="use"))
        sys.exit(EXIT_ENVIRONMENT)
    except RunInterruptedError as exc:
        print(f"penaltyrun: {exc}", file=sys.stderr)
        sys.exit(128 + exc.signum)
    except KeyboardInterrupt as exc:
        signum = getattr(exc, "signum", int(signal.SIGINT))
        how = "interrupted" if signum == signal.SIGINT else f"stopped by {signal_name(signum)}"
        print(f"penaltyrun: {how}", file=sys.stderr)
        sys.exit(128 + signum)


class _NoHydraError(Exception):
    """Stands for Hydra's exception class while Hydra is not imported (none can be raised)."""


def _hydra_exception() -> type[Exception]:
    """Hydra's ``HydraException`` if Hydra is imported, else :class:`_NoHydraError`."""
    errors = sys.modules.get("hydra.errors")
    return errors.HydraException if errors is not None else _NoHydraError


def install_signal_handlers() -> None:
    """Handle SIGTERM and SIGHUP like Ctrl-C: raise :class:`SignalInterrupt` in the main
    thread, so workers are stopped, finished jobs kept and one line printed."""
    def handler(signum: int, frame: Any) -> None:
        raise SignalInterrupt(signum)

    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, handler)


def _discard_run_dir() -> None:
    """Remove the run directory Hydra created for a run that failed before doing anything
    (it holds only Hydra's ``.hydra/`` and the log), so a mistake leaves nothing behind.
    A directory without ``.hydra/`` is not Hydra's own, e.g. the current directory of an
    evaluation that writes nothing: it is never touched."""
    from hydra.core.hydra_config import HydraConfig

    try:
        out = Path(HydraConfig.get().runtime.output_dir)
    except (ValueError, AttributeError):
        return
    if not (out / ".hydra").is_dir() or out.resolve() == Path.cwd().resolve():
        return
    if all(p.name == ".hydra" or p.suffix == ".log" for p in out.iterdir()):
        shutil.rmtree(out, ignore_errors=True)


def _hydra_main() -> None:
    """Run the Hydra app (:func:`_task` on the config Hydra composes from ``sys.argv``).
    Hydra is imported here, after the checks that need no config
    (:mod:`penaltyrun.cli.quickcheck`)."""
    import hydra

    hydra.main(version_base="1.3", config_path="../conf", config_name="config")(_task)()


def _task(cfg: DictConfig) -> None:
    """Hydra's task: run the mode of the composed config ``cfg``."""
    def dispatch() -> Any:
        mode = modes.BY_NAME.get(cfg.mode)
        if mode is None:
            raise ConfigError("mode", f"unknown mode {cfg.mode!r}", allowed=modes.MODES)
        try:
            return mode.runner()(cfg)
        except ConfigError:
            _discard_run_dir()
            raise

    try:
        guard(dispatch)
    except Exception as exc:  # a bug in penaltyrun: a traceback, not a Hydra error line
        cliargs.mark_task_error(exc)
        raise



def use_file_backend() -> None:
    """Figures of the command line go to files only: matplotlib's non-interactive ``Agg``
    backend (unless ``MPLBACKEND`` names another), chosen before matplotlib is imported, so
    no display is needed and none is opened."""
    os.environ.setdefault("MPLBACKEND", "Agg")


def print_version(argv: list[str]) -> bool:
    """``--version``: print penaltyrun's version (Hydra would print its own); True if so."""
    if "--version" not in argv:
        return False
    print_for_reader(f"penaltyrun {__version__}")
    return True


def main() -> None:
    """Entry point of ``penaltyrun``: check the command line, then run the Hydra app.

    ``--help`` is penaltyrun's own (:mod:`penaltyrun.cli.helptext`), ``--hydra-help`` Hydra's.
    Exits with :data:`EXIT_JOBS_FAILED` (3) when a run ended with failed jobs.
    """
    ensure_utf8_mode(sys.argv)
    use_file_backend()
    logging.raiseExceptions = False  # a broken stdout is one line at the end, not tracebacks
    watch_stdout()
    argv = sys.argv[1:]
    if guard(lambda: print_version(argv)):
        return flush_stdout()
    if "--hydra-help" in argv:
        return _hydra_main()
    if helptext.wants_help(argv):
        return print_for_reader(helptext.render(argv))
    install_signal_handlers()
    argv, keep = cliargs.pop_keep(cliargs.options_first(
        guard(lambda: userconf.normalize_argv(argv))))
    guard(lambda: quickcheck.check_plain_values(argv))
    args = guard(lambda: cliargs.check_options(argv))
    parsed = guard(lambda: cliargs.check_sweeps(args.overrides, args.multirun))
    with cliargs.hydra_errors():  # Hydra's errors, also from the preflight's composition
        mode = guard(lambda: preflight(argv))
        if mode == "plan":
            from penaltyrun.cli import planmode

            if planmode.intercepts(argv):  # forecast only: Hydra runs nothing
                guard(lambda: planmode.run(argv))
                return flush_stdout()
        extra: list[str] = []
        if mode == "evaluate" and not (args.cfg or args.info or args.shell_completion):
            extra = cliargs.evaluate_overrides(parsed, args.multirun, keep)
        sys.argv = [sys.argv[0], *argv, *extra]
        guard(_hydra_main)
    flush_stdout()
    if FAILED_RUNS:
        sys.exit(EXIT_JOBS_FAILED)
