"""Command line: ``penaltyrun`` (Hydra app: optimize / evaluate / report / plan) and
``penaltyrun-report`` (report from Parquet files).

``penaltyrun --help`` is penaltyrun's own (:mod:`penaltyrun.clihelp`), ``--hydra-help``
Hydra's; flags, sweeps without ``-m`` and Hydra's own errors are checked by
:mod:`penaltyrun.cliargs`. ``mode=evaluate`` writes nothing unless ``--keep`` or
``hydra.run.dir`` is given.

Every user error (unknown names, bad values, malformed matrices) ends with one readable
line ``penaltyrun: error: <key>: <message> (allowed: ...)`` on stderr and exit code 2.
Ctrl-C (SIGINT), SIGTERM and SIGHUP end a run with one line saying how to resume it and
exit code 128 + signal number (130, 143, 129). Exit codes: :data:`EXIT_CODES`.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import shutil
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from penaltyrun import __version__, cells, checks, cliargs, clihelp, quickcheck, userconf
from penaltyrun.errors import (
    ConfigError,
    EnvironmentProblemError,
    ResultsUnreadableError,
    RunAbortedError,
    RunInterruptedError,
    SignalInterrupt,
    describe_os_error,
    signal_name,
)
from penaltyrun.preflight import preflight
from penaltyrun.streams import (
    EXIT_ENVIRONMENT,
    end_if_pipe_closed,
    ensure_utf8_mode,
    flush_stdout,
    print_error,
    print_for_reader,
    stdout_broken,
    stdout_error_line,
    watch_stdout,
)

if TYPE_CHECKING:
    from omegaconf import DictConfig

logger = logging.getLogger("penaltyrun")

MODES = checks.MODES
EXIT_OK = 0
EXIT_USAGE = 2
EXIT_JOBS_FAILED = 3
EXIT_ABORTED = 4
EXIT_INTERRUPTED = 130
#: Exit code → meaning (also in README "Errors and exit codes").
EXIT_CODES = {
    EXIT_OK: "success (every job recorded ok or diverged)",
    1: "internal error (a bug: please report the traceback)",
    EXIT_USAGE: "bad command line or config, a run directory in use by another run, or no "
                "readable results (one line on stderr)",
    EXIT_JOBS_FAILED: "the run finished but at least one job is recorded `failed` or "
                      "`timeout`",
    EXIT_ABORTED: "the run could not go on (dask: scheduler lost or no worker for "
                  "runner.worker_timeout s); finished jobs are kept",
    EXIT_ENVIRONMENT: "the machine refused a file operation (disk full, no permission, "
                      "read-only file system, output not writable): one line naming the "
                      "path; finished jobs are kept",
    128 + signal.SIGINT: "stopped by Ctrl-C (SIGINT); finished jobs are kept",
    128 + signal.SIGTERM: "stopped by SIGTERM; finished jobs are kept",
    128 + signal.SIGHUP: "stopped by SIGHUP; finished jobs are kept",
}
#: Runs of this process (several in a multirun) that ended with failed jobs.
FAILED_RUNS: list[str] = []


_plain = cells.plain
problem_params, problem_module, _setup = cells.problem_params, cells.problem_module, cells.setup


def run_optimize(cfg: DictConfig) -> Path:
    """Plan and run the jobs of one cell (:func:`penaltyrun.api.core.run_cell`), then print
    the run's summary line."""
    from hydra.core.hydra_config import HydraConfig

    from penaltyrun.api import core

    spec = cells.cell_spec(cfg)
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    path = core.run_cell(spec, run_dir, progress=lambda jobs: _progress(cfg, jobs, run_dir))
    summarize(path, run_dir)
    return path


def _progress(cfg: DictConfig, jobs: list[Any], run_dir: Path) -> Any:
    """tqdm bar over the jobs on a terminal (``runner.progress``), else plain log lines."""
    from penaltyrun import progress

    rc = cfg.runner
    done = progress.finished_before(jobs, run_dir, bool(rc.resume), bool(rc.retry_failed))
    return progress.job_bar(len(jobs), done, progress.wanted(rc.get("progress", "auto")),
                            workers=progress.slots(rc, len(jobs) - done))


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

    prob = problems.make(cfg.problem.name, cfg.case, problem_params(cfg), problem_module(cfg))
    param = _plain(cfg.param) or {}
    result = evaluate_candidate(prob, _plain(cfg.matrices) or {}, _plain(cfg.scalars) or {},
                                _plain(cfg.get("z")), str(param.get("name", "full")),
                                {k: v for k, v in param.items() if k != "name"},
                                bool(cfg.get("gradient", False)))
    print(json.dumps(result, default=str), flush=True)
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


def _guard(func: Callable[[], Any]) -> Any:
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
    (:mod:`penaltyrun.quickcheck`)."""
    import hydra

    hydra.main(version_base="1.3", config_path="conf", config_name="config")(_task)()


def _task(cfg: DictConfig) -> None:
    """Hydra's task: run the mode of the composed config ``cfg``."""
    def dispatch() -> Any:
        if cfg.mode not in MODES:
            raise ConfigError("mode", f"unknown mode {cfg.mode!r}", allowed=MODES)
        try:
            return {"optimize": run_optimize, "evaluate": run_evaluate, "report": run_report,
                    "plan": _print_cell_plan}[cfg.mode](cfg)
        except ConfigError:
            _discard_run_dir()
            raise

    try:
        _guard(dispatch)
    except Exception as exc:  # a bug in penaltyrun: a traceback, not a Hydra error line
        cliargs.mark_task_error(exc)
        raise


