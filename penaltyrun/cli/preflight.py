"""Checks of the command line before Hydra runs, so every mistake is one clear line.

:func:`preflight` parses the overrides, checks config-group choices against the files Hydra
will search (penaltyrun's ``conf/`` and the user's directories) and composes the config once
to catch unknown keys and type errors; :mod:`penaltyrun.cli.checks` checks the values.
"""

from __future__ import annotations

from typing import Any

from omegaconf import DictConfig, OmegaConf

from penaltyrun.cli import checks, userconf
from penaltyrun.cli import spec as cells
from penaltyrun.cli.overrides import (
    check_size,
    check_sweep_product,
    check_sweep_size,
    parse_each,
    split_argv,
)
from penaltyrun.errors import ConfigError

GROUPS = ("problem", "param", "optimizer", "experiment")
#: Hydra settings the preflight needs to check the run directory.
RUN_DIR_KEYS = ("hydra.run.dir", "hydra.sweep.dir", "hydra.sweep.subdir")


def _searchpath(parsed: list[Any]) -> tuple[list[str], list[str]]:
    """``hydra.searchpath`` overrides of the command line, and their entries."""
    lines = [o.input_line for o in parsed if o.key_or_group == "hydra.searchpath"]
    entries = []
    for o in parsed:
        if o.key_or_group == "hydra.searchpath" and not o.is_delete():
            value = o.value()
            entries += [str(v) for v in (value if isinstance(value, list) else [value])]
    return lines, entries


def _first_line(exc: BaseException) -> str:
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    return " ".join(lines[:2]) if lines else type(exc).__name__


def preflight(argv: list[str]) -> str:
    """Check the command line before Hydra runs, so every mistake is one clear line.

    Parses the overrides (syntax), checks config-group choices against the files Hydra
    will search (penaltyrun's ``conf/`` and the user's directories), checks the YAML of
    the chosen user files, then composes the config once (first value of each sweep) to
    catch unknown keys and type errors, and once per further sweep value. With ``-m`` the
    sweeps of the config's ``hydra.sweeper.params`` (an experiment profile's) are checked
    exactly as those of the command line. Returns the composed ``mode``.

    Raises
    ------
    ConfigError
        Naming the key and, where there is a list, the allowed values.
    """
    from hydra.core.override_parser.overrides_parser import OverridesParser

    source, argv = userconf.parse_source(argv)
    args = [a for a in split_argv(argv)[1] if "=" in a or a.startswith("~")]
    parser = OverridesParser.create()
    parsed = parse_each(args, _first_line, parser)
    for o in parsed:
        if o.key_or_group.startswith("hydra.sweeper.params"):
            name = o.key_or_group.removeprefix("hydra.sweeper.params").lstrip(".") or "KEY"
            raise ConfigError(o.key_or_group, "sweeps are given on the command line as "
                              f"{name}=a,b with -m (hydra.sweeper.params belongs in an "
                              "experiment profile)")
    hydra_overrides, searchpath = _searchpath(parsed)
    multirun = "-m" in argv or "--multirun" in argv
    with userconf.hydra_context(source):
        userconf.give_config_loader(parsed)
        _check_choices(parsed, source, hydra_overrides, searchpath)
        grouped = _compose_groups(parsed, source, hydra_overrides) if multirun else None
        profile = _profile_sweeps(grouped, parsed, parser) if multirun else []
        if multirun:
            check_sweep_product(parsed + profile + _profile_sweeps(grouped, parsed, parser,
                                                                   hydra_keys=True))
        from_profile = {o.key_or_group for o in profile}
        try:
            _check_choices(parsed + profile, source, hydra_overrides, searchpath)
            cfg = _compose_dry(parsed + profile, source, hydra_overrides, multirun=multirun)
        except ConfigError as exc:
            if exc.key not in from_profile:
                raise
            raise ConfigError(exc.key, f"{exc.message} (a sweep value of the config's "
                              "hydra.sweeper.params)", allowed=exc.allowed) from None
        if multirun and cfg.mode == "evaluate":
            checks.check_evaluate_sweeps(parsed + profile)
        return str(cfg.mode)


def _compose_groups(parsed: list[Any], source: userconf.ConfigSource,
                    hydra_overrides: list[str]) -> DictConfig | None:
    """The config composed from the command line's group choices alone (with its ``hydra``
    node), to read an experiment profile's sweeps before the values are checked; ``None``
    when it does not compose (the full check then names the mistake)."""
    from hydra import compose
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    groups = [o.input_line for o in parsed
              if o.key_or_group.lstrip("+") in GROUPS and not o.is_sweep_override()]
    try:
        return compose(config_name=source.config_name, overrides=groups + hydra_overrides,
                       return_hydra_config=True)
    except (HydraException, OmegaConfBaseException):
        return None


