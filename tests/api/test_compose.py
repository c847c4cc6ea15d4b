"""The API composes each cell's config as Hydra does for the command line: same nodes,
same config hash, same job ids (studies deduplicate runs by the hash)."""

from __future__ import annotations

import pytest
from hydra import compose as hydra_compose
from hydra import initialize_config_module

from penaltyrun.api.compose import choices, compose, plain, run_spec
from penaltyrun.cli import spec as cells
from penaltyrun.errors import ConfigError
from penaltyrun.runner import config_hash
from penaltyrun.yamlsafe import MAX_DEPTH

#: Every problem file, every map file and every optimizer file (some with a defaults list of
#: their own), each once.
CELLS = sorted({*((p, "full", "cmaes") for p in choices("problem")),
                *(("zermelo", m, "pso") for m in choices("param")),
                *(("zermelo", "diagonal", o) for o in choices("optimizer"))})


@pytest.fixture(scope="module")
def hydra_cfg():
    with initialize_config_module("penaltyrun.conf", version_base="1.3"):
        yield lambda overrides: hydra_compose("config", overrides=overrides)


def test_every_config_file_composes_as_hydra_does(hydra_cfg):
    for problem, param, optimizer in CELLS:
        cfg = hydra_cfg([f"problem={problem}", f"param={param}", f"optimizer={optimizer}",
                         "runner.seed=3"])
        want = cells.run_spec(cfg)
        got = run_spec(compose(problem, None, case=None, param=param, optimizer=optimizer,
                                optimizer_options=None, params=None, runner={"seed": 3}))
        cell = (problem, param, optimizer)
        assert config_hash(got.hashed) == config_hash(want.hashed), cell
        for field in ("problem", "case", "param", "optimizer", "problem_params",
                      "param_options", "optimizer_options", "problem_module"):
            assert getattr(got, field) == getattr(want, field), (*cell, field)
        assert got.runner == want.runner and got.runner.seed == 3


def test_overrides_compose_as_hydra_does(hydra_cfg):
    cfg = hydra_cfg(["problem=lqr", "case=default", "param=givens", "optimizer=pso",
                     "optimizer.iters=7", "++problem.params.t_max=5.0", "runner.seed=1"])
    got = run_spec(compose("lqr", None, case="default", param="givens", optimizer="pso",
                            optimizer_options={"iters": 7}, params={"t_max": 5.0},
                            runner={"seed": 1}))
    want = cells.run_spec(cfg)
    assert got.hashed == want.hashed and got.problem_params == want.problem_params


def test_unknown_choices_list_the_files():
    with pytest.raises(ConfigError, match="unknown param 'spiral'.*givens"):
        compose("zermelo", None, case=None, param="spiral", optimizer="pso",
                optimizer_options=None, params=None, runner={})


def test_a_value_nested_deeper_than_a_config_file_may_be_is_one_config_error():
    deep: list = []
    inner = deep
    for _ in range(3000):
        inner.append([])
        inner = inner[0]
    with pytest.raises(ConfigError, match=f"params: nested deeper than {MAX_DEPTH} levels"):
        plain({"x0": deep}, "params")
    ok = [[1.0, 2.0], [3.0, 4.0]]
    assert plain({"A": ok, "n": (1, 2)}, "params") == {"A": ok, "n": [1, 2]}