def _print_cell_plan(cfg: DictConfig) -> None:
    from penaltyrun import planmode

    planmode.print_cell_plan(cfg)


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

    ``--help`` is penaltyrun's own (:mod:`penaltyrun.clihelp`), ``--hydra-help`` Hydra's.
    Exits with :data:`EXIT_JOBS_FAILED` (3) when a run ended with failed jobs.
    """
    ensure_utf8_mode(sys.argv)
    use_file_backend()
    logging.raiseExceptions = False  # a broken stdout is one line at the end, not tracebacks
    watch_stdout()
    argv = sys.argv[1:]
    if _guard(lambda: print_version(argv)):
        return flush_stdout()
    if "--hydra-help" in argv:
        return _hydra_main()
    if clihelp.wants_help(argv):
        return print_for_reader(clihelp.render(argv))
    install_signal_handlers()
    argv, keep = cliargs.pop_keep(cliargs.options_first(userconf.normalize_argv(argv)))
    _guard(lambda: quickcheck.check_plain_values(argv))
    args = _guard(lambda: cliargs.check_options(argv))
    parsed = _guard(lambda: cliargs.check_sweeps(args.overrides, args.multirun))
    with cliargs.hydra_errors():  # Hydra's errors, also from the preflight's composition
        mode = _guard(lambda: preflight(argv))
        if mode == "plan":
            from penaltyrun import planmode

            if planmode.intercepts(argv):  # forecast only: Hydra runs nothing
                _guard(lambda: planmode.run(argv))
                return flush_stdout()
        extra: list[str] = []
        if mode == "evaluate" and not (args.cfg or args.info or args.shell_completion):
            extra = cliargs.evaluate_overrides(parsed, args.multirun, keep)
        sys.argv = [sys.argv[0], *argv, *extra]
        _guard(_hydra_main)
    flush_stdout()
    if FAILED_RUNS:
        sys.exit(EXIT_JOBS_FAILED)


def report_main(argv: list[str] | None = None) -> None:
    """Entry point of ``penaltyrun-report INPUT [-o OUTPUT] [--no-paper] [--export DIR]``."""
    parser = argparse.ArgumentParser(
        prog="penaltyrun-report",
        description="Tables and figures from penaltyrun results (Parquet only).")
    parser.add_argument("input", help="results.parquet or a folder searched recursively")
    parser.add_argument("-o", "--output", help="output folder (default <input>/report)")
    parser.add_argument("--no-paper", action="store_true",
                        help="leave out the paper's numbers")
    parser.add_argument("--export", metavar="DIR",
                        help="also write each cell's best matrices to DIR as JSON and MATLAB "
                             ".mat files (with index.csv)")
    parser.add_argument("--problem-module", metavar="NAME=MODULE", action="append",
                        default=[],
                        help="run the report hooks of user problem NAME from MODULE (its "
                             "folder on PYTHONPATH); without it, reading results imports no "
                             "module named in them (repeatable)")
    parser.add_argument("--plant-module", metavar="MODULE", action="append", default=[],
                        help="import MODULE for an LQR plant or dynamics the results name "
                             "(module:function), to draw its figures (repeatable)")
    parser.add_argument("--basin-points", metavar="N", type=int, default=None,
                        help="grid points per axis of the basin-of-attraction maps of the "
                             "best diagonal and full gains (default 16; 0: no maps)")
    parser.add_argument("--version", action="version", version=f"penaltyrun {__version__}")
    if argv is None:
        ensure_utf8_mode(sys.argv)
    use_file_backend()
    watch_stdout()
    try:
        args = parser.parse_args(argv)
    except SystemExit:  # --help, --version or a usage error: printed already
        end_if_pipe_closed()
        raise
    from penaltyrun import problems, report

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    install_signal_handlers()
    src = Path(args.input)

    def build() -> None:
        if not src.exists():
            raise ConfigError("input", f"{src} does not exist")
        checks.check_output_dir(args.output, "-o")
        for item in args.problem_module:
            name, sep, module_path = item.partition("=")
            if not sep or not name.strip():
                raise ConfigError("--problem-module", f"{item!r} is not NAME=MODULE (e.g. "
                                  "--problem-module cartpole=mylab.problems.cartpole)")
            problems.register(name.strip(), module_path)
        for module_path in args.plant_module:
            problems.trust.allow_module(module_path)
        out = Path(args.output) if args.output else \
            (src.parent if src.is_file() else src) / "report"
        maps = {} if args.basin_points is None else {"basin_points": args.basin_points}
        if maps and not (maps["basin_points"] == 0 or 2 <= maps["basin_points"] <= 200):
            raise ConfigError("--basin-points", f"must be 0 (no maps) or 2 to 200, got "
                              f"{args.basin_points}")
        report.build_report(src, out, paper=not args.no_paper, **maps)
        print(f"report written to {out}")
        if args.export:
            _export(src, Path(args.export))

    _guard(build)
    flush_stdout()


def _export(src: Path, out: Path) -> None:
    """``penaltyrun-report --export DIR``: best matrices of each cell as JSON and .mat."""
    from penaltyrun.report.export import export_best

    files = export_best(src, out)
    print(f"best matrices of {(len(files) - 1) // 2} cells exported to {out}")


if __name__ == "__main__":
    main()
