"""Markdown / CSV writing of report tables (no extra dependency)."""

from __future__ import annotations

import hashlib
import math
import re
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
    return md_text(value)


_MD_ACTIVE = re.compile(r"([\\`*\[\]<>|])")
_MD_LINK = re.compile(r"([\[\]<>])")


def one_line(value: object) -> str:
    """``value`` as text on one line: every run of white space (newlines included) one
    space, and every other character that is not printable (an escape, NUL, a carriage
    return inside a word) the replacement character U+FFFD."""
    text = " ".join(str(value).split())
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else "\ufffd" for c in text)


def fenced(value: object) -> str:
    """A name from the data inside a fenced code block: :func:`one_line`, with backticks
    turned into quotes (a name can neither close the fence nor open another)."""
    return one_line(value).replace("`", "'")


def md_text(value: object) -> str:
    """A text from the data as inert Markdown on one line (:func:`one_line`), with
    ``\\ ` * [ ] < > |`` backslash-escaped, so no name can start a line, a table row, an
    image, a link or raw HTML."""
    return _MD_ACTIVE.sub(r"\\\1", one_line(value))


def alt_text(caption: object) -> str:
    """A figure caption as the alternative text of a Markdown image: one line, brackets
    turned into parentheses (the image line stays one image)."""
    return " ".join(str(caption).split()).replace("[", "(").replace("]", ")")


def md_line(text: str) -> str:
    """A line the report composed around names from the data (it may use ``**`` and
    backticks itself): on one line, with ``[ ] < >`` escaped (no image, link or raw HTML)."""
    return _MD_LINK.sub(r"\\\1", one_line(text))


def with_unit(value: float, unit: str, digits: int = 5) -> str:
    """``fmt(value)`` followed by the unit (none for a nondimensional ``"1"`` or ``""``)."""
    text = fmt(value, digits)
    return text if unit in ("", "1") or text == "—" else f"{text} {unit}"


#: Characters a file-name stem keeps as they are (ASCII letters, digits, ``_`` and ``-``; no
#: dot, so no ``..`` and no hidden file).
STEM_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")
_HASH_END = re.compile(r"_[0-9a-f]{10}$")


def file_stem(text: object, limit: int = 80) -> str:
    """``text`` (a name from the data) as a safe file-name stem, distinct for distinct texts.

    A text of ASCII letters, digits, ``_`` and ``-`` of at most ``limit`` characters is its
    own stem. Any other text (a path such as ``../x`` or ``/abs``, a newline, a space, a long
    label) becomes its letters and digits, every other character
    ``_``, cut to ``limit − 11`` characters, then ``_`` and 10 hex digits of its SHA-1: no
    separator and no dot survive, and the hash keeps two texts that look alike apart.
    """
    text = str(text)
    if (text and len(text) <= limit and set(text) <= STEM_CHARS
            and not text.startswith("-") and not _HASH_END.search(text)):
        return text
    safe = "".join(ch if ch.isascii() and ch.isalnum() else "_" for ch in text)
    digest = hashlib.sha1(text.encode("utf-8", "surrogatepass")).hexdigest()[:10]
    return f"{safe[:max(limit - 11, 1)]}_{digest}"


class StemBook:
    """File-name stems of the cells of one output folder, one stem per cell identity.

    :meth:`stem` joins the :func:`file_stem` of each part with ``_``; when two different
    identities would share a stem (``a_b`` + ``c`` against ``a`` + ``b_c``, or names equal
    but for capitals), the later one gets ``_`` and 10 hex digits of its identity's hash.
    """

    def __init__(self) -> None:
        self._owner: dict[str, tuple[str, ...]] = {}

    def stem(self, *parts: object, limit: int = 60) -> str:
        """The stem of the cell named by ``parts`` (empty parts left out)."""
        identity = tuple(str(p) for p in parts)
        stem = "_".join(file_stem(p, limit) for p in identity if p)
        key = stem.lower()
        if self._owner.setdefault(key, identity) != identity:
            digest = hashlib.sha1("\0".join(identity).encode("utf-8", "surrogatepass"))
            stem = f"{stem}_{digest.hexdigest()[:10]}"
            self._owner.setdefault(stem.lower(), identity)
        return stem


#: Margin (inches) around the tight box of a figure saved with one.
TIGHT_PAD = 0.15
#: zlib level of the report's PNG files (1: fastest compression; the pixels are the same
#: at every level).
PNG_COMPRESS_LEVEL = 1


#: Most points of one group (a box, a map) that a report scatter plot draws: above it, that
#: many drawn at random (:func:`dot_sample`); the figure says so. A hundred thousand
#: overlapping dots show no more than a few thousand and cost memory and time in proportion.
MAX_DOTS = 2000


