"""Log-axis tick labels in plain Unicode text (10⁻³, 2×10⁴) instead of mathtext.

Matplotlib labels logarithmic and symmetric-log axes with
:class:`matplotlib.ticker.LogFormatterSciNotation`, whose every label is a mathtext
expression (``$\\mathdefault{10^{-3}}$``). Laying such a label out parses it with
pyparsing, which cost about a tenth of the CPU time of a report's figures. The same labels
written with Unicode superscripts (which the default font, DejaVu Sans, draws) are laid out
as ordinary text. :func:`plain_log_labels` swaps the formatters of a figure's log axes for
:class:`PlainLogFormatter` just before the figure is laid out; every figure the report saves
goes through it (:func:`penaltyrun.report.tables.save_figure`).
"""

from __future__ import annotations

import re
from typing import Any

import matplotlib.ticker

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


__all__ = ["PlainLogFormatter", "SUPERSCRIPTS", "plain_log_labels", "plain_text"]
