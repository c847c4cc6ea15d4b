"""The paper table: published evaluation counts beside ours where a source gives them."""

import pytest

from penaltyrun import io, runner
from penaltyrun.problems.attitude.report import COMPANION_EVALS
from penaltyrun.report import sections
from penaltyrun.report.stats import add_variant

TINY = {"n_particles": 4, "iters": 2, "ftol_iter": 2}


@pytest.fixture(scope="module")
def companion_frame(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("companion")
    jobs = []
    for param in ("diagonal", "givens"):
        jobs += runner.plan_jobs("attitude_lyapunov", "schaub_detumble", param, "pso", n_starts=2,
                                 root_seed=3, problem_params={"holdout_n_perturbed": 1},
                                 optimizer_options=TINY, meta={"git_commit": "test"})
    runner.execute(jobs, run_dir)
    return add_variant(io.read_results(io.collect(run_dir)))


def test_published_evaluations_stand_beside_ours_with_the_ratio(companion_frame):
    table = sections.paper_rows(companion_frame).set_index("map")
    low, median, high = COMPANION_EVALS["schaub_detumble"]["diagonal"]
    diagonal = table.loc["diagonal"]
    assert diagonal[sections.PAPER_EVALS] == f"{median:.0f} ({low:.0f}–{high:.0f})"
    ours = companion_frame.loc[companion_frame["param"] == "diagonal", "n_evals"]
    assert diagonal[sections.OUR_EVALS] == \
        f"{ours.median():.0f} ({ours.min():.0f}–{ours.max():.0f})"
    assert diagonal[sections.EVALS_RATIO] == pytest.approx(ours.median() / median)
    givens = table.loc["givens"]  # the authors published no counts for this map
    assert givens[sections.PAPER_EVALS] != givens[sections.PAPER_EVALS]  # NaN
    assert givens[sections.EVALS_RATIO] != givens[sections.EVALS_RATIO]


def test_evaluation_columns_are_left_out_where_no_source_gives_counts(companion_frame):
    givens = companion_frame[companion_frame["param"] == "givens"]
    table = sections.paper_rows(givens)
    assert len(table) == 1
    assert not set(sections.EVALUATION_COLUMNS) & set(table.columns)
