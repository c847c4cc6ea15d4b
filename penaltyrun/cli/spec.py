"""From one composed config (one cell of a sweep) to its typed run specification.

:func:`run_spec` is the one boundary: ``mode=optimize`` (:func:`penaltyrun.cli.app.run_optimize`),
``mode=plan`` (:mod:`penaltyrun.cli.planmode`) and the preflight
(:mod:`penaltyrun.cli.checks`) each turn the composed config into the cell's
:class:`~penaltyrun.runner.spec.RunSpec` here, then build and plan it as the runner does, so
that a plan forecasts exactly the jobs a run would run and the preflight refuses what the
run would refuse."""

from __future__ import annotations

import copy
import dataclasses
from typing import Any

from omegaconf import DictConfig, OmegaConf, open_dict

from penaltyrun.errors import ConfigError


def plain(node: Any) -> Any:
    """Plain Python value of a config node (resolved), or None."""
    return OmegaConf.to_container(node, resolve=True) if node is not None else None


def problem_params(cfg: DictConfig) -> dict[str, Any]:
    """Problem overrides from ``problem.params`` (nulls mean "from the case table")."""
    params = plain(cfg.problem.get("params")) or {}
    return {k: v for k, v in params.items() if v is not None}


def params_fields(name: str, module_path: str | None = None) -> dict[str, Any]:
    """Fields of problem ``name``'s ``Params`` dataclass with their defaults as plain config
    values (``None`` where a default is not a number, string, boolean or list of them);
    ``{}`` if the module cannot be imported or defines no such dataclass."""
    from penaltyrun import problems

    try:
        mod = problems.module(str(name), module_path)
    except ConfigError:
        return {}
    cls = getattr(mod, "Params", None)
    if not (isinstance(cls, type) and dataclasses.is_dataclass(cls)):
        return {}
    try:
        defaults = cls()
    except TypeError:  # a field without a default
        return {f.name: None for f in dataclasses.fields(cls)}
    return {f.name: _config_value(getattr(defaults, f.name)) for f in dataclasses.fields(cls)}


def _config_value(value: Any) -> Any:
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (tuple, list)):
        items = [_config_value(v) for v in value]
        return None if any(v is None for v in items) else items
    return None


def with_params_schema(base: DictConfig) -> DictConfig:
    """``base`` with every field of the problem's ``Params`` dataclass in ``problem.params``.

    A problem's parameters are the fields of its ``Params`` dataclass, whether or not its
    YAML file lists them: the missing ones are added with their dataclass defaults, so that
    the command-line checks know their names (unknown keys are still refused, with the
    allowed list) and their types.
    """
    node = base.get("problem")
    if not isinstance(node, DictConfig) or not node.get("name"):
        return base
    listed = plain(node.get("params")) or {}
    missing = {k: v for k, v in params_fields(node.name, problem_module(base) or None).items()
               if k not in listed}
    if not missing:
        return base
    out = copy.deepcopy(base)
    with open_dict(out):
        if not isinstance(out.problem.get("params"), DictConfig):
            out.problem.params = {}
        for key, value in missing.items():
            out.problem.params[key] = value
    return out


def problem_module(cfg: DictConfig) -> str | None:
    """Module of a problem outside penaltyrun (``problem.module``), or None."""
    value = cfg.problem.get("module")
    return str(value) if value else None


def optimizer_options(cfg: DictConfig) -> dict[str, Any]:
    """The optimizer's settings (``optimizer.*`` without its name)."""
    return {k: v for k, v in plain(cfg.optimizer).items() if k != "name"}


def run_spec(cfg: DictConfig) -> Any:
    """The one boundary from a composed config to the typed run specification: the cell's
    :class:`~penaltyrun.runner.spec.RunSpec` (its nodes as plain data, the checked
    :class:`~penaltyrun.runner.spec.RunnerOptions`, ``config_hash``'s input and the YAML).

    Raises
    ------
    ConfigError
        A ``runner.*`` option of the wrong type or out of range.
    """
    from penaltyrun.problems.criteria import hashed_node
    from penaltyrun.runner.spec import RunnerOptions, RunSpec

    hashed = {"problem": hashed_node(plain(cfg.problem)), "case": cfg.case,
              "param": plain(cfg.param),
              "optimizer": plain(cfg.optimizer), "seed": cfg.runner.seed}
    return RunSpec(
        problem=cfg.problem.name, case=cfg.case, param=cfg.param.name,
        optimizer=cfg.optimizer.name, problem_params=problem_params(cfg),
        param_options=plain(cfg.param), optimizer_options=optimizer_options(cfg),
        problem_module=problem_module(cfg), runner=RunnerOptions.from_mapping(plain(cfg.runner)),
        hashed=hashed, config_text=OmegaConf.to_yaml(cfg),
        report_output=cfg.report.output or None, report_paper=bool(cfg.report.paper))
