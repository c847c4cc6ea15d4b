"""Jobs at an equal evaluation budget, and warm-started full maps (Zermelo)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from penaltyrun import io, runner

BUDGET = 600
OPTIONS = {"pso": {"n_particles": 30, "iters": 1000, "max_evals": BUDGET},
           "de": {"popsize": 15, "iters": 1000, "max_evals": BUDGET, "polish": "L-BFGS-B"},
           "cmaes": {"max_evals": BUDGET},
           "pso_matlab": {"swarm_size": 30, "max_evals": BUDGET}}


@pytest.mark.parametrize("optimizer", sorted(OPTIONS))
def test_every_job_respects_max_evals(tmp_path, optimizer):
    jobs = []
    for param in ("diagonal", "givens"):
        jobs += runner.plan_jobs("zermelo", "default", param, optimizer, n_starts=2, root_seed=7,
                                 optimizer_options=OPTIONS[optimizer], meta={"git_commit": "test"})
    runner.execute(jobs, tmp_path)
    df = io.read_results(io.collect(tmp_path))
    assert len(df) == 4 and set(df["status"]) == {"ok"}
    assert (df["n_evals"] <= BUDGET).all() and (df["max_evals"] == BUDGET).all()
    for _, row in df.iterrows():
        assert row["trace_evals"][-1] == row["n_evals"]
        assert row["trace_best"][-1] == pytest.approx(row["best_cost"])


@pytest.mark.parametrize("optimizer", ["pso", "cmaes", "pso_matlab"])
def test_warm_started_full_job_is_never_worse_than_its_diagonal_stage(tmp_path, optimizer):
    options = {**OPTIONS[optimizer], "max_evals": 500}
    jobs = runner.plan_jobs("zermelo", "default", "full", optimizer, n_starts=1, root_seed=3,
                            optimizer_options=options, meta={"git_commit": "test"},
                            warm_start_share=0.4)
    cold = runner.plan_jobs("zermelo", "default", "full", optimizer, n_starts=1, root_seed=3,
                            optimizer_options=options, meta={"git_commit": "test"})
    assert jobs[0].job_id != cold[0].job_id and jobs[0].seed == cold[0].seed
    record = json.loads(runner.execute(jobs, tmp_path)[0].read_text())
    warm = record["warm_start"]
    assert warm["share"] == 0.4 and warm["n_evals"] == 200
    assert 0 <= warm["polish_evals"] <= record["polish_evals"]  # the diagonal stage's polish
    assert np.asarray(warm["matrices"]["K"])[0, 1] == 0.0  # the diagonal stage's best
    assert record["best_cost"] <= warm["best_cost"] * (1 + 1e-12)
    assert record["n_evals"] <= 500 and record["trace_evals"][-1] == record["n_evals"]
    assert np.all(np.diff(record["trace_best"]) <= 0)
    assert record["stop_reason"].startswith("warm:")


def test_warm_start_is_ignored_for_the_diagonal_map():
    jobs = runner.plan_jobs("zermelo", "default", "diagonal", "pso", n_starts=1, root_seed=3,
                            optimizer_options=OPTIONS["pso"], warm_start_share=0.3)
    assert jobs[0].warm_start_share == 0.0


def test_a_warm_started_job_searches_as_long_as_a_cold_diagonal_job(tmp_path):
    """Each stage keeps its share of max_evals: a diagonal stage whose polish converges
    early leaves its unspent evaluations unspent, so the job's searches spend what the cold
    diagonal job's search spends and the report tests them at an equal budget."""
    from penaltyrun.report.compare import budget, equal_budget
    from penaltyrun.report.stats import add_variant

    options = {"max_evals": 3000, "polish": "gradient", "polish_share": 0.2}
    jobs = runner.plan_jobs("zermelo", "default", "diagonal", "cmaes", n_starts=2, root_seed=5,
                            optimizer_options=options, meta={"git_commit": "test"})
    jobs += runner.plan_jobs("zermelo", "default", "givens", "cmaes", n_starts=2, root_seed=5,
                             optimizer_options=options, meta={"git_commit": "test"},
                             warm_start_share=0.3)
    runner.execute(jobs, tmp_path)
    df = add_variant(io.read_results(io.collect(tmp_path)))
    search = df["n_evals"] - df["polish_evals"].fillna(0)
    warm = df["param"] == "givens"
    assert (df.loc[warm, "n_evals"] <= 3000).all()
    stage = df.loc[warm, "warm_start"].map(lambda w: json.loads(w)["n_evals"])
    assert (stage < 900).any()  # a diagonal stage whose polish converged early
    cold_search, warm_search = search[~warm].mean(), search[warm].mean()
    assert abs(warm_search - cold_search) <= 0.01 * cold_search, (cold_search, warm_search)
    assert df["variant"].nunique() == 1
    assert equal_budget(budget(df[~warm]), budget(df[warm]))
