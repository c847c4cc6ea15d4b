"""The checks that need no composed config: answered before Hydra (or numba) is imported.

A plain value on the command line for a ``runner.*`` option, ``mode``, an ``optimizer.*``
option or a config-group choice (``runner.n_starts=0``, ``runner.seed=-1``,
``mode=optimise``, ``optimizer.n_particles=0``, ``param=bogus``) is checked here first, by
the checks the preflight applies (:func:`penaltyrun.runner.options.check_value`,
:func:`penaltyrun.optim.make_settings` with the chosen optimizer file's other options, the
files of penaltyrun's config directory) and with the preflight's wording, so a refused value
costs the check, not the import of Hydra and of the problems' compiled kernels.

Only refusals are answered here. A value that passes, an override whose value is not a
plain literal (a sweep, a quoted string, an interpolation, a list), and every override of a
command line with options other than ``-m`` (``--config-dir``, ``--cfg`` ...) or with
``hydra.searchpath`` go through the full preflight as before.
"""

from __future__ import annotations

import re
from typing import Any

from penaltyrun.cli.overrides import split_argv
from penaltyrun.errors import ConfigError

#: Options after which the quick check still applies (other options, e.g. ``--cfg`` or a
#: user config directory, leave everything to the preflight).
PLAIN_OPTIONS = ("-m", "--multirun")
#: A value as Hydra's override grammar reads it, for the literals handled here.
_INT = re.compile(r"[+-]?(?:0|[1-9][0-9]*)")
_FLOAT = re.compile(r"[+-]?(?:(?:(?:0|[1-9][0-9]*)\.[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                    r"|(?:0|[1-9][0-9]*)[eE][+-]?[0-9]+)")
_ID = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_SKIP = object()


def settings_not_value(key: str) -> str:
    """The refusal of one value given for the settings node ``key`` (``runner=5``)."""
    return f"is a group of settings, not one value: set one of its keys, {key}.<key>=VALUE"


#: Config nodes that hold settings (a mapping), never one plain value.
SETTINGS_NODES = ("runner", "report", "matrices", "scalars", "hydra", "problem.params")


def literal(text: str) -> Any:
    """The value of a plain override literal as Hydra reads it (int, float, bool, None or
    an identifier string), or :data:`_SKIP` for anything else."""
    lower = text.lower()
    if lower in ("true", "false"):
        return lower == "true"
    if lower == "null":
        return None
    if _INT.fullmatch(text):
        return int(text)
    if _FLOAT.fullmatch(text):
        return float(text)
    if lower in ("inf", "nan") or not _ID.fullmatch(text):
        return _SKIP
    return text


def check_plain_values(argv: list[str]) -> None:
    """Refuse a plain ``runner.*`` or ``mode`` value that the preflight would refuse, with
    the preflight's own message (see the module docstring).

    Parameters
    ----------
    argv : list of str
        The command line after the program name.

    Raises
    ------
    ConfigError
        The first refused value, naming its key.
    """
    options, overrides = split_argv(argv)
    if any(opt not in PLAIN_OPTIONS for opt in options):
        return
    values = {}
    for arg in overrides:
        key, eq, text = arg.partition("=")
        name = key.lstrip("+~")
        if eq and name in SETTINGS_NODES and not text.strip().startswith("{"):
            raise ConfigError(name, settings_not_value(name))
        value = literal(text) if eq else _SKIP
        if value is _SKIP:
            continue
        values[key] = value
        if key == "mode":
            from penaltyrun.cli.modes import MODES

            if value not in MODES:
                raise ConfigError("mode", f"unknown mode {value!r}", allowed=MODES)
        elif key.startswith("runner."):
            _check_runner(key.removeprefix("runner."), value)
    groups = {arg.partition("=")[0].lstrip("+~") for arg in overrides}
    if "hydra.searchpath" in groups:
        return  # other config directories: their choices and files are the preflight's
    _check_choices(argv, {k.lstrip("+"): v for k, v in values.items()})
    if "experiment" not in groups:
        _check_optimizer(values)


def _check_choices(argv: list[str], values: dict[str, Any]) -> None:
    """A plain config-group choice (``param=bogus``) that no file of penaltyrun's own
    config directory names: the preflight's line, with its hint when such a file lies
    elsewhere (:func:`penaltyrun.cli.userconf.misplaced`) or the allowed names."""
    from penaltyrun.cli import userconf
    from penaltyrun.cli.preflight import GROUPS

    for group in GROUPS:
        value = values.get(group)
        if not isinstance(value, str):
            continue
        allowed = sorted(path.stem for path in (userconf.CONF_DIR / group).glob("*.yaml"))
        if value in allowed:
            continue
        source, _ = userconf.parse_source(argv)
        hint = userconf.misplaced(group, value, source, [])
        if hint:
            raise ConfigError(group, f"unknown choice {value!r}: {hint}")
        raise ConfigError(group, f"unknown choice {value!r}", allowed=allowed)


def _check_runner(name: str, value: Any) -> None:
    from penaltyrun.runner.options import RUNNER_OPTIONS, check_value
    from penaltyrun.runner.plan import check_n_starts

    if name not in RUNNER_OPTIONS:
        return  # the preflight names the unknown key with the config's own list
    kind, what = RUNNER_OPTIONS[name]
    check_value(name, kind, value, what)
    if name == "n_starts":
        check_n_starts(value)


def _check_optimizer(values: dict[str, Any]) -> None:
    """Plain ``optimizer.*`` values of a run that plans jobs, checked with the chosen
    shipped optimizer file's other options (:func:`penaltyrun.optim.make_settings`), as the
    preflight checks them. Left to the preflight: a mode that does not read the optimizer,
    an optimizer file that is not penaltyrun's own or names others, a key it does not list."""
    from penaltyrun.cli.modes import JOB_MODES
    from penaltyrun.cli.userconf import CONF_DIR

    given = {k.removeprefix("optimizer."): v for k, v in values.items()
             if k.startswith("optimizer.")}
    name = values.get("optimizer", "pso")
    if not given or values.get("mode", "optimize") not in JOB_MODES or \
            not isinstance(name, str):
        return
    path = CONF_DIR / "optimizer" / f"{name}.yaml"
    if not path.is_file():
        return
    from penaltyrun import yamlsafe

    shipped = yamlsafe.load_file(path)
    if not isinstance(shipped, dict) or "defaults" in shipped or \
            not set(given) <= set(shipped) - {"name"}:
        return
    from penaltyrun import optim

    options = {k: v for k, v in {**shipped, **given}.items() if k != "name"}
    optim.make_settings(str(shipped.get("name")), options)
