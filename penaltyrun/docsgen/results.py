"""The results pages' templates' view of the committed studies: :class:`Context`, whose
methods the templates call for every number, table and sentence (each from a study's merged
``results.parquet`` or the report tables written beside it,
:class:`~penaltyrun.docsgen.studydata.StudyData`). Rendering and checking the pages:
:mod:`penaltyrun.docsgen.resultpages`.

A study whose data is not committed renders as *pending*: which study fills the place and
the command that regenerates it — never a number.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from penaltyrun.docsgen import convergence
from penaltyrun.docsgen.layout import (
    MAX_COLUMNS,
    fmt,
    fold,
    markdown_table,
    md_cell,
    narrow_table,
)
from penaltyrun.docsgen.studydata import StudyData
from penaltyrun.jobrecord import OK, POLISH_CONVERGED, split_stop

#: Columns of the verdict table shown outside its fold (one result per cell).
VERDICT_MAIN = ("question", "diagonal best-known", "full best-known", "gain")
#: Grid points per axis of the basin tables on the results pages (:meth:`Context.basins`).
BASIN_POINTS = 12
#: Columns of ``holdout.csv`` the results pages show.
HELD_OUT_COLUMNS = ["optimizer", "full_map", "judged_at", "scenarios", "full_cheaper",
                    "ratio_median", "ratio_q05", "ratio_q95", "ratio_p_holm",
                    "arrival_shift_median"]
#: Second table of the held-out section: convergence and the pairs both converge.
HELD_OUT_CONV_COLUMNS = ["optimizer", "full_map", "diag_conv", "full_conv",
                         "diag_conv_deadline", "full_conv_deadline", "pairs",
                         "median_imp_pct", "p_holm"]


def default_columns(stem: str) -> list[str]:
    """The columns the report's own Markdown copy of a table shows (all columns of the CSV
    for a table without one)."""
    from penaltyrun.report import build
    return {"summary": build.SUMMARY_MD, "comparison": build.COMPARISON_MD,
            "best_known": build.BEST_KNOWN_COLUMNS, "shortfall": build.SHORTFALL_COLUMNS,
            "targets": build.TARGET_COLUMNS,
            "verdict": build.VERDICT_COLUMNS}.get(stem, [])


def main_columns(stem: str, frame: Any) -> list[str] | None:
    """The answer columns a results page shows of a report table wider than
    :data:`~penaltyrun.docsgen.layout.MAX_COLUMNS` (the others go behind a fold); None for
    a narrow table or one without a choice here (its first columns are shown)."""
    if len(frame.columns) <= MAX_COLUMNS:
        return None
    if stem == "paper":
        return [c for c in ["problem", "case", "variant", "optimizer", "map", "converged",
                            "ours median / mean", "paper median / mean", "Holm p"]
                if c in frame]
    if stem == "holdout_tuning_modes":
        answer = ["full cheaper", "median J_full/J_diag", "Wilcoxon p (log ratio)"]
        modes = ["single", multi_column(dict.fromkeys(frame.columns))]
        return ["case", "optimizer", "full_map",
                *[f"{m}: {a}" for m in modes for a in answer if f"{m}: {a}" in frame]]
    return None


class Context:
    """The functions a template calls (bound to one repository root)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self._studies: dict[str, StudyData] = {}
        #: Text files rendered beside the pages (the numbers of each figure), by path
        #: relative to the root.
        self.figures: dict[Path, str] = {}

    def study(self, name: str) -> StudyData:
        """The data of study ``name``."""
        if name not in self._studies:
            self._studies[name] = StudyData(self.root, name)
        return self._studies[name]

    def pending(self, name: str, short: bool = False) -> str:
        """The sentence that stands where a study's numbers will go (``short``: for a table
        cell); for a committed study whose data lacks the cells a place reads, a note
        saying so."""
        data = self.study(name)
        if data.available:  # committed, but without the cells the place reads
            return (f"*the committed data of `{name}` has no cell this place reads; "
                    f"regenerate it with `{data.make}`*")
        if short:
            return f"*not yet regenerated: `{data.make}`*"
        return (f"*Not yet regenerated: this place is filled from the committed data of the "
                f"study `{name}` ({data.title}). Run `{data.make}` (resumable with "
                f"`RESUME=true`), commit `studies/{name}/`, then `make docs-results`.*")

    def value(self, name: str, column: str, agg: str = "min", where: dict | None = None,
              spec: str = ".4g", converged: bool = True) -> str:
        """One number: ``agg`` (min, max, median, mean, count, sum) of ``column`` over the
        matching records (converged starts only unless ``converged=False``)."""
        frame = self.study(name).rows(where, converged=converged)
        if agg == "count":
            return str(len(frame))
        return fmt(getattr(frame[column].astype(float), agg)(), spec)

    def number(self, name: str, column: str, agg: str = "min", where: dict | None = None,
               converged: bool = True) -> float:
        """Like :meth:`value`, unformatted (for arithmetic in a template, e.g. a gain)."""
        frame = self.study(name).rows(where, converged=converged)
        return float(len(frame)) if agg == "count" else \
            float(getattr(frame[column].astype(float), agg)())

    def summary(self, name: str, by: list[str], where: dict | None = None,
                cost: str = "best_cost", spec: str = ".4g") -> str:
        """Per group: its budget, converged starts (``k of n``), best / median / worst /
        mean of ``cost`` over the converged starts and the median evaluations, as Markdown
        (columns beyond the width behind a fold). Starts with other optimizer settings
        (another budget, swarm or stall rule) are never pooled: each settings variant is
        its own row, with its ``max_evals`` budget."""
        import pandas as pd
        frame = self.study(name).rows(where).copy()
        ok = (frame["status"] == OK) & frame["best_converged"].astype(bool)
        settings = frame["optimizer_settings"] if "optimizer_settings" in frame else None
        frame["_settings"] = "" if settings is None else \
            [("" if v is None or v != v else str(v)) for v in settings]
        budget = frame["max_evals"] if "max_evals" in frame else pd.Series(index=frame.index)
        rows = []
        for key, group in frame.groupby([*by, "_settings"], sort=True, dropna=False):
            key = key if isinstance(key, tuple) else (key,)
            good = group.loc[ok.loc[group.index], cost].astype(float)
            cap = budget.loc[group.index].dropna()
            rows.append({**dict(zip(by, key[:len(by)])),
                         "budget (max_evals)": f"{int(cap.iloc[0])}" if len(cap) else "—",
                         "converged": f"{len(good)} of {len(group)}", "best": good.min(),
                         "median": good.median(), "worst": good.max(), "mean": good.mean(),
                         "evaluations (median)": f"{group['n_evals'].median():.0f}"})
        return narrow_table(pd.DataFrame(rows), spec, keys=by)

    def csv(self, name: str, stem: str, columns: list[str] | None = None,
            where: dict | None = None, spec: str = ".4g") -> str:
        """A report table of the study (or some of its columns / rows) as Markdown; a note
        saying so when the study's report did not write that table (e.g. no pair of maps
        to compare).

        Raises
        ------
        ValueError
            If ``stem`` is not a table the report writes (:func:`report_table`).
        """
        if not self.study(name).has_table(stem):
            return f"*The report of `{name}` has no `{stem}` table.*"
        frame = convergence.rows_of(self.study(name).table(stem), where)
        if frame.empty:
            return f"*The `{stem}` table of `{name}` has no row for {where}.*"
        columns = columns or [c for c in default_columns(stem) if c in frame]
        shown = frame[columns] if columns else frame
        keys = ["problem", "case", "setting", "optimizer", "full_map"] \
            if stem == "holdout_tuning_modes" else None
        return narrow_table(shown, spec, main=main_columns(stem, shown), keys=keys)

    def comparison(self, name: str) -> str:
        """The study's equal-budget map-vs-map tests: the A12 figure (diagonal vs each full
        map, by optimizer, with 95 % Brunner–Munzel intervals) and the comparison table
        behind a fold (:func:`penaltyrun.docsgen.comparefig.section`); a note when the
        report wrote no comparison."""
        from penaltyrun.docsgen.comparefig import section
        if not self.study(name).has_table("comparison"):
            return f"*The report of `{name}` has no `comparison` table.*"
        return section(name, self.study(name).df, self.study(name).table("comparison"),
                       self.figures)

    def scaling(self, name: str, where: dict | None = None) -> str:
        """The study's time to the known optimum against the size of the tuned matrix as a
        figure (:func:`penaltyrun.docsgen.scalingfig.section`, rows of its
        ``known_optimum`` table matching ``where``); a note when the report wrote none."""
        from penaltyrun.docsgen.scalingfig import section
        if not self.study(name).has_table("known_optimum"):
            return f"*The report of `{name}` has no `known_optimum` table.*"
        frame = convergence.rows_of(self.study(name).table("known_optimum"), where)
        if frame.empty:
            return f"*The `known_optimum` table of `{name}` has no row for {where}.*"
        return section(name, frame, self.figures)

    def table_value(self, name: str, stem: str, column: str, where: dict | None = None,
                    spec: str = ".4g") -> str:
        """One entry of a report table (text as the report wrote it, a number formatted with
        ``spec``): the row matching ``where`` must be unique.

        Raises
        ------
        ValueError
            If ``stem`` is not a report table, the study's report did not write it, or no
            row or several rows match (the template's query is ambiguous).
        """
        entry = self._table_entry(name, stem, column, where)
        return entry if isinstance(entry, str) else fmt(float(entry), spec)

    def table_number(self, name: str, stem: str, column: str,
                     where: dict | None = None) -> float:
        """Like :meth:`table_value`, unformatted (for arithmetic in a template)."""
        return float(self._table_entry(name, stem, column, where))

    def _table_entry(self, name: str, stem: str, column: str, where: dict | None) -> Any:
        """The raw entry of :meth:`table_value` (same checks, same errors)."""
        if not self.study(name).has_table(stem):
            raise ValueError(f"{name}: its report wrote no {stem} table")
        frame = convergence.rows_of(self.study(name).table(stem), where)
        if len(frame) != 1:
            raise ValueError(f"{name}/{stem}: {len(frame)} rows match {where}, need one")
        return frame[column].iloc[0]

    def verdict(self, name: str, spec: str = ".4g") -> str:
        """The report's verdict of the study: a table of one result per cell (the
        best-known values with their evidence and the gain), the equal-budget tests and
        the held-out answer behind a fold, and under it the generated sentence per row (a
        note when the report wrote no verdict)."""
        if not self.study(name).has_table("verdict"):
            return self.csv(name, "verdict", spec=spec)
        frame = self.study(name).table("verdict")
        columns = [c for c in default_columns("verdict") if c in frame]
        main = [c for c in columns if c in VERDICT_MAIN]
        rest = [c for c in columns if c not in main]
        table = markdown_table(frame[main], spec)
        if rest:
            table += "\n\n" + fold("Per cell: " + ", ".join(rest),
                                    markdown_table(frame[[main[0], *rest]], spec))
        sentences = self.study(name).table("verdict").get("sentence")
        lines = [f"- {s}" for s in ([] if sentences is None else sentences.dropna())]
        return "\n\n".join([table, *(["\n".join(lines)] if lines else [])])

    def answers(self, name: str, where: dict | None = None) -> list[str]:
        """The verdict sentences of the study's rows matching ``where`` (``problem``,
        ``case``, ...): training result, evidence, held-out result with its statistic, n
        and horizon, and the equal-budget test, as the report words them, with ``|``
        escaped: the sentences fill a cell of the answer table."""
        if not self.study(name).has_table("verdict"):
            raise ValueError(f"the report of {name!r} has no verdict table")
        rows = convergence.rows_of(self.study(name).table("verdict"), where)
        if rows.empty:
            raise ValueError(f"{name}: no verdict row matches {where}")
        return [md_cell(str(s)) for s in rows["sentence"]]

    def held_out_words(self, name: str, problem: str, case: str, variant: str = "") -> str:
        """The held-out answer of one cell's best-known pair in words: scenarios where full
        is cheaper, median J_full / J_diag with its 5–95 % range, the Wilcoxon signed-rank
        test of the log ratios (Holm), the arrival shift, the horizon it was judged at and
        convergence there and by the training deadline (escaped for a Markdown table
        cell: the answer table holds it)."""
        from penaltyrun.report.holdout import BEST_KNOWN
        from penaltyrun.report.verdict import horizon_words, ratio_words

        held = convergence.rows_of(self.study(name).table("holdout"),
                       {"problem": problem, "case": case, "variant": variant,
                        "optimizer": BEST_KNOWN})
        if len(held) != 1:
            raise ValueError(f"{name}: {len(held)} best-known held-out rows for "
                             f"{problem} / {case} [{variant}]")
        h = held.iloc[0].to_dict()
        return md_cell(f"{ratio_words(h)}; {horizon_words(h)}")

    def held_out(self, name: str, spec: str = ".4g") -> str:
        """The report's held-out table (``holdout.csv``: one row per cell × full map and
        per best-known pair, paired by scenario) as one Markdown table per problem × case,
        under a heading naming it, with its convergence table behind a fold."""
        from penaltyrun.report.holdout import SHARE_COLUMNS, counts

        if not self.study(name).has_table("holdout"):
            return "*The study's report has no held-out table.*"
        frame = self.study(name).table("holdout")
        parts = []
        for (problem, case, variant), group in frame.groupby(["problem", "case", "variant"],
                                                             sort=True):
            title = f"{problem} / {case}" + (f" [{variant}]" if variant else "")
            group = group.assign(**{c: counts(group[c], group["scenarios"])
                                    for c in SHARE_COLUMNS if c in group})
            answer, conv = (markdown_table(group[[c for c in cols if c in group]], spec)
                            for cols in (HELD_OUT_COLUMNS, HELD_OUT_CONV_COLUMNS))
            parts.append(f"**Held-out scenarios, {title}:**\n\n{answer}\n\n"
                         + fold(f"Convergence, {title}: at the horizon, by the training "
                                "deadline, and the pairs both converge", conv))
        return "\n\n".join(parts)

    def problem_params(self, name: str, key: str) -> Any:
        """Problem parameter ``key`` as the study's records carry it (``problem_params``;
        ``None`` where unset). Records that disagree give their distinct values as text,
        joined by " / " (a study that mixes settings says so instead of showing one)."""
        return self._recorded(name, "problem_params", key)

    def optimizer_setting(self, name: str, key: str) -> Any:
        """Optimizer setting ``key`` (``polish``, ``polish_share``, ...) as the study's
        records carry it (``optimizer_settings``), as :meth:`problem_params`."""
        return self._recorded(name, "optimizer_settings", key)

    def _recorded(self, name: str, column: str, key: str) -> Any:
        """``key`` of the JSON column ``column`` over the study's records: the one value,
        or the distinct values as text joined by " / "."""
        values = sorted({json.dumps(json.loads(text or "{}").get(key), sort_keys=True)
                         for text in self.study(name).df[column]})
        if len(values) == 1:
            return json.loads(values[0])
        return " / ".join(values)

    def late_gain(self, name: str, where: dict | None = None, share: float = 0.5) -> float:
        """:func:`.convergence.late_gain` of the study's records matching ``where``."""
        return convergence.late_gain(self.study(name).rows(where), share)

    def largest_late_gain(self, name: str, best_known: bool = False) -> float:
        """:func:`.convergence.largest_late_gain` of the study's cells, or of the cells
        holding a best-known value (``best_known``: the jobs of the ``best_known`` table)."""
        best = self.study(name).table("best_known")["job_id"] if best_known else None
        return convergence.largest_late_gain(self.study(name).df, best)

    def cells(self, name: str) -> list[dict[str, Any]]:
        """The study's cells (:func:`.convergence.cells`; a cell run at two budgets is two
        cells), each the ``where`` of :meth:`late_gain`."""
        return convergence.cells(self.study(name).df)

    def budgets(self, name: str, spec: str = ".0f") -> str:
        """The study's evaluations per start as text (:func:`.convergence.budgets`)."""
        return convergence.budgets(self.study(name).df, spec)

    def budget_check(self, name: str) -> str:
        """The cells of the study run at more than one budget
        (:func:`.convergence.budget_check`) as Markdown, the count of starts behind a
        fold (:data:`.convergence.BUDGET_CHECK_MAIN`); empty when there are none."""
        frame = convergence.budget_check(self.study(name).df)
        return "" if frame.empty else narrow_table(
            frame, ".4g", main=list(convergence.BUDGET_CHECK_MAIN),
            keys=list(convergence.BUDGET_CHECK_COLUMNS[:5]))

    def holdout_by_budget(self, name: str) -> dict[str, Any]:
        """:func:`.convergence.holdout_by_budget` of the study's records: ``table``
        (Markdown, the variant and scenario count behind a fold; empty without such
        cases), ``same`` and ``cases`` (:func:`.convergence.verdict_stability`)."""
        frame = convergence.holdout_by_budget(self.study(name).df)
        same, cases = convergence.verdict_stability(frame)
        main = [c for c in convergence.HOLDOUT_BY_BUDGET_COLUMNS
                if c not in ("variant", "scenarios")]
        table = "" if frame.empty else narrow_table(
            frame, ".4g", main=main, keys=["problem", "case", "full records up to"])
        return {"table": table, "same": same, "cases": cases}

    def budget_effect(self, name: str) -> float:
        """:func:`.convergence.budget_effect` of the study's records."""
        return convergence.budget_effect(self.study(name).df)

    def polished(self, names: list[str]) -> list[str]:
        """The studies among ``names`` that are committed and whose searches were refined by
        the exact-gradient polish (``optimizer.polish: gradient``), in the given order."""
        return [name for name in names if self.study(name).available
                and self.optimizer_setting(name, "polish") == "gradient"]

    def polish_endings(self, name: str) -> str:
        """How the polishes of the study's finished starts ended, from ``stop_reason``
        (``+polish``, ``+polish:<why>``; see :mod:`penaltyrun.optim.lbfgs`), as text: e.g.
        "on its own tolerances in 12, with the budget spent in 98, without a gradient near
        the search's best in 50 of 160 starts" (empty when no start was polished)."""
        frame = self.study(name).rows(None)
        reasons = frame.loc[frame["status"] == OK, "stop_reason"].astype(str)
        ends = reasons.map(lambda reason: split_stop(reason)[1]).dropna()
        if ends.empty:
            return ""
        ends = ends.value_counts()
        words = {POLISH_CONVERGED: "on its own tolerances", "max_evals": "with the budget spent",
                 "no_gradient": "without a gradient near the search's best"}
        order = [*words, *sorted(set(ends.index) - set(words))]
        parts = [f"{words.get(end, end)} in {int(ends[end])}" for end in order if end in ends]
        return f"{', '.join(parts)} of {int(ends.sum())} starts"

    def basins(self, name: str, n: int = BASIN_POINTS, spec: str = ".4g") -> str:
        """Basin-of-attraction tables of the study, computed when the page is rendered from
        the committed matrices (the best converged diagonal and full start of each problem ×
        case run from an ``n`` × ``n`` grid of initial conditions at the held-out horizon,
        :func:`penaltyrun.report.basins.maps_of`): per map the start it comes from, the grid
        points that converge, their median arrival time and cost. No figure: the report
        draws the maps from the same data (``penaltyrun-report --basin-points``)."""
        from penaltyrun.report.basins import COLUMNS, maps_of, table

        parts = []
        for (problem, case), group in self.study(name).df.groupby(["problem", "case"],
                                                                   sort=True):
            maps = maps_of(group, n)
            if not maps:
                continue
            bm = next(iter(maps.values()))[1]
            unit = f" {bm.axes.time_unit}" if bm.axes.time_unit else ""
            parts.append(f"**Basins of attraction, {problem} / {case}** ({n} × {n} grid of "
                         f"{bm.axes.labels[0]} × {bm.axes.labels[1]}, judged at "
                         f"{fmt(bm.horizon, spec)}{unit}):\n\n"
                         + markdown_table(table(maps)[COLUMNS], spec))
        return "\n\n".join(parts) or f"*The problems of `{name}` offer no basin maps.*"

    def provenance(self, name: str) -> str:
        """One paragraph: jobs, machine and package versions of the study's data. The git
        commits of its records stay in ``studies/<name>/provenance.json`` (user pages carry
        no commit hashes); the paragraph says how many there are and where."""
        info = self.study(name).provenance
        if not info:
            return ""
        packages = info.get("packages", {})
        in_records = info.get("packages_in_records") or []
        if len(in_records) == 1:  # the versions the records carry win over the merge's
            try:
                packages = {k: v for k, v in json.loads(in_records[0]).items()
                            if isinstance(v, str) and k != "git_commit"}
            except (ValueError, AttributeError):
                pass
        versions = ", ".join(f"{k} {v}" for k, v in sorted(packages.items()))
        if len(in_records) > 1:
            versions += f" (the records carry {len(in_records)} different version sets)"
        hosts = info.get("machines") or [info.get("machine", {})]
        where = "; ".join(f"{h.get('cpu')}, {h.get('cores')} cores, {h.get('os')}"
                          for h in hosts)
        statuses = ", ".join(f"{v} {k}" for k, v in sorted(info.get("status", {}).items()))
        return (f"Data: {info.get('jobs')} jobs ({statuses}); "
                f"{'machines' if len(hosts) > 1 else 'machine'}: {where}; "
                f"versions: {versions}; git commits of the records: "
                f"{len(info.get('git_commits', []))} (`studies/{name}/provenance.json`).")


def multi_column(row: dict[str, Any]) -> str:
    """The multi-scenario prefix of a ``holdout_tuning_modes`` row's columns, e.g.
    ``"multi (mean of 8)"`` (its number of training scenarios varies by study)."""
    names = [k[:-len(": scenarios")] for k in row
             if k.startswith("multi") and k.endswith(": scenarios")]
    if len(names) != 1:
        raise ValueError(f"expected one multi-scenario column group, got {names}")
    return names[0]


def paper_claim(problem: str, case: str) -> str:
    """What the paper states for a problem case, as the problem declares it to the report
    (``report_info(case, {}).paper.claim``); empty when it declares none."""
    from penaltyrun import problems
    from penaltyrun.problems import report_hooks
    paper = report_hooks.info(problems.module(problem), case, {}).paper
    return paper.claim if paper is not None else ""


