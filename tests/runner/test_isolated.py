"""Work outside the jobs that runs a problem's code (the forecast before a run) under
``runner.job_timeout``: in a forked process of its own, so that a problem that hangs or
ends its process costs the forecast only, with one warning."""

import logging
import os
import time

import numpy as np
import psutil
import pytest

import penaltyrun
from penaltyrun import problems
from penaltyrun.runner import forecast, isolated, plan_jobs

pytestmark = pytest.mark.skipif(not isolated.can_isolate(), reason="needs fork")


def _sleep_forever():
    time.sleep(3600)


def _fail(kind):
    if kind == "raise":
        raise ValueError("bad sample")
    if kind == "interrupt":
        raise KeyboardInterrupt
    os._exit(3)


def test_a_result_comes_back():
    assert isolated.call_isolated(divmod, (7, 2), 30, "limit") == (3, 1)


def test_a_hanging_call_is_killed_at_its_limit():
    t0 = time.monotonic()
    with pytest.raises(isolated.IsolatedCallError, match=r"ran longer than limit=0.5 s") as info:
        isolated.call_isolated(_sleep_forever, (), 0.5, "limit")
    assert time.monotonic() - t0 < 10
    pid = int(str(info.value).split("pid ")[1].split(")")[0])
    assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE


@pytest.mark.parametrize("kind, text", [("raise", "ValueError: bad sample"),
                                        ("interrupt", "KeyboardInterrupt"),
                                        ("exit", "exited with code 3")])
def test_a_failing_call_is_one_line(kind, text):
    with pytest.raises(isolated.IsolatedCallError) as info:
        isolated.call_isolated(_fail, (kind,), 30, "limit")
    assert text in str(info.value) and "\n" not in str(info.value)


def test_a_hanging_problem_costs_the_forecast_only(tmp_path, caplog):
    def cost(K):
        time.sleep(3600)
        return float(np.trace(K))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="hangs_forecast")
    with problems.hold(prob) as module:
        jobs = plan_jobs("hangs_forecast", prob.case, "diagonal", "baseline", n_starts=2,
                         root_seed=0, problem_module=module)
        t0 = time.monotonic()
        with caplog.at_level(logging.WARNING):
            assert forecast.log_forecast(jobs, 2, 0, 1, time_limit_s=0.5) == {}
    assert time.monotonic() - t0 < 10
    lines = [r.getMessage() for r in caplog.records if "forecast" in r.getMessage()]
    assert len(lines) == 1 and "runner.job_timeout=0.5 s" in lines[0]


@pytest.mark.parametrize("exc", [KeyboardInterrupt, SystemExit])
def test_a_problem_raising_an_interrupt_costs_the_forecast_only(exc, caplog):
    """Without a limit the forecast runs in this process: the problem's own
    KeyboardInterrupt / SystemExit is one warning, not a stopped run."""
    def cost(K):
        raise exc

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="raises_forecast")
    with problems.hold(prob) as module, caplog.at_level(logging.WARNING):
        jobs = plan_jobs("raises_forecast", prob.case, "diagonal", "baseline", n_starts=2,
                         root_seed=0, problem_module=module)
        assert forecast.log_forecast(jobs, 2, 0, 1) == {}
    lines = [r.getMessage() for r in caplog.records if "forecast" in r.getMessage()]
    assert lines == [f"forecast: not available ({exc.__name__} raised by the problem's code)"]
