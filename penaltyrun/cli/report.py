"""``penaltyrun-report INPUT [-o OUTPUT]``: tables and figures from Parquet results.

The same errors and exit codes as ``penaltyrun`` (:func:`penaltyrun.cli.app.guard`).
``python -m penaltyrun.report_cli`` runs it too, with the current folder taken off
``sys.path`` first (a received results folder may hold files named like modules).
"""

from __future__ import annotations

import argparse
import logging
import sys
import warnings
from pathlib import Path

from penaltyrun import __version__
from penaltyrun.cli.app import guard, install_signal_handlers, use_file_backend
from penaltyrun.cli.streams import end_if_pipe_closed, ensure_utf8_mode, flush_stdout, watch_stdout
from penaltyrun.errors import ConfigError


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
    parser.add_argument("--no-probe", action="store_true",
                        help="leave out the probe of each case's best diagonal and full "
                             "point for cliffs of the criterion (each variable moved alone "
                             "by 1e-6 to 1e-3 of its range)")
    parser.add_argument("--workers", metavar="N", default="auto",
                        help="processes writing the case sections side by side: a positive "
                             "integer or auto (default: one per core); the report is the "
                             "same for any number")
    parser.add_argument("--cache-dir", metavar="DIR", default=None,
                        help="folder of the cache of drawn case sections: a section whose "
                             "rows, tables, options and code are unchanged is copied, not "
                             "drawn again (default $PENALTYRUN_CACHE_DIR, else "
                             "$XDG_CACHE_HOME/penaltyrun or ~/.cache/penaltyrun)")
    parser.add_argument("--no-cache", action="store_true",
                        help="draw every section; read and write no cache")
    parser.add_argument("--progress", choices=("auto", "true", "false"), default="auto",
                        help="progress bar of the report's steps on stderr (auto: on a "
                             "terminal only; as runner.progress for runs)")
    parser.add_argument("--version", action="version", version=f"penaltyrun {__version__}")

    def one_line_error(message: str) -> None:  # argparse prints its usage block besides
        print(f"penaltyrun-report: error: {message} (see penaltyrun-report --help)",
              file=sys.stderr)
        sys.exit(2)

    parser.error = one_line_error  # type: ignore[method-assign]
    if argv is None:
        ensure_utf8_mode(sys.argv)
    use_file_backend()
    watch_stdout()
    try:
        args = parser.parse_args(argv)
    except SystemExit:  # --help, --version or a usage error: printed already
        end_if_pipe_closed()
        raise
    from penaltyrun.safepath import ignore_folder_config

    ignore_folder_config()  # before the report imports numba and matplotlib
    from penaltyrun import problems, report
    from penaltyrun.cli import progress
    from penaltyrun.io.memory import lean_process_memory

    lean_process_memory()

    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    install_signal_handlers()
    src = Path(args.input)

    def build() -> None:
        if not src.exists():
            raise ConfigError("input", f"{src} does not exist")
        from penaltyrun.cli.checks import check_output_dir
        from penaltyrun.runner.options import workers_argument

        check_output_dir(args.output, "-o")
        if args.export:  # refused before the report is written, not after
            from penaltyrun.report import outdir

            outdir.check(Path(args.export), "--export", src)
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
        workers = workers_argument(args.workers)
        if args.no_cache and args.cache_dir is not None:
            raise ConfigError("--no-cache", "give either --no-cache or --cache-dir, not both")
        from penaltyrun.report.cache import default_dir

        cache_dir = None if args.no_cache else Path(args.cache_dir or default_dir())
        with warnings.catch_warnings():
            # numpy's and matplotlib's arithmetic warnings on extreme stored values (a cost
            # of -1e308 squared) are no message for the user: the report's own checks
            # name non-finite values, and a figure that cannot be drawn is a warning line
            warnings.simplefilter("ignore", RuntimeWarning)
            report.build_report(src, out, paper=not args.no_paper,
                                progress=progress.wanted(args.progress),
                                probe=not args.no_probe, workers=workers,
                                cache_dir=cache_dir, **maps)
        print(f"report written to {out}")
        if args.export:
            _export(src, Path(args.export))

    guard(build)
    flush_stdout()


def _export(src: Path, out: Path) -> None:
    """``penaltyrun-report --export DIR``: best matrices of each cell as JSON and .mat."""
    from penaltyrun.report.export import export_best

    files = export_best(src, out)
    print(f"best matrices of {(len(files) - 1) // 2} cells exported to {out}")
