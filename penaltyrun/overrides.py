"""Hydra's override parser, one override at a time, so that a bad one names its own key.

The command-line checks (:mod:`penaltyrun.cliargs`) and the preflight
(:mod:`penaltyrun.preflight`) both parse the overrides before Hydra runs; both use
:func:`parse_each`. Each caller keeps its own wording of Hydra's message (``describe``).
"""

from __future__ import annotations

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
        that does not parse; the key is the override's without ``+``/``~`` prefixes.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.errors import HydraException

    if parser is None:
        parser = OverridesParser.create()
    parsed = []
    for arg in args:
        try:
            parsed.extend(parser.parse_overrides([arg]))
        except HydraException as exc:
            key = arg.split("=", 1)[0].lstrip("+~")
            raise ConfigError(key, f"malformed override {arg!r}: {describe(exc)}") from None
    return parsed
