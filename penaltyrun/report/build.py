"""Build the report (tables + figures + report.md) from Parquet results only."""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.io import read_results
from penaltyrun.report import figures, sections
from penaltyrun.report.anytime import target_table
from penaltyrun.report.bestknown import CERTIFY_RTOL, best_known, improvement, shortfall
from penaltyrun.report.compare import FAMILY, full_worse_rows, pairwise
from penaltyrun.report.paper import MEAN_COST
from penaltyrun.report.stats import MIN_N_TEST, add_variant, cell_summary
from penaltyrun.report.tables import write_table
from penaltyrun.report.units import cost_label

logger = logging.getLogger(__name__)

SUMMARY_COLUMNS = [
    "problem", "case", "variant", "optimizer", "param", "max_evals", "n_jobs", "n_converged",
    "success_rate", "best", "median", "median_ci95_lo", "median_ci95_hi", "mean",
    "mean_ci95_lo", "mean_ci95_hi", "worst", "std", "ci_note", "mean_evals", "paper_mean",
]
COMPARISON_COLUMNS = [
    "problem", "case", "variant", "optimizer", "map_a", "map_b", "n_a", "n_b", "success_a",
    "success_b", "median_a", "median_b", "median_change_pct", "a12_b_beats_a",
    "a12_magnitude", "p_mwu", "p_holm", "note",
]
BEST_KNOWN_COLUMNS = ["problem", "case", "problem_variant", "family", "best_known",
                      "optimizer", "param", "job_id", "certified", "certified_by",
                      "n_converged", "matrices"]
SHORTFALL_COLUMNS = ["problem", "case", "variant", "optimizer", "param", "n_converged",
                     "n_jobs", "best_known", "best", "median", "gap_best_pct",
                     "gap_median_pct"]
TARGET_COLUMNS = ["problem", "case", "variant", "optimizer", "param", "epsilon", "target",
                  "n_starts", "n_reached", "share_reached", "ert_evals",
                  "median_evals_to_target"]

METHODS = (
    "Conventions (spec/statistics.md). A cell is problem × case × variant × optimizer × map; "
    "a variant is a set of problem parameters, a warm start or an optimizer budget of its "
    "own, and cells are never pooled across optimizers, budgets or variants. Cost "
    "statistics use **converged starts only** (a diverged start carries a graded penalty, "
    "which is a search aid, not a cost); the success rate stands beside them. Intervals: "
    "95 % BCa bootstrap (scipy.stats.bootstrap, 9999 resamples, seeded) of the median and "
    "the mean; none for n < 3 or constant samples. Tests: two-sided Mann–Whitney U between "
    "two maps of the same optimizer and budget; effect size Vargha–Delaney A12 = P(a start "
    f"of map b beats a start of map a) + ½ P(tie), magnitude by |A12 − 0.5| ≥ 0.06 / 0.14 "
    f"/ 0.21 (small / medium / large); p-values Holm-corrected over {FAMILY}. Below "
    f"n = {MIN_N_TEST} converged starts per group a test is underpowered, and the table "
    "says so.")


def why_full_worse(df: pd.DataFrame, row: pd.Series) -> str:
    """Explain a cell where the best full start is worse than the best diagonal start."""
    sel = df[(df["problem"] == row["problem"]) & (df["case"] == row["case"])
             & (df["variant"] == row["variant"]) & (df["optimizer"] == row["optimizer"])
             & (df["param"] == row["full_map"])]
    stops = sel["stop_reason"].value_counts().to_dict()
    variant = f" [{row['variant']}]" if row["variant"] else ""
    return (f"- **{row['problem']} / {row['case']}{variant} / {row['optimizer']} / "
            f"{row['full_map']}**: best full "
            f"{row['full_best']:.6g} > best diagonal {row['diag_best']:.6g}. The diagonal set "
            f"is contained in the full set, so this is an optimizer shortfall, not a property "
            f"of the parameterization: stop reasons of the full starts {stops}, mean "
            f"evaluations {sel['n_evals'].mean():.0f} for {sel['best_z'].dropna().map(len).max()} "
            f"variables. A larger budget (optimizer.max_evals) is needed.")


_why_full_worse = why_full_worse  # the name before the report used pairwise comparisons


def _best_known_lines(bk: pd.DataFrame, out: Path, df: pd.DataFrame) -> list[str]:
    if bk.empty:
        return []
    imp = improvement(bk)
    lines = ["## Best-known optima", "",
             "Lowest converged cost per problem × case × problem variant and map family "
             "(diagonal; full = any orthogonal map), over every optimizer, budget and warm "
             f"start. *Certified*: reached by the grid optimizer, or by two different "
             f"optimizers within {CERTIFY_RTOL:g} relative.", "",
             write_table(bk, out, "best_known", BEST_KNOWN_COLUMNS), ""]
    if not imp.empty:
        lines += ["### Improvement: best-known full vs best-known diagonal", "",
                  "A claim about the maps holds only as far as the diagonal value is certified; "
                  "per-optimizer distributions at equal budget are in the map-vs-map table.",
                  "", write_table(imp, out, "best_known_improvement"), ""]
    gaps = shortfall(df, bk)
    if not gaps.empty:
        lines += ["### Optimizer shortfall against the best-known value of the map family", "",
                  "gap = (cell best or median − best-known)/best-known over converged starts. "
                  "For a diagonal cell the gap is the optimizer's failure to reach the "
                  "diagonal optimum, not a gain of any full map.", "",
                  write_table(gaps, out, "shortfall", SHORTFALL_COLUMNS), ""]
    return lines


