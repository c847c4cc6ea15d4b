"""The API composes each cell's config as Hydra does for the command line: same nodes,
same config hash, same job ids (studies deduplicate runs by the hash)."""

from __future__ import annotations

import pytest
from hydra import compose as hydra_compose
from hydra import initialize_config_module

from penaltyrun import api
from penaltyrun.api.compose import check_like_defaults, choices, compose, plain, run_spec
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
    with pytest.raises(ConfigError, match="param: unknown choice 'spiral'.*givens"):
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


@pytest.mark.parametrize(("values", "fragment"), [
    ({"x0": "abc"}, "list of 2 numbers"), ({"x0": [1, 2, 3]}, "list of 2 numbers"),
    ({"t_max": True}, "a number"), ({"t_max": "1"}, "a number"), ({"flag": 1}, "true or"),
])
def test_problem_params_like_defaults(values, fragment):
    defaults = {"x0": [0.0, 1.0], "t_max": 10.0, "flag": False, "free": None}
    check_like_defaults({"x0": [1, 2], "t_max": 3, "free": "x"}, defaults, "p")
    with pytest.raises(ConfigError, match=fragment):
        check_like_defaults(values, defaults, "p")


def test_yaml_infinity_on_the_command_line_names_the_spelling_that_works():
    with pytest.raises(ConfigError, match=r"got '\.inf' \(Hydra reads YAML's \.inf as text: "
                                          r"write inf or -inf\)"):
        check_like_defaults({"event_spacing": ".inf"}, {"event_spacing": 0.05}, "p")
    check_like_defaults({"event_spacing": float("inf")}, {"event_spacing": 0.05}, "p")


@pytest.mark.parametrize("params", [{"x0": [[[[1.0]]]]}, {"x0": "abc"}, {"t_max": "x"}])
def test_library_refuses_problem_params_unlike_their_defaults(params, tmp_path):
    key = f"problem.params.{next(iter(params))}"
    with pytest.raises(ConfigError, match=key):
        api.evaluate("zermelo", matrices={"K": [[1.0, 0.0], [0.0, 1.0]]}, params=params)
    with pytest.raises(ConfigError, match=key):
        api.tune("zermelo", n_starts=1, optimizer_options={"max_evals": 20}, params=params,
                 run_dir=tmp_path, workers=1)
    assert not list(tmp_path.iterdir())
