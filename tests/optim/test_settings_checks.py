"""Optimizer options are checked against the settings dataclasses' annotations."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from penaltyrun import optim
from penaltyrun.errors import ConfigError
from penaltyrun.optim.checks import coerce_field, settings_hints


@dataclass(frozen=True)
class _Demo:
    budget: int | None = None
    share: float = 0.5
    method: str = "none"
    bounds: tuple[float, float] = (0.0, 1.0)
    sizes: tuple[int, ...] = (1,)
    flag: bool = False


HINTS = settings_hints(_Demo)


@pytest.mark.parametrize(("key", "value", "expected"), [
    ("budget", None, None), ("budget", 7, 7), ("share", 1, 1.0), ("method", "x", "x"),
    ("bounds", [0, 2.5], (0.0, 2.5)), ("sizes", [1, 2, 3], (1, 2, 3)), ("flag", True, True),
])
def test_values_that_fit_are_converted(key, value, expected):
    out = coerce_field(f"optimizer.{key}", value, HINTS[key])
    assert out == expected and type(out) is type(expected)


@pytest.mark.parametrize(("key", "value", "fragment"), [
    ("budget", "abc", "an integer or null"), ("budget", 2.5, "an integer or null"),
    ("budget", True, "an integer or null"), ("share", "abc", "a number"),
    ("share", float("nan"), "a number"), ("method", 3, "a string"),
    ("bounds", [1], "a list of 2 values"), ("bounds", "ab", "a list of 2 values"),
    ("sizes", [1.5], "a list of integers"), ("flag", "yes", "true or false"),
])
def test_values_that_do_not_fit_are_one_error(key, value, fragment):
    with pytest.raises(ConfigError, match=f"optimizer.{key}: must be {fragment}"):
        coerce_field(f"optimizer.{key}", value, HINTS[key])


@pytest.mark.parametrize(("name", "options", "fragment"), [
    ("pso", {"w": "abc"}, "optimizer.w: must be a number"),
    ("pso", {"w": -0.1}, "optimizer.w: must be a finite number in [0, inf)"),
    ("pso", {"c1": float("inf")}, "optimizer.c1"),
    ("pso", {"vh_strategy": "bogus"}, "allowed: unmodified, adjust, invert, zero"),
    ("pso", {"bh_strategy": "wrap"}, "allowed: nearest"),
    ("pso", {"n_particles": 2.0}, "optimizer.n_particles: must be an integer"),
    ("de", {"mutation": [1.5, 0.5]}, "optimizer.mutation"),
    ("de", {"mutation": [0.5, 3]}, "optimizer.mutation"),
    ("de", {"recombination": 1.5}, "optimizer.recombination"),
    ("de", {"polish": "yes"}, "optimizer.polish"),
    ("pso", {"max_evals": "many"}, "optimizer.max_evals: must be an integer or null"),
    ("pso", {"polish_share": "x"}, "optimizer.polish_share: must be a number"),
    ("baseline", {"scale": 0}, "optimizer.scale"),
])
def test_make_settings_checks_types_and_ranges(name, options, fragment):
    with pytest.raises(ConfigError) as err:
        optim.make_settings(name, options)
    assert fragment in str(err.value)


def test_make_settings_converts_config_values():
    settings = optim.make_settings("de", {"mutation": [0.5, 1], "recombination": 1})
    assert settings.mutation == (0.5, 1.0) and settings.recombination == 1.0
    assert optim.make_settings("pso", {"w": 1}).w == 1.0
