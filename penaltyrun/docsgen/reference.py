"""Reference pages generated from the code, so that they cannot drift from it.

Each ``page_*`` function returns the Markdown of one page; :func:`pages` maps their file
names (relative to ``docs/``) to their text. Everything is read from what exists at build
time — the optimizers in :data:`penaltyrun.optim.OPTIMIZERS`, the problems in
:data:`penaltyrun.problems.REGISTRY`, every YAML file under ``penaltyrun/conf`` — so a key,
an optimizer, a problem or a profile added later appears without an edit here.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import re
import typing
from pathlib import Path
from typing import Any

from penaltyrun.docsgen.layout import md_cell
from penaltyrun.docsgen.sources import (
    attribute_docs,
    header_comment,
    numpydoc_to_md,
    rst_to_md,
    yaml_entries,
)
from penaltyrun.errors import ConfigError

CONF = Path(__file__).resolve().parents[1] / "conf"
#: Value kinds of the runner's option checks → the type a user writes.
_KINDS = {"pos_int": "int", "nonneg_int": "int", "forecast_samples": "int", "bool": "bool",
          "pos_float": "float", "unit_open": "float", "workers": "int or auto",
          "chunks": "int or auto",
          "choice": "str", "evaluate_on": "str", "progress": "bool or auto",
          "address": "str or null", "opt_pos_float": "float or null"}
_PROBE = {int: (-(10 ** 12), 0, 10 ** 12), float: (-1e300, 1e300),
          str: ("\x00not-a-choice",)}


def cell(value: Any) -> str:
    """A value as a Markdown table cell."""
    if isinstance(value, float) and math.isinf(value):
        text = "inf" if value > 0 else "-inf"
    elif isinstance(value, tuple):
        text = "[" + ", ".join(str(v) for v in value) + "]"
    elif value is None:
        text = "null"
    elif isinstance(value, bool):
        text = str(value).lower()
    else:
        text = str(value)
    text = md_cell(text)
    return f"`{text}`" if text else ""


def _text(text: str) -> str:
    """Prose for a table cell: one line, pipes escaped, no tracker references."""
    text = re.sub(r"\s*\((?:see )?issue[^)]*\)", "", text, flags=re.IGNORECASE)
    return md_cell(text)


def type_name(hint: Any) -> str:
    """Short readable form of a type annotation (``int | None``, ``tuple[float, ...]``)."""
    if isinstance(hint, type) and not typing.get_args(hint):
        return hint.__name__
    return str(hint).replace("typing.", "").replace("NoneType", "None")


def probe_range(cls: type, name: str, hint: Any) -> str:
    """What ``validate()`` of settings class ``cls`` accepts for field ``name``: the
    message of the error it raises for out-of-range probes, or ``any <type>``."""
    base = [a for a in typing.get_args(hint) if a is not type(None)] or [hint]
    for probe in _PROBE.get(base[0], ()):
        try:
            settings = cls(**{name: probe})
            validate = getattr(settings, "validate", None)
            if callable(validate):
                validate()
        except ConfigError as exc:
            text = str(exc).split(": ", 1)[-1]
            text = text.split(", got ")[0].removeprefix("must be ")
            if exc.allowed:
                return "one of " + ", ".join(f"`{a}`" for a in exc.allowed)
            return text
        except Exception:  # a probe the settings class rejects in its own way  # noqa: BLE001
            continue
    from penaltyrun.optim.checks import describe
    return "any " + describe(hint).removeprefix("a ").removeprefix("an ")


def optimizer_section(name: str, cls: type) -> list[str]:
    """Table of one optimizer's settings and the presets that select it."""
    hints = typing.get_type_hints(cls)
    docs = attribute_docs(cls)
    lines = [f"### `{name}`", "", rst_to_md((inspect.getdoc(cls) or "").split("\n\n")[0]),
             "", "| key | type | default | range | meaning |", "|---|---|---|---|---|"]
    for field in dataclasses.fields(cls):
        default = field.default if field.default is not dataclasses.MISSING else (
            field.default_factory() if field.default_factory is not dataclasses.MISSING
            else None)
        lines.append(f"| `optimizer.{field.name}` | {cell(type_name(hints[field.name]))} | "
                     f"{cell(default)} | {_text(probe_range(cls, field.name, hints[field.name]))}"
                     f" | {_text(docs.get(field.name, ''))} |")
    presets = []
    for path in sorted((CONF / "optimizer").glob("*.yaml")):
        entries = {e["key"]: e for e in yaml_entries(path)}
        if entries.get("name", {}).get("value") != name:
            continue
        changed = [f"`{k}={cell(e['value']).strip('`')}`" for k, e in entries.items()
                   if k != "name" and e["value"] != _default(cls, k)]
        presets.append(f"* `optimizer={path.stem}`: {header_comment(path) or ''}"
                       f"{' Sets ' + ', '.join(changed) + '.' if changed else ''}")
    if presets:
        lines += ["", "Presets (`penaltyrun/conf/optimizer/`):", "", *presets]
    return lines + [""]


