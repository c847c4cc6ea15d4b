"""The how-to's optimizer, registered as the how-to says, runs a job of the runner: its
settings are checked, its batch size forecast, its result recorded."""

from __future__ import annotations

import re
import sys
import types
from pathlib import Path

import pytest

from penaltyrun import optim
from penaltyrun.errors import ConfigError
from penaltyrun.runner import forecast
from penaltyrun.runner.job import run_job
from penaltyrun.runner.spec import RunnerOptions, RunSpec

HOWTO = Path(__file__).resolve().parents[2] / "docs" / "how-to" / "add-an-optimizer.md"


@pytest.fixture
def random_search(monkeypatch):
    """The module of the how-to's first code block, registered as ``random``."""
    code = re.findall(r"```python\n(.*?)```", HOWTO.read_text(), re.S)[0]
    module = types.ModuleType("random_search")
    monkeypatch.setitem(sys.modules, module.__name__, module)  # dataclasses look it up
    exec(compile(code, str(HOWTO), "exec"), module.__dict__)  # noqa: S102 (our own docs)
    entry = optim.Optimizer(module.RandomSettings, module.run_random)
    monkeypatch.setitem(optim.OPTIMIZERS, "random", entry)
    return module


def test_the_how_to_optimizer_runs_a_job(random_search):
    settings = optim.make_settings("random", {"max_evals": 64, "batch": 16})
    assert forecast.optimizer_batch(settings, 3) == 16
    with pytest.raises(ConfigError, match="optimizer.max_evals: random search needs a budget"):
        optim.make_settings("random", {})
    spec = RunSpec("zermelo", None, "diagonal", "random", optimizer_options={"max_evals": 64},
                   runner=RunnerOptions(n_starts=2, seed=1))
    prob, _, _ = spec.build()
    jobs = spec.plan(prob.case)
    records = [run_job(job) for job in jobs]
    assert [r["status"] for r in records] == ["ok", "ok"]
    assert all(r["n_evals"] <= 64 for r in records)
    assert records[0]["best_cost"] != records[1]["best_cost"]  # seeded per job
    assert run_job(jobs[0])["best_cost"] == records[0]["best_cost"]  # and reproducible
