"""Markdown / CSV writing of report tables (no extra dependency)."""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: Most columns of a Markdown table in the report (CSV files keep every column).
MAX_COLUMNS = 10


def fmt(value: object, digits: int = 5) -> str:
    """Compact text of one cell by magnitude: ``digits`` significant digits in plain
    notation for 1e-3 ≤ |x| < 1e6, scientific otherwise;
    integers as integers; NaN → '—'."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if math.isnan(value):
            return "—"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        if value == int(value) and abs(value) < 1e6:
            return str(int(value))
        mag = abs(value)
        if 1e-3 <= mag < 1e6:
            text = f"{value:.{digits}g}"
            return text if "e" not in text else f"{value:.0f}"
        return f"{value:.{digits - 1}e}"
    if value is None:
        return "—"
    return str(value).replace("|", "\\|")


def with_unit(value: float, unit: str, digits: int = 5) -> str:
    """``fmt(value)`` followed by the unit (none for a nondimensional ``"1"`` or ``""``)."""
    text = fmt(value, digits)
    return text if unit in ("", "1") or text == "—" else f"{text} {unit}"


def file_stem(text: str, limit: int = 80) -> str:
    """``text`` as a file-name stem: every character not a letter or digit becomes ``_``;
    a stem longer than ``limit`` keeps its first characters and ends with a hash of the
    whole text, so stems stay distinct and within file-system limits (255 bytes)."""
    stem = "".join(ch if ch.isalnum() else "_" for ch in str(text))
    if len(stem) <= limit:
        return stem
    digest = hashlib.sha1(stem.encode()).hexdigest()[:10]
    return f"{stem[:limit - 11]}_{digest}"


def save_figure(fig: Any, path: Path, dpi: int = 110) -> Path:
    """Lay out (no panel title over the panel above), save with ``bbox_inches="tight"``
    (no title or label is clipped) and close."""
    import warnings

    import matplotlib.pyplot as plt

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # 3-D axes: tight_layout approximates
        fig.tight_layout()

    fig.savefig(path, dpi=dpi, bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)
    return path


def markdown(df: pd.DataFrame, columns: Sequence[str] | None = None,
             headers: Sequence[str] | None = None, digits: int = 5) -> str:
    """A GitHub-flavoured Markdown table of ``df[columns]``."""
    columns = list(columns or df.columns)
    headers = list(headers or columns)
    if len(headers) > MAX_COLUMNS:
        raise ValueError(f"a report table has at most {MAX_COLUMNS} columns, got "
                         f"{len(headers)}: {headers}")
    lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for _, row in df[columns].iterrows():
        lines.append("| " + " | ".join(fmt(row[c], digits) for c in columns) + " |")
    return "\n".join(lines)


def markdown_split(df: pd.DataFrame, digits: int = 5) -> str:
    """:func:`markdown` of a table of any width: wider than :data:`MAX_COLUMNS`, it is cut
    into tables of the first column plus the next ``MAX_COLUMNS − 1`` columns."""
    cols = list(df.columns)
    if len(cols) <= MAX_COLUMNS:
        return markdown(df, digits=digits)
    step = MAX_COLUMNS - 1
    return "\n\n".join(markdown(df, [cols[0], *cols[k:k + step]], digits=digits)
                       for k in range(1, len(cols), step))


def write_table(df: pd.DataFrame, out_dir: Path, stem: str,
                columns: Sequence[str] | None = None,
                headers: Sequence[str] | None = None) -> str:
    """Write ``<stem>.csv`` (all columns) and ``<stem>.md``; returns the Markdown text."""
    out_dir.mkdir(parents=True, exist_ok=True)
    df.to_csv(out_dir / f"{stem}.csv", index=False, encoding="utf-8")
    text = markdown(df, columns, headers)
    (out_dir / f"{stem}.md").write_text(text + "\n", encoding="utf-8")
    return text