def dot_sample(n: int, rng: np.random.Generator) -> np.ndarray:
    """Sorted positions of the points of a group of ``n`` that a scatter plot draws: all of
    them up to :data:`MAX_DOTS`, else that many drawn at random by ``rng`` (distinct)."""
    if n <= MAX_DOTS:
        return np.arange(n)
    return np.sort(rng.choice(n, MAX_DOTS, replace=False))


def save_figure(fig: Any, path: Path, dpi: int = 110) -> Path:
    """Lay out (no panel title over the panel above, every title, label and legend inside
    the figure), save and close.

    The tight layout fits the panels' tick labels and the titles' heights into the
    figure, so a figure whose titles, axis labels and legends lie inside it is saved as
    laid out: a ``bbox_inches="tight"`` save would lay it out twice more (a fifth of a
    report's time) only to trim the margins. A figure with one that sticks out (a title
    wider than the figure), an approximate layout (3-D axes) or a refused one (a warning)
    is saved with ``bbox_inches="tight"``, whose image grows to hold it.

    The tight layout is applied once (:func:`penaltyrun.report.layout.tight_layout`: what
    ``fig.tight_layout()`` does, each panel measured once instead of twice) without leaving
    a layout engine on the figure: with one, even a placeholder, ``savefig`` draws the
    whole figure once more before drawing it into the file. The placeholder or tight
    engine a problem's plotting code left (``fig.tight_layout()`` leaves a placeholder) is
    removed first; another engine (constrained layout) is kept. The tight box of a figure
    that needs one is measured once, at the saving resolution, and given to ``savefig``
    as a box: ``bbox_inches="tight"`` would measure it after a whole dry-run draw (the
    same box; 3-D axes keep that path).

    A PNG file is compressed at zlib level :data:`PNG_COMPRESS_LEVEL` (Pillow's default is
    6): the same pixels, written in about 60 % of the time, in files about a tenth larger.
    Another format (the suffix of ``path``) is saved with matplotlib's defaults.

    Log axes are made lighter first (:func:`penaltyrun.report.ticks.lighter_log_axes`):
    tick labels in plain text (10⁻³, not mathtext), laid out without parsing, and on axes
    spanning two decades or more minor ticks at 2 and 5 × 10ᵏ only.
    """
    import warnings

    import matplotlib.pyplot as plt
    from matplotlib.layout_engine import PlaceHolderLayoutEngine, TightLayoutEngine

    from penaltyrun.report.layout import tight_layout
    from penaltyrun.report.ticks import lighter_log_axes

    if isinstance(fig.get_layout_engine(), (PlaceHolderLayoutEngine, TightLayoutEngine)):
        fig.set_layout_engine(None)  # laid out below; a hook's fig.tight_layout() left one
    lighter_log_axes(fig)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        tight_layout(fig)
    flat = all(getattr(ax, "name", "") != "3d" for ax in fig.axes)
    png = ({"pil_kwargs": {"compress_level": PNG_COMPRESS_LEVEL}}
           if Path(path).suffix.lower() == ".png" else {})
    if not caught and flat and _inside(fig):
        fig.savefig(path, dpi=dpi, **png)
    elif flat:
        fig.set_dpi(dpi)  # the box of the saved image, measured as savefig measures it
        box = fig.get_tightbbox(fig.canvas.get_renderer()).padded(TIGHT_PAD)
        fig.savefig(path, dpi=dpi, bbox_inches=box, **png)
    else:
        fig.savefig(path, dpi=dpi, bbox_inches="tight", pad_inches=TIGHT_PAD, **png)
    plt.close(fig)
    return path


def _inside(fig: Any) -> bool:
    """Whether the figure's titles, axis labels, legends and texts lie inside it (the
    tick labels are placed inside by the tight layout)."""
    renderer = fig.canvas.get_renderer()
    box = fig.bbox
    artists = [getattr(fig, "_suptitle", None), *fig.texts, *fig.legends]
    for ax in fig.axes:
        artists += [ax.title, getattr(ax, "_left_title", None),
                    getattr(ax, "_right_title", None), ax.xaxis.label, ax.yaxis.label,
                    ax.get_legend()]
    for artist in artists:
        if artist is None or not artist.get_visible() or \
                (hasattr(artist, "get_text") and not artist.get_text()):
            continue
        e = artist.get_window_extent(renderer)
        if e.x0 < box.x0 - 1 or e.y0 < box.y0 - 1 or e.x1 > box.x1 + 1 or e.y1 > box.y1 + 1:
            return False
    return True


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