def _default(cls: type, key: str) -> Any:
    for field in dataclasses.fields(cls):
        if field.name == key and field.default is not dataclasses.MISSING:
            value = field.default
            return list(value) if isinstance(value, tuple) else value
    return object()


def top_level_section() -> list[str]:
    """Keys of ``conf/config.yaml`` with the runner's and report's checks."""
    from penaltyrun.runner.options import REPORT_OPTIONS, RUNNER_OPTIONS
    lines = ["| key | type | default | range | meaning |", "|---|---|---|---|---|"]
    entries = yaml_entries(CONF / "config.yaml")
    nested = {e["key"].rsplit(".", 1)[0] for e in entries if "." in e["key"]}
    for entry in entries:
        key, value = entry["key"], entry["value"]
        if key.startswith(("hydra", "defaults")) or isinstance(value, dict) and key in nested:
            continue
        group, _, leaf = key.partition(".")
        kind, allowed = "", ""
        if isinstance(value, dict):  # an inline mapping of pre-declared names
            kind, value = "mapping", ", ".join(value)
        if group == "runner" and leaf in RUNNER_OPTIONS:
            kind, allowed = RUNNER_OPTIONS[leaf]
            kind = _KINDS.get(kind, kind)
        elif group == "report" and leaf in REPORT_OPTIONS:
            kind = " or ".join("null" if t is type(None) else t.__name__
                               for t in REPORT_OPTIONS[leaf])
        elif kind != "mapping":
            kind = type(value).__name__ if value is not None else "any"
        lines.append(f"| `{key}` | {cell(kind)} | {cell(value)} | {_text(allowed)} | "
                     f"{_text(entry['comment'])} |")
    listed = {e["key"] for e in yaml_entries(CONF / "config.yaml")}
    for leaf, (kind, allowed) in RUNNER_OPTIONS.items():
        if f"runner.{leaf}" not in listed:
            lines.append(f"| `runner.{leaf}` | {cell(_KINDS.get(kind, kind))} | | "
                         f"{_text(allowed)} | |")
    return lines


def groups_section() -> list[str]:
    """The config groups and their choices (one YAML file each)."""
    lines = ["| group | choices (`penaltyrun/conf/<group>/<choice>.yaml`) |", "|---|---|"]
    for group in sorted(p for p in CONF.iterdir() if p.is_dir() and not p.name.startswith("_")):
        choices = ", ".join(f"`{p.stem}`" for p in sorted(group.glob("*.yaml")))
        if choices:
            lines.append(f"| `{group.name}` | {choices} |")
    return lines


def param_section() -> list[str]:
    """Keys of the parameterization configs."""
    lines = ["| choice | key | default | meaning |", "|---|---|---|---|"]
    for path in sorted((CONF / "param").glob("*.yaml")):
        for entry in yaml_entries(path):
            if entry["key"] != "name":
                lines.append(f"| `param={path.stem}` | `param.{entry['key']}` | "
                             f"{cell(entry['value'])} | {_text(entry['comment'])} |")
    return lines


def problem_section(name: str, module_path: str) -> list[str]:
    """One problem's cases and ``Params`` fields beside the YAML's defaults."""
    module = importlib.import_module(module_path)
    params_cls = getattr(module, "Params", None)
    lines = [f"### `problem={name}`", "",
             rst_to_md((inspect.getdoc(module) or "").split("\n\n")[0]), "",
             "Cases: " + ", ".join(f"`{c}`" for c in module.CASES)
             + f" (default `{module.DEFAULT_CASE}`).", ""]
    yaml_path = CONF / "problem" / f"{name}.yaml"
    shipped = {e["key"].removeprefix("params."): e for e in yaml_entries(yaml_path)
               if e["key"].startswith("params.")} if yaml_path.exists() else {}
    if params_cls is None or not dataclasses.is_dataclass(params_cls):
        return lines + ["This problem's module has no `Params` dataclass.", ""]
    hints = typing.get_type_hints(params_cls)
    docs = attribute_docs(params_cls)
    lines += ["| key | type | default | shipped YAML | meaning |", "|---|---|---|---|---|"]
    for field in dataclasses.fields(params_cls):
        default = getattr(params_cls(), field.name)
        entry = shipped.get(field.name)
        yaml_value = cell(entry["value"]) if entry else "—"
        meaning = docs.get(field.name) or (entry["comment"] if entry else "")
        lines.append(f"| `problem.params.{field.name}` | {cell(type_name(hints[field.name]))} "
                     f"| {cell(default)} | {yaml_value} | {_text(meaning)} |")
    return lines + ["", "A `null` in the shipped YAML means: the case's value, else the "
                    "dataclass default. Set a key with `problem.params.<key>=<value>`.", ""]


