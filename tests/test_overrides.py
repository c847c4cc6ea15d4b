"""Splitting the command line into Hydra's options and the overrides."""

from __future__ import annotations

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.overrides import parse_each, split_argv
from penaltyrun.preflight import preflight


def test_an_option_value_with_equals_is_not_an_override():
    options, overrides = split_argv(["-p", "pkg=x", "case=A", "-m", "--info", "config",
                                     "param=full", "--experimental-rerun", "a=b"])
    assert options == ["-p", "pkg=x", "-m", "--info", "config", "--experimental-rerun", "a=b"]
    assert overrides == ["case=A", "param=full"]


def test_info_without_a_choice_takes_no_value():
    assert split_argv(["--info", "case=A"]) == (["--info"], ["case=A"])


def test_preflight_leaves_the_value_of_package_to_hydra():
    preflight(["-p", "nonexistent_key=1", "mode=plan"])  # not refused as an unknown key
    with pytest.raises(ConfigError, match="nonexistent_key"):
        preflight(["nonexistent_key=1", "mode=plan"])


def test_parse_each_names_the_bad_override():
    with pytest.raises(ConfigError, match=r"^case: malformed override 'case=\[': oops"):
        parse_each(["mode=plan", "case=["], lambda exc: "oops")
