"""Where the command line's configs come from: penaltyrun's own ``conf/`` plus the user's
directories (``--config-dir``, ``--config-path``, ``hydra.searchpath``).

Used by the preflight of :mod:`penaltyrun.cli` so that the allowed values it lists are the
ones Hydra will find, and so that a malformed user file is one line naming file and line.

``--config-path`` is resolved against the current directory (Hydra itself would resolve a
relative path against the installed package, which no user means); :func:`normalize_argv`
rewrites it to an absolute path before Hydra parses the command line.
"""

from __future__ import annotations

import atexit
import importlib.util
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from penaltyrun import yamlsafe
from penaltyrun.cli.reachable import follow_defaults
from penaltyrun.errors import ConfigError

CONF_DIR = Path(__file__).resolve().parent.parent / "conf"
#: A dotted module path (``my_pkg.my_module``) given as ``problem=``.
_MODULE_PATH = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)+$")
#: Hydra's options that take a value: long form, short form.
SOURCE_OPTIONS = {"--config-path": "-cp", "--config-name": "-cn", "--config-dir": "-cd"}


@dataclass(frozen=True)
class ConfigSource:
    """The config sources named on one command line.

    Attributes
    ----------
    primary : Path
        Directory of the primary config (``--config-path``, default penaltyrun's ``conf/``).
    config_name : str
        Primary config name without ``.yaml`` (``--config-name``, default ``config``).
    config_dirs : tuple of Path
        Extra directories from ``--config-dir`` (searched before the package's).
    """

    primary: Path
    config_name: str = "config"
    config_dirs: tuple[Path, ...] = ()


def _option_values(argv: list[str]) -> tuple[dict[str, str], list[str]]:
    """Split ``argv`` into Hydra's config-source options and the rest."""
    short = {v: k for k, v in SOURCE_OPTIONS.items()}
    found: dict[str, str] = {}
    rest: list[str] = []
    i = 0
    while i < len(argv):
        arg = argv[i]
        name, eq, value = arg.partition("=")
        name = short.get(name, name)
        if name in SOURCE_OPTIONS:
            if not eq:
                if i + 1 >= len(argv):
                    raise ConfigError(name, "expects a value")
                value = argv[i + 1]
                i += 1
            found[name] = value
        else:
            rest.append(arg)
        i += 1
    return found, rest


#: Overrides of problem parameters, given as ``problem.params.X=v`` or ``+problem.params...``.
PARAMS_PREFIX = "problem.params."


def normalize_argv(argv: list[str]) -> list[str]:
    """``argv`` with a relative ``--config-path`` made absolute (relative to the cwd), and
    problem parameters overridden with ``++``.

    ``problem.params.X=v`` becomes ``++problem.params.X=v`` (set or add): a problem's
    parameters are the fields of its ``Params`` dataclass, listed in its YAML file or not;
    the preflight refuses names that are not fields
    (:func:`penaltyrun.cli.spec.with_params_schema`).

    ``problem=my_pkg.my_module`` names a problem module by its path
    (:func:`module_problems`).
    """
    out = [f"++{arg.lstrip('+')}" if arg.lstrip("+").startswith(PARAMS_PREFIX) and "=" in arg
           else arg for arg in module_problems(argv)]
    short = {v: k for k, v in SOURCE_OPTIONS.items()}
    for i, arg in enumerate(out):
        name, eq, value = arg.partition("=")
        if short.get(name, name) != "--config-path":
            continue
        if eq and not value.startswith("pkg://"):
            out[i] = f"{name}={os.path.abspath(value)}"
        elif not eq and i + 1 < len(out) and not out[i + 1].startswith("pkg://"):
            out[i + 1] = os.path.abspath(out[i + 1])
    return out