def experiment_section() -> list[str]:
    """Every sweep profile with its header comment and swept values."""
    lines = []
    for path in sorted((CONF / "experiment").glob("*.yaml")):
        entries = {e["key"]: e["value"] for e in yaml_entries(path)}
        swept = [f"`{k.removeprefix('hydra.sweeper.params.')}={v}`" for k, v in entries.items()
                 if k.startswith("hydra.sweeper.params.")]
        lines += [f"* **`+experiment={path.stem}`**: {_text(header_comment(path))}"
                  + (f" Sweeps {', '.join(swept)}." if swept else "")]
    return lines


def page_config() -> str:
    """The configuration reference."""
    from penaltyrun.optim import OPTIMIZERS
    from penaltyrun.problems import REGISTRY
    lines = ["# Configuration reference", "",
             "Generated from the code when the documentation is built: the YAML files under "
             "`penaltyrun/conf`, the optimizers' settings dataclasses, the runner's and the "
             "report's option checks and each problem's `Params` dataclass. *Range* is what "
             "the command line's checks accept (read from the checks themselves). Print the "
             "composed config of a command with `penaltyrun --cfg job <overrides>`.", "",
             "## Top level (`conf/config.yaml`)", "", *top_level_section(), "",
             "## Config groups", "", *groups_section(), "",
             "## Optimizers (`optimizer.*`)", "",
             "Keys shared by every search optimizer come first in each table.", ""]
    for name, entry in OPTIMIZERS.items():
        cls = entry.settings
        lines += optimizer_section(name, cls)
    lines += ["## Parameterizations (`param.*`)", "", *param_section(), "",
              "## Problems (`problem.params.*`)", ""]
    for name, module_path in REGISTRY.items():
        lines += problem_section(name, module_path)
    lines += ["## Experiment profiles (`+experiment=…`)", "", *experiment_section(), ""]
    return "\n".join(lines)


def page_exit_codes() -> str:
    """Exit codes, read from :data:`penaltyrun.errors.EXIT_CODES` (the command line's
    ``penaltyrun.cli.EXIT_CODES``)."""
    from penaltyrun import errors
    names = {v: k for k, v in vars(errors).items()
             if k.startswith("EXIT_") and isinstance(v, int)}
    lines = ["# Exit codes", "", "Generated from `penaltyrun.cli.EXIT_CODES`. `penaltyrun` "
             "and `penaltyrun-report` end with one of these codes.", "",
             "| code | name | meaning |", "|---|---|---|"]
    for code, meaning in sorted(errors.EXIT_CODES.items()):
        lines.append(f"| {int(code)} | {cell(names.get(code, ''))} | {_text(meaning)} |")
    return "\n".join(lines) + "\n"


def page_schema() -> str:
    """The Parquet schema, read from :mod:`penaltyrun.io.schema`."""
    from penaltyrun.io import schema
    json_columns = set(getattr(schema, "JSON_COLUMNS", ()))
    lines = ["# Results schema (Parquet)", "",
             f"Generated from `penaltyrun.io.schema` (schema version "
             f"{schema.SCHEMA_VERSION}). Every run directory ends with "
             f"`{schema.RESULTS_FILE}`, one row per job; `penaltyrun.io.read_results(path)` "
             "reads one file or every file under a folder as a pandas DataFrame. Columns "
             "marked JSON hold JSON text.", "",
             rst_to_md(inspect.getdoc(schema) or ""), "",
             "| column | Arrow type | meaning |", "|---|---|---|"]
    for name, (arrow_type, meaning) in schema.COLUMNS.items():
        kind = f"{arrow_type} (JSON)" if name in json_columns else str(arrow_type)
        lines.append(f"| `{name}` | {cell(kind)} | {_text(meaning)} |")
    return "\n".join(lines) + "\n"


