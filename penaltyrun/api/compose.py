"""The config of one cell, composed from penaltyrun's YAML files without Hydra.

The command line composes ``conf/config.yaml`` with one file of each group (``problem``,
``param``, ``optimizer``) through Hydra; :func:`compose` reads the same files with the same
YAML rules (OmegaConf's: ``1e-8`` is a float), so a cell tuned from Python has the same
nodes, the same ``config_hash`` and the same job ids as the same cell run from the command
line.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path, PurePath
from typing import Any

import yaml

from penaltyrun import yamlsafe
from penaltyrun.errors import ConfigError
from penaltyrun.problems.criteria import hashed_node
from penaltyrun.runner.spec import OPTIONAL_OPTIMIZER_OPTIONS, RunnerOptions, RunSpec
from penaltyrun.typed import is_number

CONF = Path(__file__).resolve().parent.parent / "conf"
#: ``runner.*`` values the API uses where the command line's defaults differ: no report
#: at the end of a run (:meth:`~penaltyrun.api.result.TuneResult.report` writes it), no
#: progress bar, no forecast (it would spend extra evaluations of the cost to time them).
API_RUNNER = {"report": False, "progress": False, "forecast_samples": 0}

_FLOAT = re.compile(r"""^(?:
     [-+]?[0-9]+(?:_[0-9]+)*\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?[0-9]+(?:_[0-9]+)*(?:[eE][-+]?[0-9]+)
    |\.[0-9]+(?:_[0-9]+)*(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X)


class _Loader(yaml.SafeLoader):
    """YAML as OmegaConf reads it: ``1e-8`` is a float, dates stay strings."""


_Loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT, list("-+0123456789."))
_Loader.yaml_implicit_resolvers = {
    key: [(tag, rx) for tag, rx in resolvers if tag != "tag:yaml.org,2002:timestamp"]
    for key, resolvers in _Loader.yaml_implicit_resolvers.items()}


def read_yaml(path: Path) -> dict[str, Any]:
    """One config file as a dict (empty file: ``{}``)."""
    return yamlsafe.load_file(path, loader=_Loader) or {}


def choices(group: str) -> tuple[str, ...]:
    """Names of the files of config group ``group`` (``problem``, ``param``, ...)."""
    return tuple(sorted(p.stem for p in (CONF / group).glob("*.yaml")))


def group_node(group: str, name: str) -> dict[str, Any]:
    """The node of ``group=name``, with the group-internal ``defaults`` list applied.

    Raises
    ------
    ConfigError
        No such file in the group (the allowed names listed).
    """
    path = CONF / group / f"{name}.yaml"
    if not path.is_file():
        raise ConfigError(group, f"unknown choice {name!r}", allowed=choices(group))
    data = read_yaml(path)
    defaults = data.pop("defaults", None) or []
    node: dict[str, Any] = {}
    own_merged = False
    for entry in defaults:
        if entry == "_self_":
            node = _merge(node, data)
            own_merged = True
        else:
            node = _merge(node, group_node(group, str(entry)))
    return node if own_merged else _merge(node, data)


def plain(value: Any, key: str = "value", depth: int = 0) -> Any:
    """``value`` as the plain data a config holds: numpy arrays and scalars as lists and
    Python numbers, tuples as lists, mappings as dicts (e.g. a plant matrix ``A`` given as
    an array is stored, hashed and recorded as the nested list the command line takes).

    Raises
    ------
    ConfigError
        On ``key``: nested deeper than :data:`~penaltyrun.yamlsafe.MAX_DEPTH` levels, the
        limit of a config file and of a command-line override.
    """
    if depth > yamlsafe.MAX_DEPTH:
        raise ConfigError(key, f"nested deeper than {yamlsafe.MAX_DEPTH} levels (the limit of a "
                          "config value; a matrix is a list of lists)")
    if isinstance(value, Mapping):
        return {str(k): plain(v, key, depth + 1) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v, key, depth + 1) for v in value]
    if hasattr(value, "tolist") and callable(value.tolist):  # numpy arrays and scalars
        return plain(value.tolist(), key, depth)
    if isinstance(value, PurePath):  # a file a parameter names, as the command line gives it
        return str(value)
    if value is not None and not isinstance(value, (str, int, float, bool)):
        raise ConfigError(key, f"{type(value).__name__} is not a config value (numbers, "
                               "text, true/false, null, lists and mappings of them)")
    return value


def _merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def problem_node(name: str, module: str | None) -> dict[str, Any]:
    """The ``problem`` node: the group file of a built-in problem, else ``{name, module,
    params}`` for a problem module outside penaltyrun (``module`` None: an entry point)."""
    if module is None and (CONF / "problem" / f"{name}.yaml").is_file():
        return group_node("problem", name)
    node: dict[str, Any] = {"name": name}
    if module is not None:
        node["module"] = module
    node["params"] = {}
    return node


