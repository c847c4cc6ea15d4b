"""B3/B4: a YAML bomb that Hydra would reach only through a defaults list (in a hidden
folder, deeper than the scan, or behind a linked folder) is refused before Hydra reads it."""

from __future__ import annotations

import time

import pytest

from penaltyrun.cli.preflight import preflight
from penaltyrun.cli.reachable import candidates
from penaltyrun.errors import ConfigError

#: 10^9 values once its aliases are expanded: never to be read without the limits.
BOMB = "name: zermelo\nparams:\n  l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + \
    "".join(f"  l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]\n" for i in range(1, 9))


@pytest.mark.parametrize("place, group", [(".hid", "/.hid@problem"),
                                          ("g1/g2/g3", "/g1/g2/g3@problem"),
                                          ("lnk", "/lnk@problem")])
def test_a_bomb_reached_only_through_a_defaults_list_is_refused_at_once(tmp_path, place,
                                                                       group):
    conf = tmp_path / "conf"
    (conf / "experiment").mkdir(parents=True)
    if place == "lnk":
        (tmp_path / "elsewhere").mkdir()
        (tmp_path / "elsewhere" / "bomb.yaml").write_text(BOMB)
        (conf / "lnk").symlink_to(tmp_path / "elsewhere", target_is_directory=True)
    else:
        (conf / place).mkdir(parents=True)
        (conf / place / "bomb.yaml").write_text(BOMB)
    (conf / "experiment" / "x.yaml").write_text(
        f"# @package _global_\ndefaults:\n  - {group}: bomb\n")
    start = time.process_time()
    with pytest.raises(ConfigError, match="aliases expand to more than"):
        preflight(["--config-dir", str(conf), "+experiment=x", "mode=plan"])
    assert time.process_time() - start < 10


def test_defaults_entries_name_the_files_hydra_would_read(tmp_path):
    for rel in ("problem/mine.yaml", "experiment/base.yaml", "experiment/sub/a.yaml",
                "top.yaml"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("{}\n")
    dirs = [tmp_path]
    assert candidates({"override /problem@problem": "mine"}, "experiment", dirs) == [
        tmp_path / "problem/mine.yaml"]
    assert candidates({"sub": ["a", "missing"]}, "experiment", dirs) == [
        tmp_path / "experiment/sub/a.yaml"]
    assert candidates("base", "experiment", dirs) == [tmp_path / "experiment/base.yaml"]
    assert candidates("top", "", dirs) == [tmp_path / "top.yaml"]
    assert candidates("_self_", "experiment", dirs) == []
    assert candidates({"optional problem": None}, "", dirs) == []