def _profile_sweeps(cfg: DictConfig | None, parsed: list[Any], parser: Any,
                    hydra_keys: bool = False) -> list[Any]:
    """The sweeps of the composed config's ``hydra.sweeper.params`` (an experiment
    profile's) as parsed overrides, leaving out keys the command line sets itself (those
    win, as in Hydra's basic sweeper); those of ``hydra.*`` keys instead with
    ``hydra_keys`` (not checked as config keys, but swept by Hydra all the same: they
    count in the number of runs).

    Raises
    ------
    ConfigError
        A sweep that is not valid override syntax.
    """
    from hydra.errors import HydraException

    params = OmegaConf.select(cfg, "hydra.sweeper.params") if cfg is not None else None
    if not isinstance(params, DictConfig):
        return []
    given = {o.key_or_group for o in parsed}
    out = []
    for key, value in OmegaConf.to_container(params, resolve=False).items():
        if key in given or str(key).startswith("hydra") != hydra_keys:
            continue
        line = f"{key}={value}"
        check_size(line, f"hydra.sweeper.params.{key}")
        try:
            out.extend(parser.parse_overrides([line]))
            check_sweep_size(out[-1])
        except HydraException as exc:
            raise ConfigError(f"hydra.sweeper.params.{key}", f"malformed sweep {line!r}: "
                              f"{_first_line(exc)}") from None
    return out


def _check_choices(parsed: list[Any], source: userconf.ConfigSource,
                   hydra_overrides: list[str], searchpath: list[str]) -> None:
    """Config-group choices against the files Hydra will find; chosen files' YAML."""
    choices = []
    for o in parsed:
        if o.key_or_group not in GROUPS or o.is_delete():
            continue
        values = list(o.sweep_string_iterator()) if o.is_sweep_override() else \
            [o.get_value_element_as_str()]
        allowed = userconf.group_options(o.key_or_group, source, hydra_overrides)
        for value in values:
            if value not in allowed:
                hint = userconf.misplaced(o.key_or_group, value, source, searchpath)
                if hint:
                    raise ConfigError(o.key_or_group, f"unknown choice {value!r}: {hint}")
                raise ConfigError(o.key_or_group, f"unknown choice {value!r}", allowed=allowed)
            choices.append((o.key_or_group, value))
    userconf.check_files(source, searchpath, choices)


def _compose_dry(parsed: list[Any], source: userconf.ConfigSource,
                 hydra_overrides: list[str], multirun: bool = False) -> DictConfig:
    """Compose once (first value of each sweep) to catch unknown keys and type errors,
    then each further sweep value; returns the config composed (with its ``hydra`` node)."""
    from hydra import compose
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    dry = []
    for o in parsed:
        if o.key_or_group.startswith("hydra"):
            if o.key_or_group in RUN_DIR_KEYS and not o.is_sweep_override():
                dry.append(o.input_line)
            continue
        values = list(o.sweep_string_iterator()) if o.is_sweep_override() else \
            [o.get_value_element_as_str()]
        dry.append(o.input_line if not o.is_sweep_override()
                   else f"{o.get_key_element()}={values[0]}")
    dry += hydra_overrides
    name = source.config_name
    try:
        cfg = compose(config_name=name, overrides=dry, return_hydra_config=True)
    except (HydraException, OmegaConfBaseException) as exc:
        hits = [o for o in parsed if o.key_or_group in str(exc)]
        bad = max(hits, key=lambda o: len(o.key_or_group)) if hits else None
        key = bad.key_or_group if bad else "override"
        if "Could not override" not in str(exc) or bad is None:
            raise ConfigError(key, _first_line(exc)) from None
        groups = [d for d in dry if d.split("=", 1)[0].lstrip("+") in GROUPS]
        schema = cells.with_params_schema(compose(config_name=name,
                                                  overrides=groups + hydra_overrides))
        parent = OmegaConf.select(schema, key.rpartition(".")[0] or "")
        allowed = sorted(parent.keys()) if isinstance(parent, DictConfig) else None
        if key.startswith("problem.params.") and key.rpartition(".")[2] in (allowed or ()):
            raise ConfigError(key, "a parameter the problem's YAML does not list: a sweep in "
                              f"hydra.sweeper.params sets it as ++{key}") from None
        raise ConfigError(key, "unknown config key", allowed=allowed) from None
    groups = [d for d in dry if d.split("=", 1)[0].lstrip("+") in GROUPS]
    base = compose(config_name=name, overrides=groups + hydra_overrides)
    checks.check_composed(cfg, base, multirun=multirun)
    for variant in checks.sweep_variants(parsed, dry):
        checks.check_variant(compose, variant, config_name=name)
    return cfg
