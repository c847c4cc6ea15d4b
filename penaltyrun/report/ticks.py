"""Log axes that cost less to lay out and draw: plain-text tick labels, 1-2-5 minor ticks.

Log axes made a report figure about three times as expensive as a linear one, for two
reasons, each handled here just before a figure is laid out (every figure the report saves
goes through :func:`lighter_log_axes`, :func:`penaltyrun.report.tables.save_figure`):

* Matplotlib labels logarithmic and symmetric-log axes with
  :class:`matplotlib.ticker.LogFormatterSciNotation`, whose every label is a mathtext
  expression (``$\\mathdefault{10^{-3}}$``), parsed with pyparsing to be laid out (about a
  tenth of the CPU of a report's figures). :func:`plain_log_labels` swaps it for
  :class:`PlainLogFormatter`: the same labels in Unicode superscripts (10⁻³, 2×10⁴), which
  the default font (DejaVu Sans) draws as ordinary text.
* Its minor ticks sit at 2, 3, …, 9 × 10ᵏ: eight tick objects per decade, each a few
  artists to create, lay out and draw (about 85 ms a log-log panel of five decades). On an
  axis spanning :data:`THIN_FROM_DECADES` or more, where those ticks are unlabelled marks and
  grid lines, :func:`thin_log_minor_ticks` keeps them at 2 and 5 × 10ᵏ only (the 1-2-5 grid
  of printed log paper). A narrower axis, whose minor ticks may be its only labels, keeps all.
"""

from __future__ import annotations

import re
from typing import Any

import matplotlib.ticker
import numpy as np

#: Decades a log axis must span for its minor ticks to be thinned.
THIN_FROM_DECADES = 2.0
#: The minor ticks kept on such an axis, as multiples of each power of the base.
THIN_SUBS = (2.0, 5.0)
#: Unicode superscripts of the characters of an exponent.
SUPERSCRIPTS = str.maketrans("0123456789-−", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁻")
#: A mathtext label as LogFormatterSciNotation writes it: ``$\mathdefault{...}$``.
_MATHTEXT = re.compile(r"^\$\\mathdefault\{(.*)\}\$$")
#: ``base^{exponent}`` inside such a label.
_POWER = re.compile(r"\^\{([^{}]*)\}")


def plain_text(label: str) -> str:
    """A label of :class:`~matplotlib.ticker.LogFormatterSciNotation` in plain text.

    ``$\\mathdefault{10^{-3}}$`` → ``10⁻³``, ``$\\mathdefault{2\\times10^{4}}$`` → ``2×10⁴``,
    ``$\\mathdefault{0.5}$`` → ``0.5``, a leading minus as the minus sign (−). Any other
    text is returned unchanged.
    """
    match = _MATHTEXT.match(label)
    if match is None:
        return label
    body = match.group(1).replace("\\times", "×")
    body = _POWER.sub(lambda m: m.group(1).translate(SUPERSCRIPTS), body)
    return "−" + body[1:] if body.startswith("-") else body


class PlainLogFormatter(matplotlib.ticker.LogFormatterSciNotation):
    """:class:`~matplotlib.ticker.LogFormatterSciNotation` whose labels are plain text
    (:func:`plain_text`): the same ticks labelled, the same numbers shown."""

    def __call__(self, x: float, pos: int | None = None) -> str:
        return plain_text(super().__call__(x, pos))


def plain_log_labels(fig: Any) -> None:
    """Give every axis of ``fig`` labelled by a mathtext log formatter (major or minor)
    the same formatter writing plain text (:class:`PlainLogFormatter`, its settings
    kept)."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None)):
            if axis is None:
                continue
            for getter, setter in ((axis.get_major_formatter, axis.set_major_formatter),
                                   (axis.get_minor_formatter, axis.set_minor_formatter)):
                old = getter()
                if type(old) is matplotlib.ticker.LogFormatterSciNotation:
                    new = PlainLogFormatter.__new__(PlainLogFormatter)
                    new.__dict__.update(old.__dict__)
                    setter(new)


def thin_log_minor_ticks(fig: Any) -> None:
    """Minor ticks at 2 and 5 × 10ᵏ only on every log axis of ``fig`` spanning at least
    :data:`THIN_FROM_DECADES` decades (its view limits as they are now); others unchanged."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            locator = axis.get_minor_locator()
            if axis.get_scale() != "log" or type(locator) is not matplotlib.ticker.LogLocator:
                continue
            low, high = sorted(axis.get_view_interval())
            if low > 0 and np.log10(high / low) >= THIN_FROM_DECADES:
                axis.set_minor_locator(matplotlib.ticker.LogLocator(
                    base=axis.get_transform().base, subs=THIN_SUBS))


def lighter_log_axes(fig: Any) -> None:
    """:func:`plain_log_labels` and :func:`thin_log_minor_ticks` of ``fig``."""
    plain_log_labels(fig)
    thin_log_minor_ticks(fig)


__all__ = ["PlainLogFormatter", "SUPERSCRIPTS", "THIN_FROM_DECADES", "THIN_SUBS",
           "lighter_log_axes", "plain_log_labels", "plain_text", "thin_log_minor_ticks"]
