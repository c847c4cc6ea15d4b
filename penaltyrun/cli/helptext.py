"""``penaltyrun --help``: penaltyrun's own help, generated from the config files.

The groups and their choices are the YAML files Hydra will search (penaltyrun's ``conf/`` and
the user's ``--config-dir`` / ``--config-path``), the defaults come from the primary config's
defaults list, and each problem's cases from its module's ``CASES``, read from the module's
source without importing it (importing a problem module loads numba; the help answers in a
fraction of a second). Hydra's own help stays available as ``--hydra-help``.
"""

from __future__ import annotations

import ast
import importlib.util
import textwrap
from pathlib import Path

from penaltyrun.cli import modes, userconf
from penaltyrun.errors import ConfigError

GROUPS = ("problem", "param", "optimizer", "experiment")
WIDTH = 92
INDENT = 13

EXAMPLES = (
    ("penaltyrun problem=attitude_lqr case=rest_to_rest param=diagonal",
     "one cell, 10 starts"),
    ("penaltyrun -m problem=zermelo param=diagonal,full optimizer=pso,de", "a 2 x 2 sweep"),
    ("penaltyrun -m mode=plan +experiment=zermelo_paper", "forecast a study first"),
    ("penaltyrun mode=evaluate 'matrices.K=[[1.74,0.96],[0.96,1.14]]'", "one candidate"),
    ("penaltyrun mode=report report.input=outputs/multirun", "report over many runs"),
)
OPTIONS = (
    ("-m, --multirun", "run every combination of the comma lists (sweeps)"),
    ("--config-dir DIR", "add your own groups (problems, experiments) from DIR/<group>/"),
    ("--keep", "mode=evaluate: keep Hydra's run directory (.hydra/ config and log)"),
    ("--cfg job", "print the composed config;  --version;  --hydra-help: Hydra's own help"),
)


def wants_help(argv: list[str]) -> bool:
    """Whether the command line asks for penaltyrun's help (``--help`` or ``-h``)."""
    return any(arg in ("--help", "-h") for arg in argv)


def _read_yaml(path: Path) -> dict:
    import yaml

    from penaltyrun import yamlsafe

    try:
        data = yamlsafe.load_file(path)
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return {}
    return data if isinstance(data, dict) else {}


def _defaults(primary: Path) -> dict[str, str]:
    """Group → default choice from the primary config's defaults list."""
    chosen = {}
    for entry in _read_yaml(primary).get("defaults") or []:
        if isinstance(entry, dict):
            chosen.update({str(k): str(v) for k, v in entry.items()})
    return chosen


def _choices(dirs: list[Path], group: str) -> dict[str, Path]:
    """Choice name → file of ``group`` in the searched directories (first one wins)."""
    found: dict[str, Path] = {}
    for folder in dirs:
        for path in sorted((folder / group).glob("*.yaml")):
            found.setdefault(path.stem, path)
    return found


def _module_file(module: str) -> Path | None:
    """Source file of a dotted module name, found without importing any of its packages."""
    top, *rest = module.split(".")
    try:
        spec = importlib.util.find_spec(top)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    if not rest:
        return Path(spec.origin) if spec.origin and spec.origin.endswith(".py") else None
    folders = [Path(p) for p in (spec.submodule_search_locations or [])]
    for part in rest[:-1]:
        folders = [f / part for f in folders if (f / part).is_dir()]
    for folder in folders:
        for path in (folder / f"{rest[-1]}.py", folder / rest[-1] / "__init__.py"):
            if path.is_file():
                return path
    return None


def _literal_cases(module: str, depth: int = 3) -> tuple[str, ...] | None:
    """``CASES`` of a module from its source: a literal tuple or list of strings, followed
    through ``from X import CASES``; None if it is computed."""
    path = _module_file(module)
    if path is None or depth == 0:
        return None
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, SyntaxError):
        return None
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "CASES"
                                                for t in node.targets):
            try:
                value = ast.literal_eval(node.value)
            except ValueError:
                return None
            return tuple(map(str, value)) if isinstance(value, (tuple, list)) else None
        if isinstance(node, ast.ImportFrom) and any(a.name == "CASES" and a.asname is None
                                                    for a in node.names):
            base = package.split(".")
            if node.level:
                base = base[:len(base) - node.level + 1]
            source = ".".join([*base, node.module] if node.level else [node.module or ""])
            return _literal_cases(source.strip("."), depth - 1)
    return None


