"""``python -m penaltyrun.docsgen`` — the documentation machinery's command line.

Commands (every one takes ``--root``, the repository root, default the current folder):

* ``reference OUT``: write the generated reference pages into folder ``OUT`` (MkDocs gets
  them from :mod:`penaltyrun.docsgen.mkdocs_hook` at build time);
* ``results``: regenerate ``docs/results/*.md``, the README's answer table, the explanation
  pages rendered from data and their figures (:mod:`penaltyrun.docsgen.explanation`);
* ``check``: exit 1, listing the differing lines, if those files differ from a fresh
  rendering or a figure they link to is missing (``make check-docs``);
  ``results --only PREFIX`` / ``check --only PREFIX`` handle only the generated files whose
  path starts with ``PREFIX`` (e.g. ``docs/explanation``; ``check`` then leaves the study
  tables out);
* ``study list`` / ``study run NAME`` / ``study merge NAME``: run a study (resumable) and
  merge its data and tables into ``studies/NAME`` (``make study-NAME``); ``--only SUBDIR``
  runs one of its commands, ``--extend`` keeps the records already merged (a command
  added to a committed study, run alone);
* ``study rejudge NAME``: re-evaluate the study's stored best matrices on the held-out set at
  the held-out horizon, write ``studies/NAME/holdout_long.parquet`` and the tables
  (:mod:`penaltyrun.docsgen.rejudge`; ``--jobs paired`` re-judges only the paired starts);
* ``study probe NAME``: probe each problem × case's best diagonal and full point for cliffs
  of the criterion (one variable at a time, steps of 1e-6 to 1e-3 of its range) and write
  ``studies/NAME/probe.csv`` (:mod:`penaltyrun.docsgen.probe`);
* ``study store-probes NAME``: probe the points the report probes (each problem × case ×
  variant's best diagonal and full start) and store them in ``studies/NAME/probe.parquet``,
  which every later report of the study reads instead of evaluating them again
  (:mod:`penaltyrun.io.storedprobe`);
* ``study tables NAME``: rebuild ``studies/NAME/tables`` from the committed data (after a
  report change; nothing is re-run).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from penaltyrun.docsgen import probe, rejudge, resultpages, studies
from penaltyrun.errors import ConfigError
from penaltyrun.runner.options import workers_argument


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the exit code."""
    parser = argparse.ArgumentParser(prog="python -m penaltyrun.docsgen")
    parser.add_argument("--root", type=Path, default=Path("."), help="repository root")
    sub = parser.add_subparsers(dest="command", required=True)
    ref = sub.add_parser("reference", help="write the generated reference pages")
    ref.add_argument("out", type=Path)
    for name, text in (("results", "regenerate docs/results, the README answer table and "
                                    "the reference pages"),
                       ("check", "fail if the generated docs differ from the data")):
        command = sub.add_parser(name, help=text)
        command.add_argument("--no-reference", action="store_true",
                             help="leave out the reference pages generated from the code")
        command.add_argument("--only", metavar="PREFIX",
                             help="only the generated files whose path starts with PREFIX "
                             "(e.g. docs/explanation); check then skips the study tables")
    study = sub.add_parser("study", help="run or merge a study")
    study.add_argument("action", choices=("list", "run", "merge", "rejudge", "probe",
                                          "store-probes", "tables"))
    study.add_argument("name", nargs="?")
    study.add_argument("--run-dir", type=Path, help="fixed run directory "
                       "(default outputs/studies/NAME)")
    study.add_argument("--resume", default="false", choices=("true", "false"))
    study.add_argument("--workers", default="auto",
                       help="worker processes: a positive integer or auto (all cores)")
    study.add_argument("--reduced", action="store_true",
                       help="each command's reduced overrides (few starts, tiny budgets)")
    study.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                       help="override appended to every command (repeatable)")
    study.add_argument("--dest", type=Path, help="where results and tables go "
                       "(default studies/NAME)")
    study.add_argument("--no-tables", action="store_true", help="skip the report tables")
    study.add_argument("--only", action="append", default=[], metavar="SUBDIR", dest="subdirs",
                       help="run: only the command of this subdir (repeatable)")
    study.add_argument("--extend", action="store_true",
                       help="run/merge: keep the records already merged in the study "
                       "folder beside the run directory's (a command added to a committed "
                       "study, run alone)")
    study.add_argument("--jobs", default="all", choices=rejudge.SELECTIONS,
                       help="rejudge: every job with held-out data, or only the starts the "
                       "held-out tables pair")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    root = args.root.resolve()
    if args.command == "reference":
        from penaltyrun.docsgen.reference import pages
        for rel, text in pages().items():
            path = args.out / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        return 0
    if args.command == "results":
        for rel in resultpages.render_all(root, reference=not args.no_reference,
                                            only=args.only):
            print(f"wrote {rel}")
        return 0
    if args.command == "check":
        problems = resultpages.check(root, reference=not args.no_reference,
                                       tables=not args.only, only=args.only)
        for problem in problems:
            print(problem, file=sys.stderr)
        if problems:
            print(f"check-docs: {len(problems)} generated file(s) differ from the committed "
                  "data; run `make docs-results` and commit", file=sys.stderr)
            return 1
        print("check-docs: every generated number matches the committed data")
        return 0
    if args.action == "list":
        for name in studies.list_studies(root):
            print(f"{name}: {studies.load_study(root, name).title}")
        return 0
    if not args.name:
        parser.error("study run/merge/rejudge/probe/store-probes/tables needs a NAME")
    try:
        workers = workers_argument(args.workers)
        if args.action == "run":
            studies.run_study(root, args.name, run_dir=args.run_dir,
                              resume=args.resume == "true", workers=workers,
                              reduced=args.reduced, extra=args.set, dest=args.dest,
                              tables=not args.no_tables, only=args.subdirs,
                              extend=args.extend)
        elif args.action == "tables":
            studies.rebuild_tables(root, args.name)
        elif args.action == "rejudge":
            rejudge.rejudge_study(root, args.name, jobs=args.jobs, workers=workers,
                                  tables=not args.no_tables)
        elif args.action == "probe":
            probe.probe_study(root, args.name, workers=workers)
        elif args.action == "store-probes":
            probe.store_probes(root, args.name, workers=workers)
        else:
            studies.merge_study(root, args.name, run_dir=args.run_dir, dest=args.dest,
                                tables=not args.no_tables, extend=args.extend)
    except (studies.StudyError, ConfigError) as exc:
        print(f"penaltyrun: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
