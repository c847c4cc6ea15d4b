"""Build the report (report.md, report.html, tables, figures) from Parquet results only.

Layout: the verdict first (one row and one sentence per problem × case × problem variant),
then checks (warnings, unknown statuses, non-finite evaluations, active bounds), one section
per problem case (cells, equal-budget comparisons, figures, the problem's own plots, paper
values, held-out results), the sections problems contribute, the statistics (best-known
optima, shortfall, fixed targets), and methods and conventions at the end.
"""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import storedprobe
from penaltyrun.io.filecheck import ROW, SOURCE
from penaltyrun.io.memory import release_memory
from penaltyrun.io.read import declared_rows, drop_duplicate_jobs, read_results
from penaltyrun.io.schema import config_key
from penaltyrun.jobrecord import JOB_STATUSES, NO_RESULT_STATUSES
from penaltyrun.problems import trust
from penaltyrun.report import (
    basins,
    cache,
    cases,
    controllers,
    fronts,
    fronts_section,
    holdout,
    html,
    knownopt,
    outdir,
    protocol,
    sections,
    tuning,
)
from penaltyrun.report.anytime import target_table
from penaltyrun.report.bestknown import (
    CERTIFY_RTOL,
    FIRST_ORDER_RTOL,
    best_known,
    best_labels,
    shortfall,
)
from penaltyrun.report.compare import FAMILY, NO_TEST, SPENT_RTOL, pairwise
from penaltyrun.report.fitting import fitting_rows
from penaltyrun.report.progress import Steps
from penaltyrun.report.rows import FRAME_COLUMNS, REPORT_COLUMNS, full_row, lazy, with_columns
from penaltyrun.report.stats import BCA_MAX_N, MIN_N_TEST, add_variant, cell_summary
from penaltyrun.report.tables import (
    markdown,
    markdown_split,
    md_line,
    md_text,
    write_table,
)
from penaltyrun.report.verdict import COLUMNS as VERDICT_COLUMNS
from penaltyrun.report.verdict import verdict_rows
from penaltyrun.runner.options import resolve_workers

logger = logging.getLogger(__name__)

#: Columns of ``summary.md`` / ``comparison.md`` (every column is in the CSV files).
SUMMARY_MD = ["problem", "case", "variant", "optimizer", "param", "max_evals", "mean_evals",
              "n_jobs", "n_converged", "best", "median", "mean", "worst", "std", "ci_note"]
COMPARISON_MD = ["problem", "case", "variant", "optimizer", "map_a", "map_b", "n_a", "n_b",
                 "equal_budget", "median_a", "median_b", "a12_b_beats_a", "p_mwu", "p_holm",
                 "note"]
BEST_KNOWN_COLUMNS = ["problem", "case", "problem_variant", "family", "best_known",
                      "optimizer", "param", "evidence", "n_converged"]
SHORTFALL_COLUMNS = ["problem", "case", "variant", "optimizer", "param", "n_converged",
                     "best_known", "best", "gap_best_pct", "gap_median_pct"]
TARGET_COLUMNS = ["problem", "case", "variant", "optimizer", "param", "epsilon", "n_reached",
                  "n_starts", "ert_evals", "median_evals_to_target"]