def page_protocol() -> str:
    """The problem protocol, read from :mod:`penaltyrun.problems.base`."""
    from penaltyrun import problems
    from penaltyrun.problems import base, hooks, report_hooks
    lines = ["# Problem protocol", "",
             "Generated from `penaltyrun/problems/base.py` and the registry's checks. A "
             "module that lacks a required member is refused with one line naming it.", "",
             "Required module members: " + ", ".join(f"`{m}`" for m in problems.MODULE_MEMBERS)
             + ". Required members of the object `make_problem` returns: "
             + ", ".join(f"`{m}`" for m in problems.PROBLEM_MEMBERS) + ".", "",
             "## The module", "", rst_to_md(inspect.getdoc(base) or ""), "",
             "## Optional hooks of the problem object", "",
             rst_to_md(inspect.getdoc(hooks) or ""), "",
             numpydoc_to_md(inspect.getdoc(hooks.ProblemHooks) or ""), "",
             "## Report hooks (optional)", "",
             rst_to_md(inspect.getdoc(report_hooks) or ""), ""]
    for obj in (base.Problem, base.MatrixSpec, base.ScalarSpec, base.BatchEvaluation,
                base.ClosedLoop, base.ParamsMixin, base.ReportInfo, base.PaperValues,
                base.ReportSection):
        lines += [f"## `{obj.__name__}`", "", numpydoc_to_md(inspect.getdoc(obj) or ""), ""]
        for name, member in vars(obj).items():
            if callable(member) and not name.startswith("_") or isinstance(member, classmethod):
                func = member.__func__ if isinstance(member, classmethod) else member
                try:
                    signature = str(inspect.signature(func))
                except (TypeError, ValueError):
                    signature = "(...)"
                lines += [f"### `{name}{signature}`", "",
                          numpydoc_to_md(inspect.getdoc(func) or ""), ""]
    for name in sorted(base.__all__):
        member = getattr(base, name)
        if inspect.isfunction(member):
            lines += [f"## `{name}{inspect.signature(member)}`", "",
                      numpydoc_to_md(inspect.getdoc(member) or ""), ""]
    return "\n".join(lines)


#: Where each built-in problem is explained or taught (relative to ``docs/reference``).
PROBLEM_PAGES = {"zermelo": ("Zermelo navigation", "../explanation/zermelo.md"),
                 "attitude_lyapunov": ("Spacecraft attitude", "../explanation/attitude.md"),
                 "attitude_lqr": ("Spacecraft attitude", "../explanation/attitude.md"),
                 "lyapunov_transfer": ("Low-thrust transfers", "../explanation/lowthrust.md"),
                 "qlaw": ("Low-thrust transfers", "../explanation/lowthrust.md"),
                 "mpc_rendezvous": ("Model predictive control", "../explanation/mpc.md"),
                 "lqr": ("Tune your own controller", "../tutorials/tune-your-lqr.md")}


def page_problems() -> str:
    """The built-in problems, read from the registry and each module's report hooks."""
    from penaltyrun import problems
    from penaltyrun.problems import report_hooks
    lines = ["# Problems", "",
             "Generated from the problem registry (`penaltyrun.problems.REGISTRY`): every "
             "built-in `problem=` choice, its cases (`case=`, the default first), the cost the "
             "report states and where the problem is explained. Your own problem joins with "
             "`problem=my_pkg.my_module` ([add your own problem](../how-to/add-a-problem.md)); "
             "its parameters are under `problem.params.*` in the "
             "[configuration keys](config.md).", "",
             "| `problem=` | what it is | cases | cost (unit) | page |", "|---|---|---|---|---|"]
    for name, module_path in problems.REGISTRY.items():
        mod = problems.module(name)
        summary = (inspect.getdoc(mod) or "").split("\n\n", 1)[0].replace("\n", " ")
        cases = [mod.DEFAULT_CASE, *[c for c in mod.CASES if c != mod.DEFAULT_CASE]]
        cost = report_hooks.info(mod, mod.DEFAULT_CASE, {}).cost_label
        page = PROBLEM_PAGES.get(name)
        lines.append(f"| `{name}` | {_text(rst_to_md(summary))} | "
                     f"{', '.join(f'`{c}`' for c in cases)} | {_text(cost)} | "
                     + (f"[{page[0]}]({page[1]})" if page else f"`{module_path}`") + " |")
    return "\n".join(lines) + "\n"


def pages() -> dict[str, str]:
    """Generated page path (relative to ``docs/``) → Markdown text."""
    return {"reference/config.md": page_config(),
            "reference/exit-codes.md": page_exit_codes(),
            "reference/schema.md": page_schema(),
            "reference/problem-protocol.md": page_protocol(),
            "reference/problems.md": page_problems()}
