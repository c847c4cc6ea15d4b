"""Problem sections of the report, built only from what each problem declares through the
protocol (:mod:`penaltyrun.report.protocol`): its plots of the best starts, its paper values
beside ours, active bounds, and the sections the problem contributes itself."""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy import stats  # noqa: E402

from penaltyrun.io import decode_json  # noqa: E402
from penaltyrun.problems import report_hooks  # noqa: E402
from penaltyrun.problems.base import ReportSection  # noqa: E402
from penaltyrun.report import protocol  # noqa: E402
from penaltyrun.report.bestknown import best_rows, family  # noqa: E402
from penaltyrun.report.rows import batches, full_row, groups, narrow  # noqa: E402
from penaltyrun.report.stats import converged, holm, paper_value  # noqa: E402
from penaltyrun.report.tables import (  # noqa: E402
    alt_text,
    file_stem,
    fmt,
    markdown,
    markdown_split,
    md_line,
    save_figure,
    with_unit,
)

logger = logging.getLogger(__name__)

#: Share of the largest entry within which a matrix "matches" a published one.
MATCH_TOL = 0.005
#: Relative distance to a bound within which a best matrix is "at" the bound.
BOUND_RTOL = 1e-6
#: Holm family of the median tests against published medians.
PAPER_FAMILY = "every median test against a published median of this report"


def matrices_of(row: pd.Series | dict) -> dict[str, np.ndarray]:
    """Decoded best matrices of a job row."""
    return {k: np.asarray(v, float) for k, v in (decode_json(row["matrices"]) or {}).items()}


def deviations(texts: list[Any], refs: Mapping[str, np.ndarray]) -> np.ndarray:
    """How far each start's stored matrices are from the matrices ``refs``: the largest over
    ``refs`` of max |K − ref| / max |ref| (entrywise, relative to the reference's largest
    entry; ∞ where a matrix is missing or of another shape); the starts' matrices of one
    shape are compared as one stack.

    Parameters
    ----------
    texts : list of str or None, length S
        ``matrices`` column values (JSON objects {name: nested lists}).
    refs : mapping of name to ndarray

    Returns
    -------
    ndarray, shape (S,)
    """
    decoded = [decode_json(text) or {} for text in texts]
    worst = np.zeros(len(decoded))
    for name, ref in refs.items():
        dev = np.full(len(decoded), np.inf)
        arrays = [np.asarray(m[name], float) if name in m else None for m in decoded]
        alike = [i for i, a in enumerate(arrays) if a is not None and a.shape == ref.shape]
        if alike:
            stack = np.stack([arrays[i] for i in alike]).reshape(len(alike), -1)
            dev[alike] = np.abs(stack - ref.ravel()).max(axis=1) / np.abs(ref).max()
        worst = np.maximum(worst, dev)
    return worst


def _slug(text: str) -> str:
    return file_stem(text, 80)


def plots_section(g: pd.DataFrame, out: Path, stem: str) -> list[str]:
    """The problem's own figures (``report_plots`` hook, default: time histories) of the
    best diagonal and best full start over every optimizer, and of the paper's matrices."""
    first = g.iloc[0]
    mod = protocol.module(first["problem"])
    prob = protocol.rebuild(first["problem"], first["case"], first.get("problem_params"))
    if mod is None or prob is None:
        return []
    info = protocol.info_of(g)
    sims: dict[str, Any] = {}
    for fam, row in best_rows(g).items():
        sims[f"best {fam} ({row['optimizer']}/{row['param']}, "
             f"{with_unit(float(row['best_cost']), info.cost_unit, 4)})"] = \
            protocol.simulate(row)
    if info.paper is not None and sims:
        for name, mats in info.paper.matrices.items():
            sims[f"paper {name}"] = protocol.simulate_matrices(
                first["problem"], first["case"], first.get("problem_params"), dict(mats))
    figures = report_hooks.plots(mod, sims, first["case"],
                                 protocol.params_of(first.get("problem_params")))
    lines = []
    for caption, fig in figures.items():
        name = f"{stem}_{_slug(caption)}.png"
        save_figure(fig, out / name)
        lines += [f"![{alt_text(caption)}]({name})", ""]
    return lines