#: Every CSV table the report can write (``<stem>.csv``), with what it holds. A table is
#: written only when it has rows (e.g. no ``comparison`` without two maps of one optimizer).
TABLES = {
    "verdict": "one row per problem × case × problem variant: best-known diagonal and full "
               "costs with their evidence, gain, equal-budget tests, held-out and "
               "discretization verdicts, and the generated sentence",
    "summary": "one row per cell: jobs, converged starts, best / median / mean / worst, "
               "bootstrap intervals, budget, the paper's mean where published",
    "comparison": "map against map within one optimizer and variant: medians, A12, "
                  "Mann–Whitney p, Holm p, equal-budget flag",
    "holdout": "held-out scenarios, every problem: per cell × full map and per best-known "
               "pair, at the held-out horizon: cost ratio full/diagonal (median, 5–95 %, "
               "share cheaper, Wilcoxon on log ratios, Holm p), arrival shift, convergence "
               "at the horizon and by the training deadline, and the converged pairs",
    "discretization": "the discretization check of each cell's best diagonal and best full "
                      "start (problems that declare discretization re-runs)",
    "paper": "our cells beside the published mean / median with Mood's median test and its "
             "Holm p",
    "paper_matrices": "our best matrices against the published ones: the published "
                      "matrices' cost in our implementation and the distance of our best",
    "best_known": "the lowest converged cost per problem × case × problem variant and map "
                  "family, with its evidence",
    "shortfall": "each cell's gap to the best-known value of its map family",
    "targets": "fixed targets: share of starts reaching f* + ε·|f*| and the ERT",
    "known_optimum": "problems with a known optimum J* (lqr): starts reaching J* within "
                     "1e-6 (relative), evaluations and CPU seconds to reach it, and what "
                     "the starts spent",
    "known_optimum_ratios": "problems with a known optimum J*: the CPU ratio of the median "
                            "time to reach J* between two optimizers of one cell (a lower "
                            "bound where the first did not reach J* in most starts)",
    "holdout_tuning_modes": "multi- against single-scenario tuning, held-out gaps side by "
                            "side",
    "controllers": "the best start of each map per problem × case × variant: its closed "
                   "loop at the target (slowest real part, smallest damping ratio, gain "
                   "norm and condition number)",
    "fronts": "trade-off fronts of a sweep of the price of a second ρ: per sweep × map × "
              "start, its front (energy, arrival time) and hypervolume with the sweep's "
              "reference point",
    "fronts_tests": "per sweep × full map: hypervolumes against the diagonal map's "
                    "(Mann–Whitney, A12, Holm p) and the pooled fronts' dominance",
    "fronts_holdout": "per cell of a sweep × map: the front of training cost against mean "
                      "held-out cost over its starts, its hypervolume and dominated share",
}


def methods() -> str:
    """The conventions paragraph (at the end of the report)."""
    return (
        "A cell is problem × case × variant × optimizer × map; a variant is a set of problem "
        "parameters, a warm start or an optimizer budget of its own, and cells are never "
        "pooled across optimizers, budgets or variants. Cost statistics use **converged "
        "starts only** (a diverged start carries a graded penalty, a search aid, not a "
        "cost); the success rate stands beside them. Budget = `max_evals` (none: the "
        "optimizer's own limits) and the mean evaluations its searches spent (a polish, "
        "`optimizer.polish`, ends when it converges: its mean spend is given apart). "
        "Intervals: 95 % BCa "
        "bootstrap (scipy.stats.bootstrap, 9999 resamples, seeded) of the median; above "
        f"{BCA_MAX_N} converged starts the order-statistic interval of the median and "
        "Student's t interval of the mean; none for n < 3 or a constant sample. "
        "Best-known evidence: *certified* = reached by the grid "
        f"optimizer (grid + local search) within {CERTIFY_RTOL:g} relative; *agreement* = "
        f"k ≥ 2 different optimizers within {CERTIFY_RTOL:g}; *first-order certified local "
        f"optimum* = the best start's projected exact gradient ≤ {FIRST_ORDER_RTOL:g}·max(1, "
        "|cost|) (problems with a gradient); else *single optimizer*. "
        "Equal budget: equal `max_evals` and mean evaluations the searches spent within "
        f"{100 * SPENT_RTOL:g} %; otherwise \"{NO_TEST}\". Tests: two-sided Mann–Whitney U "
        "between two maps of one optimizer and budget; Vargha–Delaney A12 = P(a start of "
        "map b beats a start of map a) + ½ P(tie), magnitude |A12 − 0.5| ≥ 0.06 / 0.14 / "
        f"0.21 (small / medium / large); below n = {MIN_N_TEST} converged starts per group a "
        "test is underpowered. Held-out: the cost ratio J_full / J_diag over every scenario "
        "at the held-out horizon, two-sided Wilcoxon signed-rank of the log ratios; beside "
        "it the Wilcoxon test on the scenarios where both converge. A non-significant "
        "result is no evidence of a difference at that n, not evidence of equality.")