def check_like_defaults(values: Mapping[str, Any], defaults: Mapping[str, Any],
                        prefix: str) -> None:
    """Check values against the type of the shipped default of the same key: a number
    for a number, true/false for a boolean, a list of as many numbers for a list of numbers,
    a list for any other list (a ``null`` default accepts anything; the problem checks it)."""
    for key, default in defaults.items():
        value = values.get(key, default)
        if default is None or value is None:
            continue
        if isinstance(default, bool):
            ok, what = isinstance(value, bool), "true or false"
        elif isinstance(default, (int, float)):
            ok, what = is_number(value), "a number"
        elif isinstance(default, list) and not all(is_number(v) for v in default):
            ok, what = isinstance(value, list), "a list"
        elif isinstance(default, list):
            ok = isinstance(value, list) and len(value) == len(default) and all(
                is_number(v) for v in value)
            what = f"a list of {len(default)} numbers"
        else:
            continue
        if not ok:
            hint = ""
            if isinstance(value, str) and value.strip().lower() in YAML_INFINITY:
                hint = " (Hydra reads YAML's .inf as text: write inf or -inf)"
            raise ConfigError(f"{prefix}.{key}", f"must be {what}, got {value!r}{hint}")


#: YAML's spellings of infinity, which the command-line grammar reads as strings.
YAML_INFINITY = (".inf", "+.inf", "-.inf")


def checked_params(node: Mapping[str, Any], params: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters of problem node ``node`` with ``params`` over them, each given value
    checked against the type of its shipped default (:func:`check_like_defaults`).

    Raises
    ------
    ConfigError
        On ``problem.params.<key>``: a value of the wrong type, or nested too deep.
    """
    given = plain(params, "params")
    check_like_defaults(given, node.get("params") or {}, "problem.params")
    return _merge(node.get("params") or {}, given)


def compose(problem: str, module: str | None, *, case: str | None, param: str,
            optimizer: str, optimizer_options: Mapping[str, Any] | None,
            params: Mapping[str, Any] | None, runner: Mapping[str, Any],
            param_options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The composed config of one cell (the dict the command line's Hydra config resolves
    to for the same choices and overrides).

    Raises
    ------
    ConfigError
        An unknown map or optimizer, an optimizer or map option the optimizer or map does
        not have, or an unknown runner option.
    """
    for key, value in (("params", params), ("optimizer_options", optimizer_options),
                       ("param_options", param_options)):
        if value is not None and not isinstance(value, Mapping):
            raise ConfigError(key, f"must be a mapping {{name: value}}, got "
                                   f"{type(value).__name__}")
    base = read_yaml(CONF / "config.yaml")
    base.pop("defaults", None)
    base.pop("hydra", None)
    prob = problem_node(problem, module)
    if params:
        prob["params"] = checked_params(prob, params)
    opt = group_node("optimizer", optimizer)
    _refuse_unknown(optimizer_options, opt, "optimizer", f"an option of optimizer "
                    f"{optimizer!r}", extra=OPTIONAL_OPTIMIZER_OPTIONS)
    opt.update(plain(optimizer_options or {}, "optimizer_options"))
    par = group_node("param", param)
    _refuse_unknown(param_options, par, "param", f"an option of map {param!r}")
    par.update(plain(param_options or {}, "param_options"))
    _refuse_unknown(runner, base["runner"], "runner", "a runner option")
    config = {"problem": prob, "param": par, "optimizer": opt}
    config.update(base)
    config["case"] = case
    config["runner"] = _merge(base["runner"], plain(runner, "runner"))
    return config


def _refuse_unknown(given: Mapping[str, Any] | None, node: Mapping[str, Any], group: str,
                    what: str, extra: tuple[str, ...] = ()) -> None:
    """Refuse a key of ``given`` that the group's ``node`` (its ``name`` aside) and
    ``extra`` do not have: ``ConfigError`` on ``<group>.<key>``, "not <what>", listing the
    node's keys."""
    known = set(node) - {"name"}
    unknown = sorted(set(given or {}) - known - set(extra))
    if unknown:
        raise ConfigError(f"{group}.{unknown[0]}", f"not {what}", allowed=sorted(known))


def run_spec(config: Mapping[str, Any]) -> RunSpec:
    """The :class:`~penaltyrun.runner.spec.RunSpec` of a composed config (as the command
    line builds it from its Hydra config, :func:`penaltyrun.cli.spec.run_spec`).

    Raises
    ------
    ConfigError
        A ``runner.*`` option of the wrong type or out of range.
    """
    hashed = {k: config[k] for k in ("problem", "case", "param", "optimizer")}
    hashed["problem"] = hashed_node(config["problem"])
    hashed["seed"] = config["runner"]["seed"]
    prob = config["problem"]
    params = {k: v for k, v in (prob.get("params") or {}).items() if v is not None}
    report = config.get("report") or {}
    return RunSpec(
        problem=prob["name"], case=config["case"], param=config["param"]["name"],
        optimizer=config["optimizer"]["name"], problem_params=params,
        param_options=dict(config["param"]),
        optimizer_options={k: v for k, v in config["optimizer"].items() if k != "name"},
        problem_module=str(prob["module"]) if prob.get("module") else None,
        runner=RunnerOptions.from_mapping(config["runner"]), hashed=hashed,
        config_text=yaml.safe_dump(dict(config), sort_keys=False, allow_unicode=True),
        report_output=report.get("output") or None, report_paper=bool(report.get("paper",
                                                                                 True)))


__all__ = ["API_RUNNER", "CONF", "YAML_INFINITY", "check_like_defaults", "checked_params",
           "choices", "compose", "group_node", "plain",
           "problem_node", "read_yaml", "run_spec"]
