"""Hydra's override parser, one override at a time, so that a bad one names its own key.

The command-line checks (:mod:`penaltyrun.cli.args`) and the preflight
(:mod:`penaltyrun.cli.preflight`) both parse the overrides before Hydra runs; both use
:func:`parse_each`. Each caller keeps its own wording of Hydra's message (``describe``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

from penaltyrun.errors import ConfigError

#: Hydra's options that take a value (``--info`` takes one only from its choices).
VALUE_OPTIONS = ("--cfg", "-c", "--package", "-p", "--config-path", "-cp", "--config-name",
                 "-cn", "--config-dir", "-cd", "--experimental-rerun")
INFO_CHOICES = ("all", "config", "defaults", "defaults-tree", "plugins", "searchpath")


def split_argv(argv: list[str]) -> tuple[list[str], list[str]]:
    """``argv`` split into Hydra's options with their values, and the overrides, each in
    their order: the value of an option that takes one (``-p pkg=x``) is never an
    override."""
    options: list[str] = []
    overrides: list[str] = []
    i = 0
    while i < len(argv):
        arg = argv[i]
        if arg.startswith("-"):
            options.append(arg)
            takes = arg in VALUE_OPTIONS or (arg in ("--info", "-i") and i + 1 < len(argv)
                                             and argv[i + 1] in INFO_CHOICES)
            if takes and i + 1 < len(argv):
                options.append(argv[i + 1])
                i += 1
        else:
            overrides.append(arg)
        i += 1
    return options, overrides


#: Most comma-separated values in one override (sweep values and list or matrix entries
#: together): Hydra's parser takes time quadratic in a list's length.
MAX_VALUES = 1000
#: Longest override (characters).
MAX_CHARS = 65_536


def count_values(arg: str) -> int:
    """Comma-separated values of an override: commas outside quotes, plus one."""
    return _scan(arg)[0]


def _scan(arg: str) -> tuple[int, int]:
    """(comma-separated values, deepest nesting of ``[]``, ``{}``, ``()``) outside quotes."""
    commas = depth = deepest = 0
    quote = ""
    escaped = False
    for char in arg:
        if escaped:
            escaped = False
        elif char == "\\":
            escaped = True
        elif quote:
            quote = "" if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == ",":
            commas += 1
        elif char in "[{(":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]})":
            depth -= 1
    return commas + 1, deepest


def check_size(arg: str, key: str | None = None) -> None:
    """Refuse an override longer than :data:`MAX_CHARS` characters, with more than
    :data:`MAX_VALUES` comma-separated values or nested deeper than
    :data:`~penaltyrun.yamlsafe.MAX_DEPTH` (the limit of a YAML file: Hydra's parser
    recurses once per level), before any parser sees it.

    Raises
    ------
    ConfigError
        Naming the key, the size and the limit, and where larger data belongs.
    """
    from penaltyrun.yamlsafe import MAX_DEPTH

    key = key or arg.split("=", 1)[0].lstrip("+~")[:80]
    fix = ("put larger data in a file (an LQR plant: problem.params.plant_file=plant.yaml) "
           "or split the sweep over several commands")
    if len(arg) > MAX_CHARS:
        raise ConfigError(key, f"override of {len(arg)} characters (the limit is "
                          f"{MAX_CHARS}): {fix}")
    values, depth = _scan(arg)
    if values > MAX_VALUES:
        raise ConfigError(key, f"override of {values} comma-separated values (the limit is "
                          f"{MAX_VALUES} per override): {fix}")
    if depth > MAX_DEPTH:
        raise ConfigError(key, f"override nested {depth} levels deep (the limit is "
                          f"{MAX_DEPTH}): a matrix is a list of lists")


def check_sweep_size(override: Any) -> None:
    """Refuse a parsed ``range(...)`` sweep of more than :data:`MAX_VALUES` values (a
    short text for a huge sweep: ``range(0,1000000)``).

    Raises
    ------
    ConfigError
        Naming the key, the number of values and the limit.
    """
    from hydra.core.override_parser.types import RangeSweep

    value = override.value() if override.is_sweep_override() else None
    if not isinstance(value, RangeSweep) or not value.step:
        return
    count = max(0, math.ceil((value.stop - value.start) / value.step))
    if count > MAX_VALUES:
        raise ConfigError(override.key_or_group, f"sweep of {count} values (the limit is "
                          f"{MAX_VALUES} per override): split it over several commands")


#: Most runs one ``-m`` command may sweep: the product of its sweeps' sizes.
MAX_RUNS = 10_000


def sweep_values(override: Any) -> int:
    """Values of a parsed override: the length of a ``a,b,c`` or ``range(...)`` sweep, 1
    for a single value (a glob of config choices counts 1: it is bounded by the files)."""
    from hydra.core.override_parser.types import ChoiceSweep, RangeSweep

    if not override.is_sweep_override():
        return 1
    value = override.value()
    if isinstance(value, ChoiceSweep):
        return len(value.list)
    if isinstance(value, RangeSweep) and value.step:
        return max(0, math.ceil((value.stop - value.start) / value.step))
    return 1


def check_sweep_product(overrides: Iterable[Any]) -> None:
    """Refuse a ``-m`` command whose sweeps together make more than :data:`MAX_RUNS` runs
    (each sweep within its own limit, their product not: ``a=range(0,1000)
    b=range(0,1000)`` is a million runs).

    Raises
    ------
    ConfigError
        Naming the sweeps' sizes, the product and the limit.
    """
    sizes = [(o.key_or_group, sweep_values(o)) for o in overrides]
    sizes = [(key, n) for key, n in sizes if n != 1]
    total = math.prod(n for _, n in sizes)
    if total > MAX_RUNS:
        shown = " × ".join(f"{n} ({key})" for key, n in sizes)
        raise ConfigError("-m", f"the sweeps make {total} runs ({shown}; the limit is "
                          f"{MAX_RUNS} runs per command): split the sweep over several "
                          "commands")


def parse_each(args: Iterable[str], describe: Callable[[BaseException], str],
               parser: Any = None) -> list[Any]:
    """Parse each override of ``args`` alone with Hydra's override parser.

    Parameters
    ----------
    args : iterable of str
        Overrides as on the command line (``key=value``, ``+key=value``, ``~key``, ...).
    describe : callable
        Hydra's parse error → the one-line text after ``malformed override '<arg>': ``.
    parser : hydra OverridesParser, optional
        The parser to use (a new one when not given).

    Returns
    -------
    list of hydra Override
        The parsed overrides, in the order of ``args``.

    Raises
    ------
    ConfigError
        ``<key>: malformed override '<arg>': <describe(error)>`` for the first override
        that does not parse; the key is the override's without ``+``/``~`` prefixes; or
        an override beyond the size limits (:func:`check_size`, before parsing, and
        :func:`check_sweep_size`).
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    if parser is None:
        parser = OverridesParser.create()
    parsed = []
    for arg in args:
        check_size(arg)
        try:
            parsed.extend(parser.parse_overrides([arg]))
        except HydraException as exc:
            key = arg.split("=", 1)[0].lstrip("+~")
            raise ConfigError(key, f"malformed override {arg!r}: {describe(exc)}") from None
        check_sweep_size(parsed[-1])
    return parsed