def checks(df: pd.DataFrame) -> list[str]:
    """Warning lines: unimportable modules, unknown statuses, non-finite evaluations,
    active bounds."""
    lines = [f"- {md_line(w)}" for w in protocol.WARNINGS]
    unknown = df[~df["status"].isin(JOB_STATUSES)]
    for status, g in unknown.groupby("status"):
        lines.append(f"- {len(g)} job(s) with status '{md_text(status)}', unknown to this "
                     "report: listed, never counted as converged.")
    if "n_nonfinite" in df:
        nf = pd.to_numeric(df["n_nonfinite"], errors="coerce").fillna(0)
        for (problem, case, variant, opt, param), g in df[nf > 0].groupby(
                ["problem", "case", "variant", "optimizer", "param"], sort=True):
            total = pd.to_numeric(g["n_evals"], errors="coerce").sum()
            lines.append(f"- {cases.title(problem, case, variant)} / {md_text(opt)} / "
                         f"{md_text(param)}: {int(nf[g.index].sum())} of {int(total)} "
                         "evaluations were non-finite (replaced by a penalty) in "
                         f"{len(g)} start(s).")
    for best in best_labels(df, ("problem", "case", "problem_variant")).values():
        lines += sections.active_bounds({fam: full_row(df, label)
                                         for fam, label in best.items()})
    return lines


#: Most characters of a failed job's error line the report shows.
ERROR_LINE_CHARS = 300


def _first_line(error: object) -> str:
    """The first line of a stored error text, cut at :data:`ERROR_LINE_CHARS` characters
    (a stored error of megabytes on one line is no line for a report)."""
    lines = str(error)[:ERROR_LINE_CHARS + 1].splitlines()
    line = lines[0] if lines else ""
    return line if len(line) <= ERROR_LINE_CHARS else line[:ERROR_LINE_CHARS] + " …"


#: Rows (declared in the files' footers) above which a report reads its results lazily:
#: the per-row text and list columns are read for the rows a section needs
#: (:mod:`penaltyrun.report.rows`), so memory does not grow with them.
STREAM_MIN_ROWS = 100_000


