"""Type checks of configuration and record values that Python's ``isinstance`` gets wrong.

``True`` and ``False`` are instances of ``int`` in Python, so ``isinstance(value, int)``
takes ``n_starts: true`` from a YAML file as one start. Every check of "an integer" or "a
number" in penaltyrun goes through :func:`is_int` and :func:`is_number`, which refuse a
bool. The callers keep their own error messages. Plain Python without imports from the
package, so every layer can use it.
"""

from __future__ import annotations

from numbers import Integral, Real

__all__ = ["is_int", "is_number"]


def is_int(value: object, *, any_integral: bool = False) -> bool:
    """Whether ``value`` is an integer and not a bool.

    Parameters
    ----------
    value : object
        The value to check.
    any_integral : bool, optional
        Also take any :class:`numbers.Integral` (e.g. ``numpy.int64``, as a caller from
        Python may pass); by default only a Python ``int`` (what YAML and JSON give).

    Returns
    -------
    bool
    """
    kinds = Integral if any_integral else int
    return isinstance(value, kinds) and not isinstance(value, bool)


def is_number(value: object, *, any_real: bool = False) -> bool:
    """Whether ``value`` is a real number (an int or a float; NaN and infinities included)
    and not a bool.

    Parameters
    ----------
    value : object
        The value to check.
    any_real : bool, optional
        Also take any :class:`numbers.Real` (e.g. ``numpy.float32``, ``numpy.int64``); by
        default only a Python ``int`` or ``float`` (``numpy.float64`` is a ``float``).

    Returns
    -------
    bool
    """
    kinds = Real if any_real else (int, float)
    return isinstance(value, kinds) and not isinstance(value, bool)
