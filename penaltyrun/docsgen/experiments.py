"""Template functions over the committed CSV files of an experiment folder.

Some findings are not a study's merged Parquet but small CSV files written by the scripts
under ``bench/`` (e.g. ``studies/fidelity_gap/*.csv``, described in the folder's README).
A results template reads them only through these functions, so every number on the page
is an expression over a committed file: a value edited by hand in the rendered page fails
``make check-docs`` like any other.

Functions (the names templates call):

* ``exp_table(folder, file, columns, where, spec, headers)``: rows as a Markdown table;
* ``exp_value(folder, file, column, where, agg, spec)``: one entry (``agg=None``: the one
  matching row) or an aggregate (min, max, median, mean, sum, count) over the matching rows;
* ``exp_number(...)``: the same, unformatted, for arithmetic in a template;
* ``exp_mwu(folder, file, column, by, a, b, spec)``: two-sided Mann–Whitney U p-value of
  ``column`` between the rows with ``by == a`` and ``by == b``.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Any

#: Aggregates of :func:`exp_value`.
AGGREGATES = ("min", "max", "median", "mean", "sum", "count")


class ExperimentError(ValueError):
    """A template query that names no committed file or no unique row."""


def functions(root: Path) -> dict[str, Any]:
    """The template functions bound to repository ``root`` (``studies/<folder>/<file>``)."""
    base = (Path(root) / "studies").resolve()

    @cache
    def frame(folder: str, file: str) -> Any:
        import pandas as pd
        path = (base / folder / file).resolve()
        if base not in path.parents or path.suffix != ".csv":
            raise ExperimentError(f"{folder}/{file}: not a CSV file under studies/")
        if not path.is_file():
            raise ExperimentError(f"studies/{folder}/{file} is not committed")
        return pd.read_csv(path, keep_default_na=True)

    def select(folder: str, file: str, where: dict | None) -> Any:
        rows = frame(folder, file)
        for key, value in (where or {}).items():
            if key not in rows:
                raise ExperimentError(f"{folder}/{file}: no column {key!r}")
            rows = rows[rows[key].isin(value if isinstance(value, list) else [value])]
        return rows

    def exp_number(folder: str, file: str, column: str, where: dict | None = None,
                   agg: str | None = None) -> Any:
        rows = select(folder, file, where)
        if agg == "count":
            return float(len(rows))
        if column not in rows:
            raise ExperimentError(f"{folder}/{file}: no column {column!r}")
        values = rows[column]
        if agg is None:
            if len(rows) != 1:
                raise ExperimentError(f"{folder}/{file}: {len(rows)} rows match {where}, "
                                      "need one (or give agg)")
            value = values.iloc[0]
            return float(value) if not isinstance(value, str) else value
        if agg not in AGGREGATES:
            raise ExperimentError(f"agg must be one of {AGGREGATES}, not {agg!r}")
        if values.empty:
            raise ExperimentError(f"{folder}/{file}: no row matches {where}")
        return float(getattr(values.astype(float), agg)())

    def exp_value(folder: str, file: str, column: str, where: dict | None = None,
                  agg: str | None = None, spec: str = ".4g") -> str:
        from penaltyrun.docsgen.layout import fmt
        return fmt(exp_number(folder, file, column, where, agg), spec)

    def exp_table(folder: str, file: str, columns: list[str] | None = None,
                  where: dict | None = None, spec: str = ".4g",
                  headers: list[str] | None = None) -> str:
        rows = select(folder, file, where)
        if rows.empty:
            raise ExperimentError(f"{folder}/{file}: no row matches {where}")
        missing = [c for c in columns or [] if c not in rows]
        if missing:
            raise ExperimentError(f"{folder}/{file}: no column(s) {missing}")
        from penaltyrun.docsgen.layout import narrow_table
        shown = rows[columns] if columns else rows
        if headers:
            shown = shown.set_axis(headers, axis=1)
        return narrow_table(shown, spec)

    def exp_mwu(folder: str, file: str, column: str, by: str, a: Any, b: Any,
                spec: str = ".2g") -> str:
        from scipy import stats

        from penaltyrun.docsgen.layout import fmt
        x = select(folder, file, {by: a})[column].astype(float).dropna()
        y = select(folder, file, {by: b})[column].astype(float).dropna()
        if x.empty or y.empty:
            raise ExperimentError(f"{folder}/{file}: no {column} for {by} = {a!r} or {b!r}")
        p = stats.mannwhitneyu(x, y, alternative="two-sided").pvalue
        return fmt(float(p), spec)

    return {"exp_table": exp_table, "exp_value": exp_value, "exp_number": exp_number,
            "exp_mwu": exp_mwu}