def build_report(src: Path, out: Path, paper: bool = True,
                 source_label: str | None = None,
                 basin_points: int = basins.REPORT_POINTS, stream: bool | None = None,
                 progress: bool | None = None, probe: bool = True,
                 workers: int | str = 1, cache_dir: Path | str | None = None) -> Path:
    """Write tables (CSV + Markdown), figures (PNG), ``report.md`` and ``report.html``.

    Every file is first written into a temporary folder inside ``out`` and renamed into
    place when the report is complete, so no reader sees a half-written file; files of a
    previous report in ``out`` that this one does not write are removed, and ``out`` may
    not be a symbolic link (:mod:`penaltyrun.report.outdir`). Unreadable Parquet files
    under ``src`` are skipped with a warning naming them. Nothing named in the results is
    imported or called (:mod:`penaltyrun.problems.trust`).

    Parameters
    ----------
    src : Path
        A results.parquet file or a folder searched recursively.
    out : Path
        Output folder (created).
    paper : bool
        Include the paper's numbers beside ours.
    source_label : str, optional
        How the report names its source (default ``src`` as given), e.g. a path relative
        to a repository, so that a committed report does not carry a machine's path.
    basin_points : int
        Grid points per axis of the basin-of-attraction maps (0: no maps); each map runs
        ``basin_points²`` starts of the best diagonal and the best full gain of a case.
    probe : bool
        Probe each case's best diagonal and full point for cliffs of the criterion
        (:mod:`penaltyrun.report.cliffs`; one batch of about 8 evaluations per decision
        variable each).
    stream : bool, optional
        Read the results lazily (:mod:`penaltyrun.report.rows`); default: when the files
        declare more than :data:`STREAM_MIN_ROWS` rows. The report is the same either way.
    progress : bool, optional
        Show a progress bar of the report's steps on stderr; default: when stderr is a
        terminal.
    workers : int or "auto"
        Processes writing the case sections (``auto``: one per core this process may
        use); sections of different problem cases are written side by side
        (:mod:`penaltyrun.report.parallel`). The report is the same file for file for any
        number.
    cache_dir : Path or str, optional
        Folder of the cache of case sections (:mod:`penaltyrun.report.cache`): a section
        whose rows, shared tables, options and drawing code are those of a cached one is
        copied from it instead of drawn (the same files). None: every section is drawn.
        Reports read lazily, and problem cases whose code or data lies outside penaltyrun
        (a user problem, a module named for it, a plant module or file named in its rows)
        are drawn in full either way.

    Raises
    ------
    FileNotFoundError, ResultsUnreadableError
        No results file, or none readable, under ``src``.
    ConfigError
        ``out`` is a symbolic link or a file, or ``workers`` is not a positive integer or
        ``auto``.
    """
    out = Path(out)
    n_workers = resolve_workers(workers, "workers")
    protocol.reset()
    if stream is None:
        stream = declared_rows(src) > STREAM_MIN_ROWS
    with trust.reading_results():
        # duplicates dropped after the unusable rows: a damaged copy never hides a job
        df = drop_duplicate_jobs(fitting_rows(add_variant(read_results(
            src, FRAME_COLUMNS if stream else REPORT_COLUMNS, lazy=stream, sources=True,
            checked=REPORT_COLUMNS, dedupe=False))))
        if df.empty:
            raise ResultsUnreadableError(f"no job rows under {src}: the results files hold "
                                         "none (point the report at a run's folder)")
        stored = stored_probes(df) if probe else None
        if not stream:  # the files named in fitting_rows' warnings; read whole from here
            df = df.drop(columns=[SOURCE, ROW])
        sections_cache = None
        if cache_dir is not None and not stream:
            sections_cache = cache.SectionCache.at(cache_dir)
        outdir.write_into(out, "report.output",
                          lambda tmp: _write_report(source_label or str(src), df, tmp, paper,
                                                   basin_points, progress, probe, n_workers,
                                                   sections_cache, stored),
                          lambda folder: outdir.report_files(
                              folder, [*TABLES, "summary", "comparison"]),
                          source=Path(src))
    if sections_cache is not None:
        sections_cache.prune()
    logger.info("report: %s", out / "report.md")
    return out


def _write_report(src: str, df: pd.DataFrame, out: Path, paper: bool,
                  basin_points: int = basins.REPORT_POINTS,
                  progress: bool | None = None, probe: bool = True, workers: int = 1,
                  sections_cache: cache.SectionCache | None = None,
                  stored: pd.DataFrame | None = None) -> None:
    """Write every file of the report into ``out`` (see :func:`build_report`; ``stored``:
    :func:`stored_probes`)."""
    n_cases = df.groupby(cases.CASE_KEYS, sort=True).ngroups
    with Steps(len(STEPS) + n_cases, progress, lazy(df) and release_memory) as steps:
        _write_files(src, df, out, paper, basin_points, steps, n_cases, probe, workers,
                     sections_cache, stored)


def stored_probes(df: pd.DataFrame) -> pd.DataFrame:
    """The cliff probes stored beside the results files of ``df`` (its :data:`SOURCE`
    column; :mod:`penaltyrun.io.storedprobe`) of starts in ``df``, with each start's
    ``problem`` and ``case`` (so that a cached section's key holds its own case's)."""
    stored = storedprobe.read_beside(df[SOURCE].dropna().unique())
    if stored.empty:  # none beside these files: no copy of the frame's keys
        return stored.assign(problem=pd.Series(dtype=object), case=pd.Series(dtype=object))
    starts = df[["job_id", "config_hash", "problem", "case"]].copy()
    starts["config_hash"] = [config_key(h) for h in starts["config_hash"]]
    return stored.merge(starts.drop_duplicates(["job_id", "config_hash"]),
                        on=["job_id", "config_hash"], how="inner")


