"""Preflight checks of a composed config, before Hydra creates a run directory.

Called by :func:`penaltyrun.cli.preflight.preflight` on the config composed from the command line:
every option's type and range (runner, report, optimizer, parameterization, problem, case),
keys that the shipped config does not know (``+foo=1``), the run directory (can it be
created?) and, for the dask backend, the scheduler (can it be reached?). Each problem is
one :class:`~penaltyrun.errors.ConfigError`. Nothing here compiles a kernel: problem
modules are imported, their kernels compile at the first evaluation.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from penaltyrun.cli import spec as cells
from penaltyrun.cli.modes import JOB_MODES, MODES
from penaltyrun.cli.quickcheck import SETTINGS_NODES, settings_not_value
from penaltyrun.errors import ConfigError
from penaltyrun.runner.spec import OPTIONAL_OPTIMIZER_OPTIONS
from penaltyrun.typed import is_number

#: Subtrees whose keys are free (candidate matrices / scalars of ``mode=evaluate``).
FREE_KEYS = ("matrices", "scalars")
#: Keys a user may add with ``+key=value`` (``mode=evaluate`` only): ``gradient``.
EVALUATE_EXTRAS = ("gradient",)
#: Settings every search optimizer reads that only some presets list, added with
#: ``+key=value`` (the charge per gradient of ``polish=gradient``).
OPTIONAL_KEYS = tuple(f"optimizer.{key}" for key in OPTIONAL_OPTIMIZER_OPTIONS)


def plain(node: Any) -> Any:
    """Plain Python value of a config node (resolved)."""
    return OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) or \
        OmegaConf.is_list(node) else node


def unknown_keys(cfg: Any, base: Any, prefix: str = "") -> tuple[str, list[str]] | None:
    """First key of ``cfg`` absent from ``base`` as (dotted key, keys allowed there)."""
    if not isinstance(cfg, Mapping) or not isinstance(base, Mapping):
        return None
    for key, value in cfg.items():
        dotted = f"{prefix}{key}"
        if dotted in FREE_KEYS or dotted in EVALUATE_EXTRAS or dotted in OPTIONAL_KEYS \
                or dotted == "hydra":
            continue
        if key not in base:
            return dotted, sorted(str(k) for k in base)
        found = unknown_keys(value, base[key], f"{dotted}.")
        if found:
            return found
    return None


def check_known_keys(cfg: Mapping[str, Any], base: Mapping[str, Any]) -> None:
    """Reject keys added with ``+key=value`` that no part of penaltyrun reads, and keys
    removed with ``~key`` that it needs.

    Parameters
    ----------
    cfg, base : mapping
        The composed config, and the config composed from the same config-group choices
        without any value overrides.
    """
    found = unknown_keys(cfg, base)
    if found:
        raise ConfigError(found[0], "unknown config key", allowed=found[1])
    deleted = unknown_keys(base, cfg)
    if deleted:
        raise ConfigError(deleted[0], "is required and cannot be removed (~key); set a value "
                                      "instead")


#: Longest file or folder name (bytes) of common file systems (ext4, XFS, APFS, NTFS).
NAME_MAX = 255


def check_run_dir(path: str | Path, key: str = "hydra.run.dir", sweep: bool = False) -> None:
    """Check that directory ``path`` exists or can be created (nothing is left behind),
    that no other run is using it and that its ``results.parquet`` can be written; of a
    ``sweep`` directory, also the run directories already in it.

    Raises
    ------
    ConfigError
        If a part of the path is a file or a dangling symbolic link, the first existing
        parent is not writable, ``results.parquet`` there is not a file, or another
        penaltyrun run holds the directory (:mod:`penaltyrun.runner.lock`).
    """
    from penaltyrun.runner.lock import check_not_locked, check_sweep_dir

    path = Path(path).expanduser()
    longest = max((len(os.fsencode(name)) for name in path.parts), default=0)
    if longest > NAME_MAX:
        raise ConfigError(key, f"a folder name of {longest} bytes in {str(path)[:60]}...: the "
                               f"file system takes at most {NAME_MAX} bytes a name; choose "
                               "a shorter one")
    for part in (path, *path.parents):
        if part.is_symlink() and not part.exists():
            raise ConfigError(key, f"{part} is a symbolic link to {os.readlink(part)}, which "
                                   "does not exist")
    if path.is_dir():
        results = path / "results.parquet"
        if results.exists() and not results.is_file():
            raise ConfigError(key, f"{results} exists and is not a file (penaltyrun writes "
                                   "its results there)")
        (check_sweep_dir if sweep else check_not_locked)(path, key)
    if path.exists():
        if not path.is_dir():
            raise ConfigError(key, f"{path} exists and is not a directory")
        anchor = path
    else:
        anchor = path
        while not anchor.exists() and anchor != anchor.parent:
            anchor = anchor.parent
        if not anchor.is_dir():
            raise ConfigError(key, f"cannot create {path}: {anchor} is a file")
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".penaltyrun-check-", dir=anchor))
    except OSError as exc:
        raise ConfigError(key, f"cannot create {path}: {exc.strerror or exc} in "
                               f"{anchor}; choose a folder you can write to") from None


def check_output_dir(path: str | Path | None, key: str = "report.output") -> None:
    """Check that the report folder ``path`` (None: the default) is not a file and can be
    created.

    Raises
    ------
    ConfigError
        If ``path`` or one of its parents is a file, or it cannot be created.
    """
    if path is None:
        return
    out = Path(path).expanduser()
    if out.exists() and not out.is_dir():
        raise ConfigError(key, f"{out} is a file; the report is a folder: pass a folder "
                               "path")
    check_run_dir(out, key)


def checked_settings_node(cfg: DictConfig, key: str) -> Any:
    """The node under ``key`` of ``cfg``, unresolved (None when absent or null).

    Raises
    ------
    ConfigError
        ``key`` holds one value (``runner=5``), not settings.
    """
    node = OmegaConf.select(cfg, key)
    if node is not None and not isinstance(node, (DictConfig, Mapping)):
        raise ConfigError(key, settings_not_value(key))
    return node


def settings_node(cfg: DictConfig, key: str) -> dict[str, Any]:
    """The settings under ``key`` of ``cfg`` as a dict (``{}`` when absent or null;
    :func:`checked_settings_node`)."""
    node = checked_settings_node(cfg, key)
    return {} if node is None else dict(plain(node))


def check_matrix_entries(values: Mapping[str, Any], prefix: str) -> None:
    """Refuse entries of ``matrices.*`` / ``scalars.*`` that are not numbers (booleans
    included: ``true`` is no matrix entry)."""
    for name, value in values.items():
        if value is None:
            continue
        stack = [value]
        while stack:
            item = stack.pop()
            if isinstance(item, list):
                stack.extend(item)
            elif not is_number(item):
                raise ConfigError(f"{prefix}.{name}", f"entries must be numbers, got "
                                  f"{item!r}")


def check_evaluate_extras(mode: str, gradient: Any, z: Any) -> None:
    """``+gradient`` is true or false and only in ``mode=evaluate``; ``z`` is null or a
    list of numbers."""
    if gradient is not None:
        if mode != "evaluate":
            raise ConfigError("gradient", "only mode=evaluate reads it; drop +gradient or "
                                          "pass mode=evaluate")
        if not isinstance(gradient, bool):
            raise ConfigError("gradient", f"must be true or false, got {gradient!r}")
    if z is not None and (not isinstance(z, list) or not all(is_number(v) for v in z)):
        raise ConfigError("z", f"must be a list of numbers (the optimizer's variables in "
                               f"z_names order), e.g. z=[1.0,2.5]; got {z!r}")


def check_param_options(options: Mapping[str, Any]) -> None:
    """Check ``param.eig_bounds`` (null or [lower, upper] with 0 <= lower < upper) and
    ``param.cayley_bound`` (positive number)."""
    bounds = options.get("eig_bounds")
    if bounds is not None:
        ok = isinstance(bounds, list) and len(bounds) == 2 and all(
            is_number(v) for v in bounds)
        if not ok or not 0 <= bounds[0] < bounds[1]:
            raise ConfigError("param.eig_bounds", "must be null or [lower, upper] with "
                              f"0 <= lower < upper, got {bounds!r}")
    bound = options.get("cayley_bound", 1.0)
    if not is_number(bound) or not bound > 0:
        raise ConfigError("param.cayley_bound", f"must be a positive number, got {bound!r}")


def _options(cfg: DictConfig, group: str) -> dict[str, Any]:
    return {k: v for k, v in (plain(cfg.get(group)) or {}).items() if k != "name"}


def check_config(cfg: DictConfig, connect: bool = True,
                 base: DictConfig | None = None) -> None:
    """Check every option of a composed config (see the module docstring).

    Parameters
    ----------
    cfg : DictConfig
        The composed config (without the ``hydra`` node or with it).
    connect : bool
        Also check that a dask scheduler given in ``runner.scheduler`` can be reached.
    base : DictConfig, optional
        The config of the same group choices without value overrides: problem parameters
        must then have the type of their shipped defaults.

    Raises
    ------
    ConfigError
        The first problem found, naming its key.
    """
    from penaltyrun import optim, problems, runner
    from penaltyrun.runner.setup import checked

    mode = cfg.get("mode")
    if mode not in MODES:
        raise ConfigError("mode", f"unknown mode {mode!r}", allowed=MODES)
    report = settings_node(cfg, "report")
    runner.check_report_options(report)
    runner.check_runner_options(settings_node(cfg, "runner"),
                                connect=connect and mode == "optimize")
    check_output_dir(report.get("output"))
    if mode == "report":
        return
    check_evaluate_extras(mode, cfg.get("gradient"), plain(cfg.get("z")))
    if mode == "evaluate":
        for group in FREE_KEYS:
            check_matrix_entries(settings_node(cfg, group), group)
    if mode in JOB_MODES:
        check_param_options(_options(cfg, "param"))
    params = cells.problem_params(cfg)
    if base is not None:
        from penaltyrun.api.compose import check_like_defaults
        check_like_defaults(params, plain(base.problem.get("params")) or {}, "problem.params")
    if mode not in JOB_MODES:
        checked("problem.params", problems.make, cfg.problem.name, cfg.get("case"), params,
                cells.problem_module(cfg))
        return
    spec = cells.run_spec(cfg)  # the cell as the runner builds and plans it
    prob, _, _ = spec.build()
    spec.warm_start_share()
    optim.check_gradient_available(spec.optimizer, spec.optimizer_options, prob)


def check_composed(cfg: DictConfig, base: DictConfig, multirun: bool = False) -> None:
    """Check a composed config (with its ``hydra`` node) against the shipped one ``base``:
    unknown ``+keys``, every option's type and range, the run directory, the scheduler."""
    for key in SETTINGS_NODES:
        checked_settings_node(cfg, key)
    base = cells.with_params_schema(base)  # a problem's parameters: its Params dataclass
    check_known_keys(plain_nohydra(cells.with_params_schema(cfg)), plain_nohydra(base))
    check_config(cfg, base=base)
    if multirun:
        check_run_dir(cfg.hydra.sweep.dir, "hydra.sweep.dir", sweep=True)
    else:
        check_run_dir(cfg.hydra.run.dir, "hydra.run.dir")


