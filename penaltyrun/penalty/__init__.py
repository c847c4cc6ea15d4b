"""Parameterizations of SPD penalty matrices (``dim``, ``bounds``, ``decode``, ``encode``)."""

from penaltyrun.penalty.layout import DecisionLayout, build_layout
from penaltyrun.penalty.maps import ALIASES, KINDS, Parameterization, make
from penaltyrun.penalty.selection import selected_quadratic, selector

__all__ = [
    "ALIASES",
    "KINDS",
    "DecisionLayout",
    "Parameterization",
    "build_layout",
    "make",
    "selected_quadratic",
    "selector",
]
