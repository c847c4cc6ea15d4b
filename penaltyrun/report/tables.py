"""Markdown / CSV writing of report tables (no extra dependency)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd


def fmt(value: object, digits: int = 5) -> str:
    """Compact text of one cell: floats with ``digits`` significant digits, NaN → '—'."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if math.isnan(value):
            return "—"
        return f"{value:.{digits}g}"
    return str(value)


def markdown(df: pd.DataFrame, columns: Sequence[str] | None = None,
             headers: Sequence[str] | None = None, digits: int = 5) -> str:
    """A GitHub-flavoured Markdown table of ``df[columns]``."""
    columns = list(columns or df.columns)
    headers = list(headers or columns)
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for _, row in df[columns].iterrows():
        lines.append("| " + " | ".join(fmt(row[c], digits) for c in columns) + " |")
    return "\n".join(lines)


def write_table(df: pd.DataFrame, out_dir: Path, stem: str,
                columns: Sequence[str] | None = None,
                headers: Sequence[str] | None = None) -> str:
    """Write ``<stem>.csv`` (all columns) and ``<stem>.md``; returns the Markdown text."""
    out_dir.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_dir / f"{stem}.csv", index=False)
    text = markdown(df, columns, headers)
    (out_dir / f"{stem}.md").write_text(text + "\n", encoding="utf-8")
    return text