def plain_nohydra(cfg: DictConfig) -> dict[str, Any]:
    """The config as plain Python values, without its ``hydra`` node."""
    return {k: plain(cfg[k]) if isinstance(cfg[k], DictConfig) else cfg[k]
            for k in cfg if k != "hydra"}


def sweep_variants(parsed: list[Any], dry: list[str]) -> list[list[str]]:
    """One override list per further value of each sweep (others at their first value),
    so that every value of a sweep is checked, not only the first."""
    variants = []
    for o in parsed:
        if not o.is_sweep_override() or o.key_or_group.startswith("hydra"):
            continue
        key = o.get_key_element()
        for value in list(o.sweep_string_iterator())[1:]:
            variants.append([d if d.split("=", 1)[0] != key else f"{key}={value}"
                             for d in dry])
    return variants


#: Config groups and subtrees that ``mode=evaluate`` does not read: it evaluates the given
#: ``matrices.*`` (and ``scalars.*``) on the problem and case.
EVALUATE_IGNORES = ("param", "optimizer", "runner", "report")


def check_evaluate_sweeps(parsed: list[Any]) -> None:
    """Refuse, in a sweep of ``mode=evaluate``, a sweep over a key that evaluation does not
    read (:data:`EVALUATE_IGNORES`): every value would evaluate the same matrices again.

    Parameters
    ----------
    parsed : list of hydra Override
        The overrides of the command line (and of the config's ``hydra.sweeper.params``).

    Raises
    ------
    ConfigError
        Naming the key, why, and what to sweep instead.
    """
    if any(o.key_or_group == "mode" and o.is_sweep_override() for o in parsed):
        return  # some cells optimize: their sweeps matter
    for o in parsed:
        root = o.key_or_group.lstrip("+~").split(".", 1)[0]
        if not o.is_sweep_override() or root not in EVALUATE_IGNORES:
            continue
        values = list(o.sweep_string_iterator())
        raise ConfigError(o.key_or_group, f"mode=evaluate does not read {root}: the sweep "
                          f"over {', '.join(values)} would evaluate the same matrices "
                          f"{len(values)} times; drop it (sweep matrices.*, problem, case or "
                          "problem.params.* instead)")


def check_variant(compose: Callable[..., DictConfig], overrides: list[str],
                  config_name: str = "config") -> None:
    """Compose one sweep variant with ``compose`` (Hydra's) and check its options."""
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    try:
        cfg = compose(config_name=config_name, overrides=overrides)
    except (HydraException, OmegaConfBaseException) as exc:
        raise ConfigError("override", " ".join(str(exc).split()[:40])) from None
    check_config(cfg, connect=False)
