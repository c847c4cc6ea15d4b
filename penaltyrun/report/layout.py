"""The tight layout of a report figure, each panel's box measured once.

matplotlib's tight layout (:class:`matplotlib.layout_engine.TightLayoutEngine`, what
``fig.tight_layout()`` runs) measures the box of every panel with its tick labels, axis
labels and titles, derives the margins, then — to fit the panels into its ``rect``, the
whole figure by default — measures every box again and derives the spacing between
panels with those margins. Nothing moves between the two passes (the panels are moved
once, after both), so the second measurement repeats the first: the tick locations,
tick labels and their text extents of every axis, about a quarter of the CPU time of
saving a report figure. :func:`tight_layout` runs the same engine with each panel's
layout box kept from the first pass, so the margins and spacing are exactly those of
``TightLayoutEngine().execute(fig)``.
"""

from __future__ import annotations

from typing import Any


def tight_layout(fig: Any) -> None:
    """Apply matplotlib's tight layout to ``fig`` once (no layout engine left on it),
    measuring each panel's layout box once.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Laid out in place (:meth:`~matplotlib.figure.Figure.subplots_adjust`).
    """
    from matplotlib.layout_engine import TightLayoutEngine

    patched = []
    try:
        for ax in fig.axes:
            ax.get_tightbbox = _measured_once(ax.get_tightbbox)
            patched.append(ax)
        TightLayoutEngine().execute(fig)
    finally:
        for ax in patched:
            vars(ax).pop("get_tightbbox", None)


def _measured_once(measure: Any) -> Any:
    """``measure`` (a panel's bound ``get_tightbbox``) answering its layout-only calls
    with one renderer from the first one's box; every other call passes through."""
    boxes: dict[int, Any] = {}

    def once(*args: Any, **kwargs: Any) -> Any:
        if len(args) == 1 and kwargs == {"for_layout_only": True}:
            key = id(args[0])
            if key not in boxes:
                boxes[key] = measure(*args, **kwargs)
            return boxes[key]
        return measure(*args, **kwargs)

    return once


__all__ = ["tight_layout"]
