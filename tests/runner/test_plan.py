"""Job planning: ids, per-job seeds, validation."""

from __future__ import annotations

import json

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.runner.plan import Job, config_hash, job_seed, plan_jobs

CELL = ("zermelo", "default", "geagsp", "pso")


def test_job_ids_unique_and_formatted():
    jobs = plan_jobs(*CELL, n_starts=12, root_seed=0)
    ids = [j.job_id for j in jobs]
    assert len(set(ids)) == 12
    settings = jobs[0].settings_hash
    assert len(settings) == 8 and all(j.settings_hash == settings for j in jobs)
    assert ids[0] == f"zermelo-default-geagsp-pso-{settings}-s000"
    assert ids[11] == f"zermelo-default-geagsp-pso-{settings}-s011"
    assert [j.start for j in jobs] == list(range(12))
    other = plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=12, root_seed=0)
    assert not set(ids) & {j.job_id for j in other}


def test_other_settings_give_other_job_ids_but_same_seeds():
    base = plan_jobs(*CELL, n_starts=2, root_seed=0, optimizer_options={"iters": 10})
    more = plan_jobs(*CELL, n_starts=2, root_seed=0, optimizer_options={"iters": 20})
    tf80 = plan_jobs(*CELL, n_starts=2, root_seed=0, optimizer_options={"iters": 10},
                     problem_params={"t_max": 80.0})
    assert len({j.job_id for j in base + more + tf80}) == 6
    assert [j.seed for j in base] == [j.seed for j in more] == [j.seed for j in tf80]


def test_plan_is_stable_across_calls():
    a = plan_jobs(*CELL, n_starts=5, root_seed=3, problem_params={"x": 1})
    b = plan_jobs(*CELL, n_starts=5, root_seed=3, problem_params={"x": 1})
    assert a == b
    assert [j.job_id for j in a] == [j.job_id for j in b]
    assert [j.seed for j in a] == [j.seed for j in b]


def test_seed_golden_value():
    """Seeds must not change between versions or machines (results are reproducible)."""
    assert job_seed(0, "zermelo/default/geagsp/pso/0") == 4101484616
    assert plan_jobs(*CELL, n_starts=1, root_seed=0)[0].seed == 4101484616


def test_seeds_distinct_across_starts_cells_and_roots():
    jobs = plan_jobs(*CELL, n_starts=50, root_seed=0)
    seeds = [j.seed for j in jobs]
    assert len(set(seeds)) == 50
    assert all(isinstance(s, int) and 0 <= s < 2**32 for s in seeds)
    other_cell = plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=50, root_seed=0)
    assert not set(seeds) & {j.seed for j in other_cell}
    other_root = plan_jobs(*CELL, n_starts=50, root_seed=1)
    assert not set(seeds) & {j.seed for j in other_root}


def test_seeds_independent_of_n_starts():
    few = plan_jobs(*CELL, n_starts=3, root_seed=7)
    many = plan_jobs(*CELL, n_starts=10, root_seed=7)
    assert [j.seed for j in few] == [j.seed for j in many[:3]]
    assert few[0].seed == many[0].seed


def test_options_are_copied_into_each_job():
    opts = {"eig_bounds": [0.1, 10.0]}
    jobs = plan_jobs(*CELL, n_starts=2, root_seed=0, param_options=opts,
                     optimizer_options={"iters": 5}, meta={"config_hash": "h"})
    assert jobs[0].param_options == opts
    assert jobs[0].param_options is not opts
    assert jobs[0].param_options is not jobs[1].param_options
    assert jobs[1].optimizer_options == {"iters": 5} and jobs[1].meta == {"config_hash": "h"}
    d = jobs[0].to_dict()
    assert d["seed"] == jobs[0].seed and d["problem"] == "zermelo"
    assert json.loads(json.dumps(d)) == d
    assert Job(**d) == jobs[0]


@pytest.mark.parametrize("n_starts", [0, -1, 2.5, "3", True, None])
def test_bad_n_starts(n_starts):
    with pytest.raises(ConfigError) as info:
        plan_jobs(*CELL, n_starts=n_starts, root_seed=0)
    assert info.value.key == "runner.n_starts"
    assert "runner.n_starts" in str(info.value)


def test_config_hash():
    h = config_hash({"a": 1, "b": [1, 2]})
    assert len(h) == 16 and int(h, 16) >= 0
    assert h == config_hash({"b": [1, 2], "a": 1})  # key order does not matter
    assert h != config_hash({"a": 2, "b": [1, 2]})


def test_job_id_covers_the_root_seed_and_the_holdout_setting():
    base = plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=1)
    other_seed = plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=2)
    no_holdout = plan_jobs("zermelo", "default", "full", "pso", n_starts=2, root_seed=1,
                           holdout=False)
    ids = [{j.job_id for j in jobs} for jobs in (base, other_seed, no_holdout)]
    assert not ids[0] & ids[1] and not ids[0] & ids[2] and not ids[1] & ids[2]
    assert {j.job_id for j in plan_jobs("zermelo", "default", "full", "pso", n_starts=2,
                                        root_seed=1)} == ids[0]


def test_n_starts_bound():
    from penaltyrun.runner.plan import MAX_N_STARTS

    with pytest.raises(ConfigError, match=f"limit of {MAX_N_STARTS}"):
        plan_jobs("zermelo", "default", "full", "pso", n_starts=MAX_N_STARTS + 1, root_seed=1)
