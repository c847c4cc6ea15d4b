"""Build the report (tables + figures + report.md) from Parquet results only."""

from __future__ import annotations

import logging
from pathlib import Path

import pandas as pd

from penaltyrun.io import read_results
from penaltyrun.report import figures, sections
from penaltyrun.report.paper import MEAN_COST
from penaltyrun.report.stats import add_variant, cell_summary, comparison
from penaltyrun.report.tables import write_table

logger = logging.getLogger(__name__)

SUMMARY_COLUMNS = [
    "problem", "case", "variant", "optimizer", "param", "n_jobs", "success_rate", "best",
    "median", "mean", "worst", "std", "mean_ci95_lo", "mean_ci95_hi", "mean_evals",
    "mean_wall_s", "paper_mean",
]
COMPARISON_COLUMNS = [
    "problem", "case", "variant", "optimizer", "full_map", "diag_best", "full_best",
    "diag_mean", "full_mean", "diag_median", "full_median", "diag_worst", "full_worst",
    "diag_std", "full_std", "diag_success", "full_success", "improvement_mean_pct",
    "improvement_best_pct", "p_value_mwu", "paper_diag_mean", "paper_full_mean",
    "paper_improvement_mean_pct",
]


def _why_full_worse(df: pd.DataFrame, row: pd.Series) -> str:
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
            f"variables. A larger budget (optimizer.iters, optimizer.n_particles) or a "
            f"longer stall window (optimizer.ftol_iter) is needed.")


def build_report(src: Path, out: Path, paper: bool = True) -> Path:
    """Write tables (CSV + Markdown), figures (PNG) and ``report.md`` into ``out``.

    Parameters
    ----------
    src : Path
        A results.parquet file or a folder searched recursively.
    out : Path
        Output folder (created).
    paper : bool
        Include the paper's numbers beside ours.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    df = add_variant(read_results(src))
    summary = cell_summary(df)
    comp = comparison(df)
    summary_cols = [c for c in SUMMARY_COLUMNS if paper or c != "paper_mean"]
    comp_cols = [c for c in COMPARISON_COLUMNS if paper or not c.startswith("paper")]
    lines = ["# penaltyrun report", "",
             f"Source: `{src}` — {len(df)} jobs, "
             f"{df['run_id'].nunique()} run(s), commit(s) "
             f"{', '.join(sorted(df['git_commit'].dropna().unique())) or 'unknown'}.", "",
             "Costs are the optimizer's best objective per start (graded penalty for "
             "non-converged candidates). Improvement = (diagonal − full)/diagonal; p-value: "
             "one-sided Mann–Whitney U (full < diagonal). CI: 95 % bootstrap of the mean.", "",
             "## All cells", "", write_table(summary, out, "summary", summary_cols), ""]
    if not comp.empty:
        lines += ["## Diagonal vs full", "", write_table(comp, out, "comparison", comp_cols), ""]
        worse = comp[comp["full_worse_on_best"]]
        if not worse.empty:
            lines += ["### Where the best full start is worse than the best diagonal start", ""]
            lines += [_why_full_worse(df, r) for _, r in worse.iterrows()] + [""]
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
        conv = figures.convergence(g, f"{title}: convergence", out / f"convergence_{stem}.png")
        dist = figures.cost_distribution(g, f"{title}: best cost per start",
                                         out / f"costs_{stem}.png",
                                         MEAN_COST.get((problem, case)) if paper else None)
        lines += [f"![convergence]({conv.name})", "", f"![costs]({dist.name})", ""]
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
    (out / "report.md").write_text("\n".join(lines) + "\n")
    logger.info("report: %s", out / "report.md")
    return out
