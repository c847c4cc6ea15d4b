"""Building a cell's problem under ``runner.job_timeout``: penaltyrun's own problems are
built directly; a user problem first in a process of its own (its misbehaviour is tested
through the command line in tests/cli/test_reliability_user_code.py)."""

from __future__ import annotations

import time

import numpy as np
import pytest

import penaltyrun
from penaltyrun import problems
from penaltyrun.errors import ConfigError
from penaltyrun.runner import isolated
from penaltyrun.runner.setup import build, build_within

ZERMELO = ("zermelo", None, {}, "diagonal", {}, "pso", {})


def test_own_problems_are_built_directly(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("forked for a problem of penaltyrun's own")

    monkeypatch.setattr(isolated, "call_isolated", refuse)
    prob, layout, _ = build_within(5.0, *ZERMELO)
    assert layout.dim == build(*ZERMELO)[1].dim and prob.name == "zermelo"


def test_a_module_of_a_built_in_name_is_still_user_code(monkeypatch):
    calls = []
    monkeypatch.setattr(isolated, "call_isolated", lambda *a, **k: calls.append(a))
    prob, _, _ = build_within(5.0, *ZERMELO, "penaltyrun.problems.zermelo")
    assert prob.name == "zermelo" and len(calls) == 1  # named by a module path: tried first


def test_a_construction_past_the_limit_is_one_config_error(monkeypatch):
    prob = penaltyrun.from_cost(lambda K: float(np.trace(K)), {"K": (2, (0.1, 10.0))},
                                name="slowbuild")
    with problems.hold(prob) as path:
        args = ("slowbuild", None, {}, "diagonal", {}, "pso", {}, path)
        assert build_within(5.0, *args)[0].name == "slowbuild"  # within the limit: built
        original = problems.make

        def hanging_make(*a, **k):
            time.sleep(60)
            return original(*a, **k)

        monkeypatch.setattr(problems, "make", hanging_make)
        t0 = time.monotonic()
        with pytest.raises(ConfigError, match="ran longer than runner.job_timeout=0.5 s"):
            build_within(0.5, *args)
        assert time.monotonic() - t0 < 10


@pytest.mark.parametrize("scale", [20.0, 1e-9])
def test_a_baseline_scale_outside_the_eigenvalue_bounds_is_refused_when_built(scale):
    """K = scale · I outside every map's box: refused naming optimizer.scale (every job
    failed with a message about the geagsp box before)."""
    with pytest.raises(ConfigError, match=r"outside the eigenvalue bounds \[1e-08, 10\] of "
                                          "K") as err:
        build("zermelo", None, {}, "full", {}, "baseline", {"scale": scale})
    assert err.value.key == "optimizer.scale"
    build("zermelo", None, {}, "full", {}, "baseline", {"scale": 1.0})