#: The report's steps besides one per case section (what its progress bar counts).
STEPS = ("cell statistics", "comparisons", "best-known optima", "held-out", "verdict",
         "paper and controller tables", "checks", "contributed sections",
         "tuning modes", "statistics", "report.md and report.html")


def _write_files(src: str, df: pd.DataFrame, out: Path, paper: bool, basin_points: int,
                 steps: Steps, n_cases: int, probe: bool = True, workers: int = 1,
                 sections_cache: cache.SectionCache | None = None,
                 stored: pd.DataFrame | None = None) -> None:
    """:func:`_write_report` with its progress bar ``steps``."""
    steps.step(STEPS[0])
    summary = cell_summary(df)
    summary.to_csv(out / "summary.csv", index=False, encoding="utf-8")
    (out / "summary.md").write_text(markdown_split(summary[SUMMARY_MD]) + "\n",
                                    encoding="utf-8")
    steps.step(STEPS[1])
    comp = pairwise(df)
    if not comp.empty:
        comp.to_csv(out / "comparison.csv", index=False, encoding="utf-8")
        (out / "comparison.md").write_text(markdown_split(comp[COMPARISON_MD]) + "\n",
                                           encoding="utf-8")
    steps.step(STEPS[2])
    bk = best_known(df)
    steps.step(STEPS[3])
    held, imps = holdout.holdout_rows(df)
    if not held.empty:
        held.to_csv(out / "holdout.csv", index=False, encoding="utf-8")
    steps.step(STEPS[4])
    verdict = verdict_rows(df, bk, comp, held)
    steps.step(STEPS[5])
    ctx = {"summary": summary, "comp": comp, "bk": bk, "held": held, "imps": imps,
           "basin_points": int(basin_points), "probe": bool(probe), "cache": sections_cache,
           "probes": stored if stored is not None else pd.DataFrame(),
           "paper": sections.paper_rows(df) if paper else pd.DataFrame(),
           "paper_matrices": sections.paper_matrix_tables(df) if paper else {}}
    _write_csv(ctx["paper"], out, "paper")
    if paper:
        _write_csv(sections.paper_matrix_rows(ctx["paper_matrices"]), out, "paper_matrices")
    _write_csv(holdout.discretization_rows(df), out, "discretization")
    _write_csv(controllers.csv_rows(df), out, "controllers")
    lines = ["# penaltyrun report", "",
             f"Source: `{src}` — {len(df)} jobs, {df['run_id'].nunique()} run(s).", ""]
    if not verdict.empty:
        verdict.to_csv(out / "verdict.csv", index=False, encoding="utf-8")
        lines += ["## Verdict: does a full matrix beat the diagonal one?", "",
                  markdown(verdict, VERDICT_COLUMNS), ""]
        lines += [f"- {md_line(s)}" for s in verdict["sentence"]] + [""]
        lines += ["Gain = (diagonal − full)/diagonal of the best-known costs; equal budget: "
                  "A12 = P(a full start beats a diagonal start), Holm-corrected; held-out: "
                  "the best-known starts paired on the problem's held-out scenarios at the "
                  "held-out horizon (J_full / J_diag over every scenario). Details per case "
                  "below; methods at the end.", ""]
    steps.step(STEPS[6])
    body = checks(df)
    if body:
        lines += ["## Checks", ""] + body + [""]
    written = iter(range(1, n_cases + 1))
    for section in cases.write_sections(
            df, ctx, out, paper, workers,
            lambda name: steps.step(f"case {next(written)}/{n_cases}: {name}")):
        lines += section
    steps.step(STEPS[7])
    lines += sections.contributed(df, out)
    front_tables = fronts.fronts_of(df)
    fronts.write(front_tables, out)
    lines += fronts_section.section(front_tables, comp, out)
    steps.step(STEPS[8])
    try:
        lines += tuning.study_sections(df, out, paper)
    except Exception as exc:  # one study must not lose the rest of the report
        logger.warning("tuning-mode section failed: %s", exc)
        lines += [f"(tuning-mode section failed: {exc!r})", ""]
    steps.step(STEPS[9])
    lines += _statistics(df, bk, out)
    failed = with_columns(df[df["status"].isin(NO_RESULT_STATUSES)], ("error",))
    if not failed.empty:
        lines += ["## Failed jobs", ""]
        lines += [f"- {md_text(r.job_id)} ({md_text(r.status)}): "
                  f"{md_text(_first_line(r.error)) if r.error else ''}"
                  for r in failed.itertuples()]
        lines.append("")
    commits = ", ".join(md_text(c) for c in sorted(map(str, df["git_commit"].dropna().unique()))
                        ) or "unknown"
    lines += ["## Methods and conventions", "", methods(), "",
              f"Code commit(s) of these results: {commits}.", ""]
    steps.step(STEPS[10])
    text = "\n".join(lines) + "\n"
    (out / "report.md").write_text(text, encoding="utf-8")
    html.write_html(text, out, out / "report.html")


