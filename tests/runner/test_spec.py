"""The typed run specification: the runner options as one checked object, and a cell's
jobs planned from its :class:`RunSpec` exactly as from its parts."""

from __future__ import annotations

import dataclasses

import pytest

from penaltyrun.api.compose import CONF, read_yaml
from penaltyrun.errors import ConfigError
from penaltyrun.runner.plan import plan_jobs
from penaltyrun.runner.spec import RunnerOptions, RunSpec
from penaltyrun.runner.usercode import user_code_hash


def test_defaults_are_those_of_the_shipped_config():
    shipped = read_yaml(CONF / "config.yaml")["runner"]
    assert RunnerOptions().as_dict() == shipped
    assert RunnerOptions.from_mapping(shipped) == RunnerOptions()


@pytest.mark.parametrize(("options", "match"), [
    ({"workers": 0}, "runner.workers: must be a positive integer or auto"),
    ({"n_starts": True}, "runner.n_starts: must be a positive integer"),
    ({"backend": "slurm"}, r"runner.backend: .*\(allowed: local, dask\)"),
    ({"scheduler": "tcp://h:1"}, "runner.scheduler: is used only with runner.backend=dask"),
    ({"warm_start_share": 1.0}, r"runner.warm_start_share: must be a number in \(0, 1\)"),
])
def test_a_bad_option_is_one_config_error(options, match):
    with pytest.raises(ConfigError, match=match):
        RunnerOptions(**options)
    with pytest.raises(ConfigError, match=match):
        RunnerOptions.from_mapping(options)


def test_an_unknown_option_lists_the_known_ones():
    with pytest.raises(ConfigError, match=r"runner.nstarts: unknown runner option \(allowed: "
                                          r"backend, chunks"):
        RunnerOptions.from_mapping({"nstarts": 3})


def test_options_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        RunnerOptions().workers = 2  # type: ignore[misc]


def test_local_workers():
    assert RunnerOptions(workers=3).local_workers() == 3
    assert RunnerOptions(backend="dask", scheduler="tcp://127.0.0.1:8786").local_workers() \
        is None


def _spec(**runner):
    return RunSpec("zermelo", None, "full", "pso", problem_params={"wind": 0.5},
                   param_options={"name": "full"}, optimizer_options={"max_evals": 100},
                   runner=RunnerOptions(n_starts=3, seed=7, **runner))


def test_plan_is_plan_jobs_of_the_parts():
    spec = _spec(holdout=False, cutoff=False)
    want = plan_jobs("zermelo", "default", "full", "pso", n_starts=3, root_seed=7,
                     problem_params={"wind": 0.5}, param_options={"name": "full"},
                     optimizer_options={"max_evals": 100}, meta={"run_id": "r"}, holdout=False,
                     cutoff=False, module_hash=user_code_hash(None, {"wind": 0.5}))
    assert spec.plan("default", {"run_id": "r"}) == want


def test_warm_start():
    assert _spec().warm_start_share() == 0.0
    jobs = _spec(warm_start=True, warm_start_share=0.25).plan("default")
    assert {job.warm_start_share for job in jobs} == {0.25}
    bare = dataclasses.replace(_spec(warm_start=True), optimizer_options={})
    with pytest.raises(ConfigError, match="runner.warm_start: needs an evaluation budget"):
        bare.plan("default")
    grid = dataclasses.replace(_spec(warm_start=True), optimizer="grid")
    with pytest.raises(ConfigError, match="runner.warm_start: not for optimizer 'grid'"):
        grid.warm_start_share()


def test_build_refuses_a_grid_too_large_for_the_map():
    spec = dataclasses.replace(_spec(), problem="lqr", problem_params={}, optimizer="grid",
                               optimizer_options={})
    with pytest.raises(ConfigError, match="grid search is for at most 4 decision variables"):
        spec.build()