def paper_matrix_tables(df: pd.DataFrame) -> dict[tuple[str, str, str], pd.DataFrame]:
    """Our best matrices against the published ones (:func:`_paper_matrix_table`) of each
    problem × case × variant of ``df`` that has published matrices, keyed by
    ``(problem, case, variant)``: computed once for the ``paper_matrices`` table
    (:func:`paper_matrix_rows`) and the case sections (:func:`paper_section`). A case
    whose stored parameters the problem accepts but cannot run is left out with one
    warning."""
    tables = {}
    df = narrow(df, ["problem", "case", "variant", "problem_params", "optimizer", "param",
                     "status", "best_converged", "best_cost", "matrices"])
    for (problem, case, variant), g in groups(df, ["problem", "case", "variant"]):
        try:
            rows = _paper_matrix_table(g)
        except Exception as exc:  # stored parameters the problem accepts but cannot run
            reason = " ".join(str(exc).split())[:120] or type(exc).__name__
            protocol.warn(f"{problem} / {case}: the paper's matrices could not be evaluated "
                          f"with the stored parameters ({type(exc).__name__}: {reason}); "
                          "their table is left out")
            continue
        if not rows.empty:
            tables[problem, case, variant] = rows
    return tables


def paper_matrix_rows(tables: Mapping[tuple[str, str, str], pd.DataFrame]) -> pd.DataFrame:
    """The ``paper_matrices`` table: the :func:`paper_matrix_tables` ``tables`` one under
    the other, with ``problem``, ``case`` and ``variant`` columns."""
    rows = [table.assign(problem=key[0], case=key[1], variant=key[2])
            [["problem", "case", "variant", *table.columns]] for key, table in tables.items()]
    return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()


def _paper_matrix_table(g: pd.DataFrame) -> pd.DataFrame:
    """Our best matrices vs the published ones, one row per published map (empty without
    published matrices)."""
    info = protocol.info_of(g)
    if info.paper is None or not info.paper.matrices:
        return pd.DataFrame()
    first = g.iloc[0]
    prob = protocol.rebuild(first["problem"], first["case"], first.get("problem_params"))
    if prob is None:
        return pd.DataFrame()
    ok = g[converged(g) & (g["optimizer"] != "baseline")]
    rows = []
    for name, ref in info.paper.matrices.items():
        cell = ok[ok["param"].map(family) == family(name)]
        if cell.empty:
            continue
        best = full_row(cell, cell["best_cost"].astype(float).idxmin())
        refs = {k: np.asarray(v, float) for k, v in ref.items()}
        devs = np.concatenate([
            [], *(deviations(batch["matrices"].tolist(), refs)
                  for batch in batches(narrow(cell, ("matrices",)), ("matrices",)))])
        best_dev = float(deviations([best["matrices"]], refs)[0])
        rows.append({"map": name, "our best": float(best["best_cost"]),
                     "by": f"{best['optimizer']}/{best['param']}",
                     f"paper {', '.join(ref)}: our cost": float(prob.evaluate(dict(ref))["cost"]),
                     "deviation of our best": f"{100 * best_dev:.3g} %",
                     f"starts within {100 * MATCH_TOL:g} %":
                         f"{int(np.count_nonzero(devs <= MATCH_TOL))}/{len(devs)}"})
    return pd.DataFrame(rows)


def paper_matrices(g: pd.DataFrame, table: pd.DataFrame | None) -> list[str]:
    """Our best matrices vs the published ones (``table``, the case's
    :func:`paper_matrix_tables` entry; None: none): cost of the published matrix in our
    implementation, distance of our best, starts that match it."""
    if table is None or table.empty:
        return []
    info = protocol.info_of(g)
    return [f"Our best matrices vs the published ones ({info.paper.source}); costs in "
            f"{info.cost_label}; deviation = max |K − K_paper| / max |K_paper|.", "",
            markdown(table), ""]


def median_test(ours: np.ndarray, their_median: float, their_runs: int) -> float:
    """Two-sided Mood's median test of our costs against a published median.

    Their runs are split half above, half below their median (true by definition of a
    median of ``their_runs`` distinct values); ours are counted (values equal to it left
    out); Fisher's exact test of the 2 × 2 table. NaN without our costs.
    """
    ours = np.asarray(ours, float)
    above, below = int((ours > their_median).sum()), int((ours < their_median).sum())
    if above + below == 0 or not their_runs:
        return float("nan")
    half = their_runs // 2
    return float(stats.fisher_exact([[above, below], [half, their_runs - half]]).pvalue)


