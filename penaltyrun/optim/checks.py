"""Type checks of optimizer options derived from the settings dataclasses' annotations.

Every optimizer's settings class is a dataclass whose field annotations say what a config
value must be (``int``, ``float``, ``bool``, ``str``, ``tuple[float, float]``,
``int | None`` ...); :func:`coerce_field` checks a config value against that annotation, so
a new optimizer (or a new field) is checked without any code here. Ranges and choices are
the settings class's own business: an optional ``validate(self) -> None`` method raising
:class:`~penaltyrun.errors.ConfigError`.
"""

from __future__ import annotations

import functools
import math
import types
import typing
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.typed import is_int, is_number

_NAMES = {int: "an integer", float: "a number", bool: "true or false", str: "a string",
          type(None): "null"}


def describe(hint: Any) -> str:
    """Readable form of a type annotation, e.g. ``an integer or null``."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(describe(a) for a in typing.get_args(hint))
    if origin is tuple:
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return f"a list of {describe(args[0]).removeprefix('a ').removeprefix('an ')}s"
        return f"a list of {len(args)} values"
    return _NAMES.get(hint, getattr(hint, "__name__", str(hint)))


def _coerce(value: Any, hint: Any) -> Any:
    """``value`` converted to ``hint``; raises TypeError if it does not fit."""
    if hint is Any:
        return value
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        for arg in typing.get_args(hint):
            try:
                return _coerce(value, arg)
            except TypeError:
                continue
        raise TypeError
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise TypeError
        args = typing.get_args(hint)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_coerce(v, args[0]) for v in value)
        if len(value) != len(args):
            raise TypeError
        return tuple(_coerce(v, a) for v, a in zip(value, args))
    if hint is type(None):
        if value is not None:
            raise TypeError
        return None
    if hint is bool:
        if not isinstance(value, bool):
            raise TypeError
        return value
    if hint is int:
        if not is_int(value):
            raise TypeError
        return value
    if hint is float:
        if not is_number(value) or math.isnan(value):
            raise TypeError
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise TypeError
        return value
    return value  # an annotation this checker does not know: left to validate()


def coerce_field(key: str, value: Any, hint: Any) -> Any:
    """Check config ``value`` of option ``key`` against annotation ``hint``; return it
    converted (int → float for float fields, list → tuple).

    Raises
    ------
    ConfigError
        ``<key>: must be <type>, got <value>``.
    """
    try:
        return _coerce(value, hint)
    except TypeError:
        raise ConfigError(key, f"must be {describe(hint)}, got {value!r}") from None


def settings_hints(cls: type) -> dict[str, Any]:
    """Field annotations of a settings dataclass, evaluated (once per class: evaluating
    them costs about 1 ms, every job builds its settings)."""
    return dict(_hints(cls))


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def check_range(key: str, value: float, lo: float | None = None, hi: float | None = None,
                lo_open: bool = False, hi_open: bool = False) -> None:
    """Raise ConfigError unless ``value`` is finite and within the given bounds."""
    ok = math.isfinite(value)
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value < hi if hi_open else value <= hi
    if not ok:
        left = "(" if lo_open or lo is None else "["
        right = ")" if hi_open or hi is None else "]"
        interval = f"{left}{'-inf' if lo is None else f'{lo:g}'}, " \
                   f"{'inf' if hi is None else f'{hi:g}'}{right}"
        raise ConfigError(key, f"must be a finite number in {interval}, got {value!r}")


def check_choice(key: str, value: Any, allowed: tuple[str, ...]) -> None:
    """Raise ConfigError unless ``value`` is one of ``allowed``."""
    if value not in allowed:
        raise ConfigError(key, f"unknown choice {value!r}", allowed=allowed)