def module_problems(argv: list[str]) -> list[str]:
    """``problem=my_pkg.my_module`` (alone or in a sweep list): a problem module named by
    its dotted path, without a config file of its own.

    For each such path a problem config ``{name: my_module, module: my_pkg.my_module,
    params: {}}`` is written into a temporary folder (removed when the process ends), which
    joins Hydra's search path (``hydra.searchpath``, after the user's own entries). The
    problem's name is the path's last part, as for ``penaltyrun.tune("my_pkg.my_module")``,
    so both give the same config hash and jobs; it may not be a built-in problem's name.

    Raises
    ------
    ConfigError
        A path whose last part is the name of a built-in problem.
    """
    paths = []
    for arg in argv:
        key, eq, value = arg.partition("=")
        if key == "problem" and eq:
            paths += [v.strip() for v in value.split(",") if _MODULE_PATH.match(v.strip())]
    if not paths:
        return list(argv)
    from penaltyrun.problems import builtin_name_refused

    for path in paths:
        builtin_name_refused(path.rsplit(".", 1)[1], "problem", "a module's problem name is "
                             "the last part of its path; rename the module")
    folder = Path(tempfile.mkdtemp(prefix="penaltyrun-problems-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / "problem").mkdir()
    for path in dict.fromkeys(paths):
        (folder / "problem" / f"{path}.yaml").write_text(
            f"name: {path.rsplit('.', 1)[1]}\nmodule: {path}\nparams: {{}}\n",
            encoding="utf-8")
    entry = f"file://{folder}"
    out = []
    for arg in argv:
        key, eq, value = arg.partition("=")
        if key == "hydra.searchpath" and value.startswith("[") and value.endswith("]"):
            inner = value[1:-1].strip()
            arg = f"{key}=[{inner + ',' if inner else ''}{entry}]"
            entry = ""
        out.append(arg)
    return out + ([f"hydra.searchpath=[{entry}]"] if entry else [])


def parse_source(argv: list[str]) -> tuple[ConfigSource, list[str]]:
    """The config sources of a command line, and the remaining arguments.

    Raises
    ------
    ConfigError
        If a named directory does not exist or lacks the primary config.
    """
    found, rest = _option_values(argv)
    primary = CONF_DIR
    name = found.get("--config-name", "config").removesuffix(".yaml")
    if "--config-path" in found:
        given = found["--config-path"]
        local = _searchpath_dir(given) if given.startswith("pkg://") else Path(given)
        primary = (local or Path(given)).expanduser().resolve()
        if not primary.is_dir():
            raise ConfigError("--config-path", f"{primary} is not a directory")
    dirs: tuple[Path, ...] = ()
    if "--config-dir" in found:
        extra = Path(found["--config-dir"]).expanduser().resolve()
        if not extra.is_dir():
            raise ConfigError("--config-dir", f"{extra} is not a directory")
        dirs = (extra,)
        _check_shadowed(primary, extra)
    if "--config-name" in found:  # a group's file named as the primary config
        for folder in (primary, *dirs):
            if (folder / f"{name}.yaml").is_file():
                _check_primary(folder / f"{name}.yaml")
    if not (primary / f"{name}.yaml").is_file():
        raise ConfigError("--config-name" if "--config-name" in found else "--config-path",
                          f"no primary config {name}.yaml in {primary}")
    return ConfigSource(primary, name, dirs), rest


def _check_shadowed(primary: Path, extra: Path) -> None:
    """Refuse a ``--config-dir`` file named like a config of the primary config's folder.

    Hydra searches the primary folder (penaltyrun's ``conf/`` unless ``--config-path``)
    before a ``--config-dir``, so such a file would be ignored without a word.

    Raises
    ------
    ConfigError
        Naming the file and a new name for it.
    """
    for path in sorted(extra.glob("*/*.yaml")):
        group, name = path.parent.name, path.stem
        if (primary / group / path.name).is_file():
            owner = "penaltyrun's own" if primary == CONF_DIR else f"the one in {_shown(primary)}"
            raise ConfigError("--config-dir", f"{_shown(path)} has the name of {owner} "
                              f"{group}={name}, which Hydra finds first, so yours would be "
                              f"ignored: rename it (e.g. {name}_mine.yaml) and pass "
                              f"{group}={name}_mine")


def _check_primary(path: Path) -> None:
    """Refuse a ``--config-name`` file that is a group's config (``name: lqr`` and its
    settings, no ``defaults`` list), e.g. a problem file given as the primary config.

    Raises
    ------
    ConfigError
        Naming the group folder the file belongs in and the command line that uses it.
    """
    import yaml

    try:
        data = yamlsafe.load_file(path)
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return  # check_yaml names the problem
    if not isinstance(data, dict) or "defaults" in data or "name" not in data:
        return
    group = "problem"
    for candidate in ("problem", "param", "optimizer"):
        names = [f.stem for f in (CONF_DIR / candidate).glob("*.yaml")]
        if str(data["name"]) in names:
            group = candidate
            break
    raise ConfigError("--config-name", f"{_shown(path)} is a {group} config (name: "
                      f"{data['name']}), not a primary config: move it to "
                      f"{_shown(path.parent / group / path.name)} and pass --config-dir "
                      f"{_shown(path.parent)} {group}={path.stem}")


@contextmanager
def hydra_context(source: ConfigSource) -> Iterator[None]:
    """Initialize Hydra's global state with the search path Hydra's app will use."""
    from hydra.core.global_hydra import GlobalHydra

    from penaltyrun.cli.hydra_private import init_global_hydra

    init_global_hydra("penaltyrun", source.primary, source.config_dirs)
    try:
        yield
    finally:
        GlobalHydra.instance().clear()


def give_config_loader(overrides: list[Any]) -> list[Any]:
    """``overrides`` (parsed), each given the config loader of Hydra's global state, which
    a glob sweep (``param=glob(*)``) needs to list its group's options, as Hydra's own
    sweeper gives it. Must be called inside :func:`hydra_context`."""
    from hydra.core.global_hydra import GlobalHydra

    loader = GlobalHydra.instance().config_loader()
    for override in overrides:
        override.config_loader = loader
    return overrides


def group_options(group: str, source: ConfigSource, hydra_overrides: list[str]) -> list[str]:
    """Config names Hydra finds in ``group`` (package, ``--config-dir``, searchpath).

    Must be called inside :func:`hydra_context`.
    """
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.object_type import ObjectType

    loader = GlobalHydra.instance().config_loader()
    return sorted(loader.get_group_options(group, results_filter=ObjectType.CONFIG,
                                           config_name=source.config_name,
                                           overrides=hydra_overrides))


def _searchpath_dir(entry: str) -> Path | None:
    """Local directory of one ``hydra.searchpath`` entry (``file://``, ``pkg://``, plain)."""
    if entry.startswith("pkg://"):
        module = entry[len("pkg://"):].replace("/", ".").strip(".")
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            return None
        locations = list(spec.submodule_search_locations or []) if spec else []
        return Path(locations[0]) if locations else None
    return Path(entry.removeprefix("file://")).expanduser()


def search_dirs(source: ConfigSource, searchpath: list[str]) -> list[Path]:
    """Local directories searched for configs, in Hydra's order (user's first)."""
    dirs = [*source.config_dirs, source.primary]
    dirs += [d for d in map(_searchpath_dir, searchpath) if d is not None]
    return dirs


def _shown(path: Path) -> str:
    """``path`` relative to the current directory when it is below it."""
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve())) or "."
    except ValueError:
        return str(path)