def paper_rows(df: pd.DataFrame) -> pd.DataFrame:
    """Our cells beside the published mean / median / four-number summaries, with a median
    test where the number of published runs is known (Holm over :data:`PAPER_FAMILY`)."""
    rows = []
    cell = ["problem", "case", "variant", "optimizer", "param"]
    for (problem, case, variant, optimizer, param), g in groups(
            df[df["optimizer"] != "baseline"], cell):
        paper = protocol.info_of(g).paper
        if paper is None:
            continue
        summary = (paper.summaries or {}).get(param)
        mean = paper_value(paper, param, "mean_cost")
        median = paper_value(paper, param, "median_cost")
        if summary is not None:
            median = summary[1] if not np.isfinite(median) else median
            mean = summary[2] if not np.isfinite(mean) else mean
        if not (np.isfinite(mean) or np.isfinite(median)):
            continue
        cost = g.loc[converged(g), "best_cost"].astype(float).to_numpy()
        rows.append({"problem": problem, "case": case, "variant": variant,
                     "optimizer": optimizer, "map": param,
                     "converged": f"{cost.size}/{len(g)}",
                     "ours median / mean": f"{fmt(np.median(cost) if cost.size else np.nan, 4)}"
                                           f" / {fmt(cost.mean() if cost.size else np.nan, 4)}",
                     "paper median / mean": f"{fmt(median, 4)} / {fmt(mean, 4)}",
                     "paper runs": paper.runs or "—", "source": paper.source,
                     **_evaluation_entries(g, (paper.evaluations or {}).get(param)),
                     "p": median_test(cost, median, paper.runs or 0)
                     if np.isfinite(median) else np.nan})
    table = pd.DataFrame(rows)
    if not table.empty:
        table["Holm p"] = holm(table.pop("p").to_numpy(float))
        if table[PAPER_EVALS].isna().all():  # no source gives evaluation counts
            table = table.drop(columns=EVALUATION_COLUMNS)
    return table


def _evaluation_entries(g: pd.DataFrame, published: tuple[float, float, float] | None
                        ) -> dict[str, Any]:
    """Our evaluations per start (median and range over every start of the cell) beside the
    published ones, and the ratio of the medians (NaN where none are published)."""
    ours = g["n_evals"].astype(float)
    entries = {OUR_EVALS: f"{ours.median():.0f} ({ours.min():.0f}–{ours.max():.0f})",
               PAPER_EVALS: np.nan, EVALS_RATIO: np.nan}
    if published is not None:
        low, median, high = published
        entries.update({PAPER_EVALS: f"{median:.0f} ({low:.0f}–{high:.0f})",
                        EVALS_RATIO: float(ours.median()) / float(median)})
    return entries


OUR_EVALS = "evaluations: ours median (range)"
PAPER_EVALS = "evaluations: paper median (range)"
EVALS_RATIO = "evaluations: median ours / paper"
#: Columns of the paper table present only where a source publishes evaluation counts.
EVALUATION_COLUMNS = [OUR_EVALS, PAPER_EVALS, EVALS_RATIO]


PAPER_COLUMNS = ["optimizer", "map", "converged", "ours median / mean", "paper median / mean",
                 "paper runs", "source", "Holm p"]


def _shown(table: pd.DataFrame) -> list[str]:
    """Columns of the paper table's Markdown copy: with evaluation counts, the source (one
    per case, in the CSV) makes room for them."""
    if not set(EVALUATION_COLUMNS) <= set(table.columns):
        return PAPER_COLUMNS
    return [c for c in PAPER_COLUMNS if c != "source"] + EVALUATION_COLUMNS


