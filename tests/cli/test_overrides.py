"""Splitting the command line into Hydra's options and the overrides."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.cli.overrides import MAX_CHARS, MAX_VALUES, count_values, parse_each, split_argv
from penaltyrun.cli.preflight import preflight
from penaltyrun.errors import ConfigError
from penaltyrun.yamlsafe import MAX_DEPTH


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


_item = st.one_of(st.integers(-10**6, 10**6).map(str),
                  st.text("abc, =", min_size=1, max_size=6).map(lambda t: f"'{t}'"))


@settings(max_examples=80, deadline=None)
@given(st.lists(_item, min_size=2, max_size=12))
def test_count_values_counts_what_hydra_parses(items):
    """Commas inside quotes are no separators: the count is the sweep's length."""
    (override,) = parse_each([f"k={','.join(items)}"], str)
    assert count_values(override.input_line) == len(override.value().list)
    (listed,) = parse_each([f"k=[{','.join(items)}]"], str)
    assert count_values(listed.input_line) == len(listed.value())


def test_the_size_check_comes_before_the_parser(monkeypatch):
    from hydra.core.override_parser.overrides_parser import OverridesParser

    monkeypatch.setattr(OverridesParser, "parse_overrides", None)  # never reached
    with pytest.raises(ConfigError, match=f"the limit is {MAX_VALUES} per override"):
        parse_each(["k=" + ",".join(["1"] * (MAX_VALUES + 1))], str)
    with pytest.raises(ConfigError, match=f"the limit is {MAX_CHARS}\\)"):
        parse_each(["k=" + "x" * MAX_CHARS], str)
    with pytest.raises(ConfigError, match=f"nested {MAX_DEPTH + 1} levels deep"):
        parse_each(["k=" + "[" * (MAX_DEPTH + 1) + "]" * (MAX_DEPTH + 1)], str)
    with pytest.raises(ConfigError, match="nested 3000 levels deep"):
        parse_each(["k=choice(" + "{a:" * 2999 + "1" + "}" * 2999 + ")"], str)


def test_brackets_inside_quotes_do_not_nest_and_a_matrix_passes():
    deep = "[" * (MAX_DEPTH + 5)
    parsed = parse_each([f"k='{deep}'", "m=[[1,2],[3,4]]", f"n=[[[{deep[:MAX_DEPTH - 3]}"
                         f"{']' * (MAX_DEPTH - 3)}]]]"], str)
    assert parsed[0].value() == deep and parsed[1].value() == [[1, 2], [3, 4]]