def misplaced(group: str, value: str, source: ConfigSource, searchpath: list[str]
              ) -> str | None:
    """Where a config file that ``group=value`` did not find really is, and the fix; None
    when no such file is near.

    Hydra finds ``<dir>/<group>/<value>.yaml`` only, ``<dir>`` a config directory
    (``--config-dir``, ``hydra.searchpath``). Looked at: a path given as the choice
    (``problem=myconf/plant.yaml``), ``<value>.yaml`` at the top of a config directory or in
    another group's folder, and ``<value>.yaml`` in the current directory or one folder
    below it, directly or in a ``<group>/`` folder, when the current directory is not
    searched.
    """
    name = Path(value).name.removesuffix(".yaml").removesuffix(".yml")
    if "/" in value or os.sep in value or value.endswith((".yaml", ".yml")):
        given = Path(value).expanduser()
        found = given if given.is_file() or not given.name else \
            given.with_name(f"{name}.yaml")
        if not found.is_file():
            return (f"a choice is the name of a file in a config directory's {group}/ "
                    f"folder, not a path: {group}={name} with --config-dir DIR")
        folder = found.parent
        if folder.name == group:
            return f"a choice is a name, not a path: pass --config-dir " \
                   f"{_shown(folder.parent)} {group}={name}"
        return (f"{_shown(found)} must be in a {group}/ folder: move it to "
                f"{_shown(folder / group / (name + '.yaml'))} and pass --config-dir "
                f"{_shown(folder)} {group}={name}")
    dirs = [d for d in search_dirs(source, searchpath) if d.resolve() != CONF_DIR]
    for folder in dirs:
        for found in [folder / f"{name}.yaml",
                      *sorted(folder.glob(f"*/{name}.yaml"))]:
            if found.is_file():
                return (f"{_shown(found)} is outside the {group}/ folder Hydra searches: "
                        f"move it to {_shown(folder / group / (name + '.yaml'))}")
    here = Path.cwd()
    if any(d.resolve() == here.resolve() for d in dirs):
        return None
    for found in [here / group / f"{name}.yaml", *sorted(here.glob(f"*/{group}/{name}.yaml"))]:
        if found.is_file():
            return f"{_shown(found)} is not searched: pass --config-dir " \
                   f"{_shown(found.parent.parent)}"
    for found in [here / f"{name}.yaml", *sorted(here.glob(f"*/{name}.yaml"))]:
        if found.is_file():
            conf = found.parent if found.parent != here else here / "conf"
            return (f"{_shown(found)} is not searched: move it to "
                    f"{_shown(conf / group / (name + '.yaml'))} and pass --config-dir "
                    f"{_shown(conf)} {group}={name}")
    return None