def _registry() -> dict[str, str]:
    """penaltyrun's problem registry (``penaltyrun.problems.REGISTRY``), read from the
    package's source so that numpy is not imported for the help."""
    path = Path(__file__).resolve().parent.parent / "problems" / "__init__.py"
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, SyntaxError):
        tree = ast.Module(body=[], type_ignores=[])
    for node in tree.body:
        target = node.target if isinstance(node, ast.AnnAssign) else \
            node.targets[0] if isinstance(node, ast.Assign) else None
        if isinstance(target, ast.Name) and target.id == "REGISTRY" and node.value:
            try:
                return {str(k): str(v) for k, v in ast.literal_eval(node.value).items()}
            except (ValueError, AttributeError):
                break
    from penaltyrun.problems import REGISTRY  # computed: import it

    return dict(REGISTRY)


def _problem_cases(path: Path, registry: dict[str, str]) -> tuple[str, tuple[str, ...] | None]:
    """Problem name and cases of one problem config file."""
    data = _read_yaml(path)
    name = str(data.get("name") or path.stem)
    module = data.get("module") or registry.get(name) or _entry_point(name)
    return name, _literal_cases(str(module)) if module else None


def _entry_point(name: str) -> str | None:
    """Module of a problem registered by an installed package (entry points)."""
    import importlib.metadata

    for ep in importlib.metadata.entry_points(group="penaltyrun.problems"):
        if ep.name == name:
            return ep.value.split(":")[0]
    return None


def _wrapped(label: str, text: str, indent: int = INDENT) -> list[str]:
    return textwrap.wrap(text, WIDTH, initial_indent=f"  {label:<{indent - 3}} ",
                         subsequent_indent=" " * indent, break_on_hyphens=False)


def render(argv: list[str]) -> str:
    """The help text (≤ 60 lines) for the config sources named on ``argv``."""
    try:
        source, _ = userconf.parse_source(argv)
    except ConfigError:
        source = userconf.ConfigSource(userconf.CONF_DIR)
    dirs = list(dict.fromkeys([*source.config_dirs, source.primary, userconf.CONF_DIR]))
    defaults = _defaults(source.primary / f"{source.config_name}.yaml")
    lines = [
        "usage: penaltyrun [KEY=VALUE ...] [GROUP=CHOICE ...] [-m] [--config-dir DIR] [--keep]",
        "",
        "Tune the penalty matrices of a feedback controller, diagonal or full K = Q Λ Qᵀ. A",
        "command line is one cell (problem, case, param, optimizer) run runner.n_starts times;",
        "with -m, comma lists (param=diagonal,full) sweep several cells.",
        "",
        "modes (mode=...; default optimize):",
        *[f"  {mode.name:<10} {mode.help}" for mode in modes.TABLE],
        "",
        "groups (GROUP=CHOICE; * default; +experiment=NAME for a study profile, with -m):",
    ]
    for group in GROUPS:
        names = sorted(_choices(dirs, group))
        if group in defaults and defaults[group] in names:
            names.remove(defaults[group])
            names.insert(0, defaults[group] + "*")
        lines += _wrapped(group, ", ".join(names) or "(none)")
    lines += ["", "cases (case=NAME; * default, case=null → the default):"]
    registry = _registry()
    problems = [_problem_cases(path, registry) for path in _choices(dirs, "problem").values()]
    indent = 3 + max((len(name) for name, _ in problems), default=0) + 1
    for name, cases in problems:
        text = ", ".join([cases[0] + "*", *cases[1:]]) if cases else "see its module's CASES"
        lines += _wrapped(name, text, indent)
    lines += ["", "examples:"]
    lines += [f"  {cmd:<70} # {what}" for cmd, what in EXAMPLES]
    lines += ["", "options:"]
    lines += [f"  {flag:<18} {text}" for flag, text in OPTIONS]
    lines += [
        "",
        "outputs: a run writes outputs/<date>/<time>_<problem>_<param>/ (results.parquet,",
        "  jobs/, report/, .hydra/); a sweep outputs/multirun/<date>/<time>/<n>_<problem>_"
        "<param>/.",
        "  Choose with hydra.run.dir=DIR (hydra.sweep.dir=DIR with -m); resume a run with the",
        "  same command plus runner.resume=true. mode=evaluate writes nothing unless --keep",
        "  or hydra.run.dir is given. A mistake is one line on stderr and exit code 2.",
        "",
        "Every config key, problem parameter and exit code: the documentation (docs/, make docs).",
    ]
    return "\n".join(lines)