def _figures(g: pd.DataFrame, bk: pd.DataFrame, out: Path, stem: str, title: str,
             paper: bool) -> list[str]:
    first = g.iloc[0]
    label = cost_label(first["problem"], first["problem_params"], first["case"])
    lines = []
    for name, path in (
            ("anytime", figures.anytime(g, bk, label, title, out / f"anytime_{stem}.png")),
            ("ECDF", figures.ecdf_figure(g, bk, title, out / f"ecdf_{stem}.png")),
            ("costs", figures.cost_distribution(
                g, label, f"{title}: best cost per converged start", out / f"costs_{stem}.png",
                MEAN_COST.get((first["problem"], first["case"])) if paper else None))):
        if path is not None:
            lines += [f"![{name}]({path.name})", ""]
    if not any(line.startswith("![anytime]") for line in lines):
        lines += ["(no anytime traces in these results — older schema: anytime and ECDF "
                  "figures skipped)", ""]
    return lines


def build_report(src: Path, out: Path, paper: bool = True) -> Path:
    """Write tables (CSV + Markdown), figures (PNG) and ``report.md`` into ``out``.

    Every file is first written into a temporary folder inside ``out`` and renamed into
    place when the report is complete, so no reader sees a half-written file. Unreadable
    Parquet files under ``src`` are skipped with a warning naming them.

    Parameters
    ----------
    src : Path
        A results.parquet file or a folder searched recursively.
    out : Path
        Output folder (created).
    paper : bool
        Include the paper's numbers beside ours.

    Raises
    ------
    FileNotFoundError, ResultsUnreadableError
        No results file, or none readable, under ``src``.
    """
    out = Path(out)
    df = add_variant(read_results(src))
    out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=".report-", dir=out))
    try:
        _write_report(src, df, tmp, paper)
        for item in sorted(tmp.iterdir()):
            os.replace(item, out / item.name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    logger.info("report: %s", out / "report.md")
    return out


def _write_report(src: Path, df: pd.DataFrame, out: Path, paper: bool) -> None:
    """Write every file of the report into ``out`` (see :func:`build_report`)."""
    summary = cell_summary(df)
    comp = pairwise(df)
    bk = best_known(df)
    targets = target_table(df, bk)
    summary_cols = [c for c in SUMMARY_COLUMNS if paper or c != "paper_mean"]
    lines = ["# penaltyrun report", "",
             f"Source: `{src}` — {len(df)} jobs, "
             f"{df['run_id'].nunique()} run(s), commit(s) "
             f"{', '.join(sorted(df['git_commit'].dropna().unique())) or 'unknown'}.", "",
             METHODS, "", "## All cells", "", write_table(summary, out, "summary", summary_cols),
             ""]
    lines += _best_known_lines(bk, out, df)
    if not comp.empty:
        n_tests = int(np.isfinite(comp["p_mwu"]).sum())
        lines += ["## Map vs map at equal budget (same optimizer, same variant)", "",
                  f"Holm family: {FAMILY} — {n_tests} tests. median_change_pct = "
                  "(median_a − median_b)/median_a (positive: map b is lower).", "",
                  write_table(comp, out, "comparison", COMPARISON_COLUMNS), ""]
        worse = full_worse_rows(comp)
        if not worse.empty:
            lines += ["### Where the best full start is worse than the best diagonal start", ""]
            lines += [why_full_worse(df, r) for _, r in worse.iterrows()] + [""]
    if not targets.empty:
        lines += ["## Fixed targets: ERT and success share", "",
                  "Target f* + ε·|f*|, f* the best-known of the map's family. ERT (COCO): "
                  "evaluations spent by all starts, each counted until it reached the target "
                  "or stopped, divided by the number of starts that reached it (∞ if none).",
                  "", write_table(targets, out, "targets", TARGET_COLUMNS), ""]
    failed = df[df["status"] == "failed"]
    if not failed.empty:
        lines += ["## Failed jobs", ""]
        lines += [f"- `{r.job_id}`: {str(r.error).splitlines()[0]}" for r in failed.itertuples()]
        lines.append("")
    for (problem, case, variant), g in df.groupby(["problem", "case", "variant"], sort=True):
        slug = "".join(ch if ch.isalnum() else "_" for ch in variant)[:60]
        stem = f"{problem}_{case}" + (f"_{slug}" if variant else "")
        title = f"{problem} / {case}" + (f" [{variant}]" if variant else "")
        lines += [f"## {title}", ""]
        try:
            lines += _figures(g, bk, out, stem, title, paper)
        except Exception as exc:  # a figure that cannot be drawn must not lose the tables
            logger.warning("figures %s failed: %s", title, exc)
            lines += [f"(figures failed: {exc!r})", ""]
        try:
            lines += sections.problem_section(problem, case, g, out, paper, stem)
        except Exception as exc:  # a figure that cannot be drawn must not lose the tables
            logger.warning("section %s/%s failed: %s", problem, case, exc)
            lines += [f"(problem-specific section failed: {exc})", ""]
    for family, study in sections.STUDIES.items():
        try:
            lines += study(df, out, paper)
        except Exception as exc:  # one family's study must not lose the rest of the report
            logger.warning("%s study sections failed: %s", family, exc)
            lines += [f"({family} study sections failed: {exc!r})", ""]
    (out / "report.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
