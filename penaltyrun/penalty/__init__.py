"""Parameterizations of SPD penalty matrices.

Each map has ``dim``, ``bounds``, ``decode``, ``encode`` and the exact derivatives
``jacobian`` and ``vjp``.
"""

from penaltyrun.penalty.derivatives import NotDifferentiableError
from penaltyrun.penalty.layout import DecisionLayout, build_layout
from penaltyrun.penalty.maps import ALIASES, KINDS, Parameterization, make
from penaltyrun.penalty.selection import selected_quadratic, selector

__all__ = [
    "ALIASES",
    "KINDS",
    "NotDifferentiableError",
    "DecisionLayout",
    "Parameterization",
    "build_layout",
    "make",
    "selected_quadratic",
    "selector",
]