def _write_csv(table: pd.DataFrame, out: Path, stem: str) -> None:
    """``<stem>.csv`` of one of :data:`TABLES` when it has rows (the report shows it in
    Markdown in the case sections)."""
    if stem not in TABLES:
        raise KeyError(f"{stem!r} is not a report table")
    if not table.empty:
        table.to_csv(out / f"{stem}.csv", index=False, encoding="utf-8")


def _statistics(df: pd.DataFrame, bk: pd.DataFrame, out: Path) -> list[str]:
    lines = ["## Statistics", "",
             f"Holm families: (1) {FAMILY}; (2) {holdout.FAMILY}; (3) "
             f"{sections.PAPER_FAMILY}. Raw p-values are in the CSV files.", ""]
    if not bk.empty:
        lines += ["### Best-known optima", "",
                  "Lowest converged cost per problem × case × problem variant and map family "
                  "over every optimizer, budget and warm start, with its evidence.", "",
                  write_table(bk, out, "best_known", BEST_KNOWN_COLUMNS), ""]
        gaps = shortfall(df, bk)
        if not gaps.empty:
            lines += ["### Optimizer shortfall against the best-known value of the map family",
                      "", "gap = (cell best or median − best-known)/best-known, %, converged "
                      "starts.", "", write_table(gaps, out, "shortfall", SHORTFALL_COLUMNS), ""]
    targets = target_table(df, bk)
    if not targets.empty:
        lines += ["### Fixed targets: ERT and success share", "",
                  "Target f* + ε·|f*|, f* the best-known of the map's own family. ERT (COCO): "
                  "evaluations spent by all starts, each counted until it reached the target "
                  "or stopped, divided by the number of starts that reached it (∞ if none).",
                  "", write_table(targets, out, "targets", TARGET_COLUMNS), ""]
    reach = knownopt.reach_table(df)
    if not reach.empty:
        lines += ["### Time to the known optimum", "",
                  f"Cells whose problem knows its optimum J*: starts whose best-so-far came "
                  f"within {knownopt.RTOL:g}·|J*| of J*, the evaluations and CPU seconds "
                  "(`trace_cpu_s`) until then, and the least CPU a start spent in all (a "
                  "lower bound where no start reached J*); gap = best/J* − 1.", "",
                  write_table(reach, out, "known_optimum", knownopt.COLUMNS), ""]
        ratios = knownopt.ratio_table(reach)
        if not ratios.empty:
            lines += ["CPU ratio a / b of the median time to reach J* over every start ('>': "
                      "a did not reach J* in most starts, its starts count with the CPU they "
                      "spent, so the ratio is a lower bound).", "",
                      write_table(ratios, out, "known_optimum_ratios",
                                  knownopt.RATIO_COLUMNS), ""]
    return lines