def check_yaml(path: Path, key: str) -> None:
    """Parse one config file as Hydra will, within the limits of :mod:`penaltyrun.yamlsafe`
    (size, nesting, aliases); a syntax error is one :class:`ConfigError` naming file and line.

    Raises
    ------
    ConfigError
        ``<key>: <file>:<line>: malformed YAML: <problem>``, ``<key>: <file>: <limit>``
        for a file beyond a limit, or if the top level is not a mapping.
    """
    import yaml
    from omegaconf._utils import get_yaml_loader

    try:
        data = yamlsafe.load_file(path, loader=get_yaml_loader())
    except yamlsafe.YamlLimitError as exc:
        raise ConfigError(key, str(exc)) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        line = f":{mark.line + 1}" if mark is not None else ""
        what = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise ConfigError(key, f"{path}{line}: malformed YAML: {what}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(key, f"{path}: cannot read ({exc})") from None
    if data is not None and not isinstance(data, dict):
        raise ConfigError(key, f"{path}:1: the top level must be a mapping of keys, "
                               f"got {type(data).__name__}")


def check_files(source: ConfigSource, searchpath: list[str],
                choices: list[tuple[str, str]]) -> None:
    """YAML-check the primary config and every chosen group file found in a user directory;
    every YAML file of the user's directories against the limits (:func:`check_limits`).

    Parameters
    ----------
    source : ConfigSource
    searchpath : list of str
        ``hydra.searchpath`` entries given on the command line.
    choices : list of (group, name)
        Config-group choices of the command line, e.g. ``("experiment", "mine")``.
    """
    check_limits(source, searchpath, choices)
    check_yaml(source.primary / f"{source.config_name}.yaml", "--config-name")
    for group, name in choices:
        for folder in search_dirs(source, searchpath):
            path = folder / group / f"{name}.yaml"
            if path.is_file():
                check_yaml(path, group)


#: How deep below a user's config directory its YAML files are checked (``<dir>/a/b/c.yaml``).
SCAN_DEPTH = 3


def _user_yaml_files(folder: Path) -> Iterator[Path]:
    """YAML files at most :data:`SCAN_DEPTH` levels below ``folder``, hidden folders
    (``.hydra``, ``.git``) left out, in a stable order."""
    stack = [(folder, 0)]
    while stack:
        here, level = stack.pop()
        try:
            entries = sorted(here.iterdir())
        except OSError:
            continue
        for entry in entries:
            if entry.name.startswith("."):
                continue
            if entry.suffix in (".yaml", ".yml") and entry.is_file():
                yield entry
            elif level + 1 < SCAN_DEPTH and entry.is_dir() and not entry.is_symlink():
                stack.append((entry, level + 1))


def check_limits(source: ConfigSource, searchpath: list[str],
                 choices: Iterable[tuple[str, str]] = ()) -> None:
    """Every YAML file of the user's config directories within the limits of
    :mod:`penaltyrun.yamlsafe` (size, nesting, aliases), before Hydra reads any of them:
    Hydra follows defaults lists (an experiment's ``- /problem: mine``) to files the
    command line does not name, and reads them without bounds: the files the defaults lists
    reach are checked too, hidden, deeper or behind a linked folder
    (:func:`penaltyrun.cli.reachable.follow_defaults`). A file's syntax is left to
    :func:`check_yaml` and Hydra, which name it only when it is used.

    Raises
    ------
    ConfigError
        ``<group>: <file>: <limit>`` for the first file beyond a limit.
    """
    import yaml
    from omegaconf._utils import get_yaml_loader

    user = [f for f in search_dirs(source, searchpath)
            if f.is_dir() and f.resolve() != CONF_DIR]

    def load(path: Path, folder: Path) -> Any:
        try:
            return yamlsafe.load_file(path, loader=get_yaml_loader())
        except yamlsafe.YamlLimitError as exc:
            parts = path.relative_to(folder).parts if folder in path.parents else ()
            option = "--config-dir" if folder in source.config_dirs else \
                "--config-path" if folder == source.primary else "hydra.searchpath"
            raise ConfigError(parts[0] if len(parts) > 1 else option,
                              f"{exc}; every YAML file in {_shown(folder)} is checked "
                              f"before Hydra reads any") from None
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            return None

    start = [(path, folder) for folder in user for path in _user_yaml_files(folder)]
    primary = source.primary / f"{source.config_name}.yaml"
    start += [(primary, source.primary)] if primary.is_file() else []
    start += [(folder / group / f"{name}.yaml", folder) for group, name in choices
              for folder in user if (folder / group / f"{name}.yaml").is_file()]
    follow_defaults(list(dict.fromkeys(start)), user, load)
