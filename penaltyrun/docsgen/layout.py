"""Markdown tables of the results pages: numbers, shares as percentages, narrow tables.

A results page shows no table wider than :data:`MAX_COLUMNS` outside a fold: a wider table
is cut (:func:`narrow_table`) into a main table (its identifying columns and the first
answer columns) and, behind a ``<details>`` fold, tables of the other columns, each
repeating the identifying columns. MkDocs renders the fold's Markdown through the
``md_in_html`` extension (``markdown="1"``); GitHub renders it as it stands.
"""

from __future__ import annotations

import html
import math
import re
from typing import Any

from penaltyrun.typed import is_number

#: Widest table a results page shows outside a fold.
MAX_COLUMNS = 10
#: Columns of the report's tables holding a share (0–1), shown as a percentage. The
#: held-out convergence at the horizon and by the deadline are shown as counts ``k/n``
#: (:func:`penaltyrun.report.holdout.counts`), not here.
PERCENT_COLUMNS = frozenset({
    "diag_conv_all_starts", "full_conv_all_starts", "success_a", "success_b",
    "full_cheaper_share", "full_better_share"})
#: Suffixes of shares in the tuning-modes table (``"single: full cheaper"``, ...).
PERCENT_SUFFIXES = (": full cheaper", ": full better")
#: Columns that identify a row; a table's leading run of them is repeated in every part
#: of a table that is cut.
KEY_COLUMNS = frozenset({
    "problem", "case", "variant", "problem_variant", "optimizer", "param", "map", "map_a",
    "map_b", "full_map", "setting", "run_id", "run", "arm", "detector", "family", "label"})
FOLD_OPEN = '<details markdown="1">'
FOLD_CLOSE = "</details>"


def fmt(value: Any, spec: str = ".4g") -> str:
    """A number formatted with ``spec`` (``—`` for missing / NaN)."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    try:
        return format(value, spec)
    except (TypeError, ValueError):
        return str(value)


def is_share(column: Any) -> bool:
    """Whether ``column`` holds a share printed as a percentage."""
    name = str(column)
    return name in PERCENT_COLUMNS or name.endswith(PERCENT_SUFFIXES)


def percent(value: Any) -> str:
    """A share (0–1) as a percentage with three significant digits, e.g. ``"33.3 %"``
    (``—`` for missing / NaN; text is left as it is)."""
    if not is_number(value):
        return str(value)
    return "—" if math.isnan(value) else f"{100.0 * value:.3g} %"


def md_cell(text: str) -> str:
    """``text`` as the content of one Markdown table cell: ``|`` escaped (it would end the
    cell) and line breaks as spaces (they would end the row)."""
    return text.replace("|", "\\|").replace("\n", " ")


def markdown_table(frame: Any, spec: str = ".4g") -> str:
    """A DataFrame as a Markdown table, numbers formatted with ``spec``, shares
    (:func:`is_share`) as percentages."""
    header = "| " + " | ".join(str(c) for c in frame.columns) + " |"
    lines = [header, "|" + "---|" * len(frame.columns)]
    shares = [is_share(c) for c in frame.columns]
    for _, row in frame.iterrows():
        cells = [percent(v) if share else
                 fmt(v, spec) if is_number(v)
                 else str(v) for v, share in zip(row, shares)]
        lines.append("| " + " | ".join(md_cell(c) for c in cells) + " |")
    return "\n".join(lines)


def fold(summary: str, body: str) -> str:
    """``body`` (Markdown) behind a fold titled ``summary``."""
    return f"{FOLD_OPEN}\n<summary>{html.escape(summary)}</summary>\n\n{body}\n\n{FOLD_CLOSE}"


def key_columns(columns: list[str]) -> list[str]:
    """The leading run of identifying columns (:data:`KEY_COLUMNS`), at least the first
    column."""
    keys = []
    for column in columns:
        if str(column) not in KEY_COLUMNS:
            break
        keys.append(column)
    return keys or list(columns[:1])


def narrow_table(frame: Any, spec: str = ".4g", main: list[str] | None = None,
                 keys: list[str] | None = None) -> str:
    """``frame`` as Markdown tables of at most :data:`MAX_COLUMNS` columns each.

    Parameters
    ----------
    frame : pandas.DataFrame
        The table.
    spec : str
        Format of the numbers.
    main : list of str, optional
        The columns of the main table (default: the identifying columns and the first
        other columns up to the width).
    keys : list of str, optional
        The identifying columns repeated in every further table (default
        :func:`key_columns`).

    Returns
    -------
    str
        One table when ``frame`` is narrow enough; else the main table and, behind a fold
        that names them, the other columns in tables of at most :data:`MAX_COLUMNS`.
    """
    columns = list(frame.columns)
    if len(columns) <= MAX_COLUMNS and main is None:
        return markdown_table(frame, spec)
    keys = [c for c in (keys or key_columns(columns)) if c in columns][:MAX_COLUMNS - 1]
    main = [c for c in (main or [*keys, *[c for c in columns if c not in keys]])
            if c in columns][:MAX_COLUMNS]
    rest = [c for c in columns if c not in main]
    parts = [markdown_table(frame[main], spec)]
    if rest:
        width = MAX_COLUMNS - len(keys)
        tables = [markdown_table(frame[[*keys, *rest[i:i + width]]], spec)
                  for i in range(0, len(rest), width)]
        parts.append(fold("More columns: " + ", ".join(map(str, rest)), "\n\n".join(tables)))
    return "\n\n".join(parts)


_FOLD_LINE = re.compile(r"^\s*<(/?)details\b", re.IGNORECASE)


def wide_tables(text: str, limit: int = MAX_COLUMNS) -> list[tuple[int, int]]:
    """(line number, columns) of every Markdown table in ``text`` outside a fold that is
    wider than ``limit``."""
    depth, previous, found = 0, False, []
    for number, line in enumerate(text.splitlines(), start=1):
        match = _FOLD_LINE.match(line)
        if match:
            depth += -1 if match.group(1) else 1
        is_row = line.lstrip().startswith("|")
        if is_row and not previous and depth == 0:
            cells = len(re.split(r"(?<!\\)\|", line.strip().strip("|")))
            if cells > limit:
                found.append((number, cells))
        previous = is_row
    return found
