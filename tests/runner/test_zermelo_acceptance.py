"""Acceptance: the default PSO budget recovers the paper's Zermelo matrices on ≥ 8/10 starts."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from penaltyrun import runner
from penaltyrun.problems.zermelo import PAPER_K_DIAGONAL, PAPER_K_FULL

CONF = Path(__file__).resolve().parents[2] / "penaltyrun" / "conf"


def default_pso() -> dict:
    settings = yaml.safe_load((CONF / "optimizer" / "pso.yaml").read_text())
    settings.pop("name")
    return settings


@pytest.mark.parametrize(("param", "paper_K"), [("diagonal", PAPER_K_DIAGONAL),
                                                 ("full", PAPER_K_FULL)])
def test_default_budget_finds_paper_matrix(param, paper_K):
    jobs = runner.plan_jobs("zermelo", "default", param, "pso", n_starts=10, root_seed=20250422,
                            optimizer_options=default_pso())
    hits = 0
    for job in jobs:
        record = runner.run_job(job)
        assert record["status"] == "ok"
        K = np.asarray(record["matrices"]["K"])
        hits += np.max(np.abs(K - paper_K)) / np.max(np.abs(paper_K)) <= 0.005
    assert hits >= 8