def paper_section(g: pd.DataFrame, table: pd.DataFrame,
                  matrices: Mapping[tuple[str, str, str], pd.DataFrame]) -> list[str]:
    """Lines of one case's paper comparison (the rows of ``table`` for it, and its entry
    of ``matrices``, see :func:`paper_matrix_tables`)."""
    first = g.iloc[0]
    lines = paper_matrices(g, matrices.get((first["problem"], first["case"],
                                            first["variant"])))
    info = protocol.info_of(g)
    if not table.empty:
        sel = table[(table["problem"] == first["problem"]) & (table["case"] == first["case"])
                    & (table["variant"] == first["variant"])]
        if not sel.empty:
            source = f"; source: {info.paper.source}" if "source" not in _shown(sel) else ""
            lines += [f"Beside the published values ({info.cost_label}{source}). Holm p: Mood's "
                      "median test (Fisher's exact test of above / below the published "
                      "median, which splits the published runs evenly by definition), Holm "
                      f"over {PAPER_FAMILY}. Optimizer implementations and budgets may "
                      "differ from the published ones.", "", markdown(sel, _shown(sel)), ""]
    if info.paper is not None and info.paper.claim:
        lines += [f"Published claim ({info.paper.source}): {info.paper.claim}.", ""]
    return (["### Paper values", ""] + lines) if lines else []


def active_bounds(best: Mapping[str, pd.Series]) -> list[str]:
    """Warning lines for best matrices (``best``: one row per family, as
    :func:`~penaltyrun.report.bestknown.best_rows` gives them) at a bound of their box: a
    diagonal entry or an eigenvalue within :data:`BOUND_RTOL` relative of it."""
    lines = []
    for fam, row in best.items():
        bounds = protocol.bounds_of(row)
        if not bounds:
            continue
        for name, K in matrices_of(row).items():
            if name not in bounds:
                continue
            values = np.diag(K) if fam == "diagonal" else np.linalg.eigvalsh(K)
            what = "diagonal entry" if fam == "diagonal" else "eigenvalue"
            for b, side in zip(bounds[name], ("lower", "upper")):
                hit = np.abs(values - b) <= BOUND_RTOL * max(abs(b), 1e-300)
                for v in values[hit]:
                    where = f"{row['problem']} / {row['case']}" + (
                        f" [{row['problem_variant']}]" if row.get("problem_variant") else "")
                    lines.append(md_line(f"- {where}: best {fam} {name} "
                                         f"({row['optimizer']}/{row['param']}): "
                                         f"{what} {v:.6g} at its {side} bound {b:g} — the "
                                         "box may be too small."))
    return lines


def render(section: ReportSection, out: Path, stem: str, level: str = "##") -> list[str]:
    """Markdown lines of a problem-contributed section (figures saved into ``out``)."""
    lines = [f"{level} {section.title}", ""]
    if section.text:
        lines += [section.text, ""]
    for caption, rows in section.tables:
        if caption:
            lines += [caption, ""]
        if rows:
            lines += [markdown_split(pd.DataFrame(rows)), ""]
    for k, (caption, fig) in enumerate(section.figures):
        name = f"{stem}_{k}_{_slug(caption)}.png"
        save_figure(fig, out / name)
        lines += [f"![{alt_text(caption)}]({name})", ""]
    return lines


def contributed(df: pd.DataFrame, out: Path) -> list[str]:
    """The sections each problem contributes (``report_sections`` hook), problem by
    problem; a failing hook costs one line."""
    lines: list[str] = []
    for problem in sorted(df["problem"].dropna().unique()):
        mod = protocol.module(problem)
        if getattr(mod, "report_sections", None) is None:  # also: module not imported
            continue
        try:  # only this problem's rows copied (a groupby would sort a copy of them all)
            found = report_hooks.sections(mod, protocol.jobs_of(df[df["problem"] == problem]))
        except Exception as exc:  # one problem's hook must not lose the report
            logger.warning("report_sections of %s failed: %s", problem, exc)
            lines += [md_line(f"({problem}: its report sections failed: {exc!r})"), ""]
            continue
        for k, section in enumerate(found):
            try:
                lines += render(section, out, f"{_slug(str(problem))}_section{k}")
            except Exception as exc:  # a malformed section costs one line
                logger.warning("section %r of %s failed: %s", section.title, problem, exc)
                lines += [md_line(f"({problem}: section {section.title!r} failed: "
                                  f"{exc!r})"), ""]
    return lines


__all__ = ["active_bounds", "contributed", "deviations", "median_test", "paper_matrix_rows",
           "paper_matrix_tables",
           "paper_rows", "paper_section", "plots_section", "render"]
