"""Hydra's private API is used in one module, and what the command line builds from it
matches what Hydra's app does."""

import ast
from pathlib import Path

import pytest
from hydra import compose
from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.global_hydra import GlobalHydra
from hydra.core.override_parser.overrides_parser import OverridesParser
from hypothesis import given, settings
from hypothesis import strategies as st

import penaltyrun
from penaltyrun.cli import hydra_private, userconf
from penaltyrun.cli.planmode import sweep_combinations
from penaltyrun.errors import ConfigError

PACKAGE = Path(penaltyrun.__file__).parent


def _imports_of(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return names


def test_private_hydra_is_imported_only_by_hydra_private():
    users = sorted(str(p.relative_to(PACKAGE)) for p in PACKAGE.rglob("*.py")
                   if any(m.startswith("hydra._internal") for m in _imports_of(p)))
    assert users == ["cli/hydra_private.py"]


def test_args_parser_parses_as_hydra_main():
    args = hydra_private.args_parser().parse_args(["-m", "--config-dir", "/tmp", "a=1", "b=2"])
    assert args.multirun and args.config_dir == "/tmp" and args.overrides == ["a=1", "b=2"]


def test_config_dir_is_searched_after_the_primary_folder(tmp_path):
    """As Hydra's own ``--config-dir``: a user's file is found, but the primary folder's
    file of the same name comes first (which is why such a name is refused)."""
    (tmp_path / "problem").mkdir()
    (tmp_path / "problem" / "zermelo.yaml").write_text("name: zermelo\nparams:\n  x0: [3.0, 4.0]\n")
    (tmp_path / "problem" / "mine.yaml").write_text("name: mine\n")
    source = userconf.ConfigSource(primary=userconf.CONF_DIR, config_name="config",
                                   config_dirs=(tmp_path,))
    with userconf.hydra_context(source):
        assert "mine" in userconf.group_options("problem", source, [])
        cfg = compose(config_name="config", overrides=["problem=zermelo"])
        assert list(cfg.problem.params.x0) == [-8.0, 6.0]
    assert not GlobalHydra.instance().is_initialized()
    with pytest.raises(ConfigError, match=r"problem/zermelo.yaml has the name of penaltyrun's "
                                          r"own problem=zermelo.*problem=zermelo_mine"):
        userconf.parse_source(["--config-dir", str(tmp_path)])


_values = st.lists(st.sampled_from(["1", "2", "x", "y7"]), min_size=1, max_size=3)
_override = st.tuples(st.sampled_from(["a", "b", "c.d", "e"]), _values)


@settings(max_examples=60, deadline=None)
@given(st.lists(_override, min_size=1, max_size=5))
def test_sweep_combinations_equal_hydras_basic_sweeper(overrides):
    lines = [f"{k}={','.join(v)}" for k, v in overrides]
    parsed = OverridesParser.create().parse_overrides(lines)
    assert sweep_combinations(parsed) == BasicSweeper.split_arguments(parsed, None)[0]


def test_range_sweeps_expand_and_an_interval_is_one_line():
    parser = OverridesParser.create()
    assert sweep_combinations(parser.parse_overrides(["a=range(1,4)", "b=q"])) == [
        ["a=1", "b=q"], ["a=2", "b=q"], ["a=3", "b=q"]]
    with pytest.raises(ConfigError, match="interval"):
        sweep_combinations(parser.parse_overrides(["a=interval(0,1)"]))
