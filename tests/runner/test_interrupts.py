"""A KeyboardInterrupt or SystemExit raised by a job's code ends that job (recorded
``failed``, one line); a Ctrl-C of the run (SIGINT) still stops the run."""

import os
import signal
import threading

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import RunInterruptedError, SignalInterrupt, exit_exception_in
from penaltyrun.runner import interrupts


def test_who_raised_it():
    assert interrupts.raised_by_job(SystemExit(3))
    assert not interrupts.raised_by_job(SignalInterrupt(signal.SIGTERM))
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        assert not interrupts.raised_by_job(KeyboardInterrupt())  # could be a Ctrl-C
        with interrupts.sigint_marked():
            assert interrupts.raised_by_job(KeyboardInterrupt())  # a Ctrl-C is marked
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    seen = []
    thread = threading.Thread(target=lambda: seen.append(
        interrupts.raised_by_job(KeyboardInterrupt())))
    thread.start()
    thread.join()
    assert seen == [True]  # signals reach the main thread only


@pytest.mark.skipif(signal.getsignal(signal.SIGINT) is not signal.default_int_handler,
                    reason="SIGINT has a handler of the test runner's own")
def test_a_ctrl_c_inside_the_block_is_marked():
    with pytest.raises(SignalInterrupt) as info, interrupts.sigint_marked():
        os.kill(os.getpid(), signal.SIGINT)
    assert info.value.signum == signal.SIGINT and not interrupts.raised_by_job(info.value)


def test_one_line_texts():
    assert interrupts.describe_exit_exception(SystemExit(3)).startswith(
        "SystemExit: the job's code called sys.exit(3)")
    text = interrupts.describe_exit_exception(KeyboardInterrupt())
    assert text.startswith("KeyboardInterrupt: raised by the job's code") and "\n" not in text


@pytest.mark.parametrize("exc", [KeyboardInterrupt, SystemExit])
def test_in_process_jobs_record_the_job_s_own_interrupt(tmp_path, exc, caplog):
    """workers=1: the jobs run in this process; the first one raises, the second runs."""
    calls = []

    def cost(K):
        calls.append(1)
        if len(calls) == 1:
            raise exc
        return float(np.trace(K))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="raises")
    res = penaltyrun.tune(prob, n_starts=2, optimizer="baseline", workers=1,
                          run_dir=tmp_path)
    df = res.records.sort_values("start")
    assert list(df["status"]) == ["failed", "ok"]
    assert df["error"].iloc[0].startswith(exc.__name__) and "\n" not in df["error"].iloc[0]
    lines = [r for r in caplog.records if df["job_id"].iloc[0] in r.getMessage()]
    assert len(lines) == 1


def test_a_ctrl_c_during_an_in_process_job_still_stops_the_run(tmp_path):
    def cost(K):
        os.kill(os.getpid(), signal.SIGINT)  # as a terminal's Ctrl-C
        return float(np.trace(K))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="ctrlc")
    with pytest.raises(RunInterruptedError) as info:
        penaltyrun.tune(prob, n_starts=2, optimizer="baseline", workers=1, run_dir=tmp_path)
    assert info.value.signum == signal.SIGINT
    assert not list((tmp_path / "jobs").glob("*.json"))


def _wrapped(inner: BaseException) -> SystemError:
    """What compiled code that held the interpreter when a signal came gives back: a
    SystemError whose cause is the signal's exception."""
    try:
        try:
            raise inner
        except BaseException as exc:
            raise SystemError("CPUDispatcher(<function kernel>) returned a result with an "
                              "exception set") from exc
    except SystemError as outer:
        return outer


def test_a_signal_wrapped_by_compiled_code_is_found_and_raised_on():
    sig = SignalInterrupt(signal.SIGTERM)
    outer = _wrapped(sig)
    assert exit_exception_in(outer) is sig
    with pytest.raises(SignalInterrupt):
        interrupts.reraise_run_signal(outer)
    # the job's own sys.exit, wrapped: the job's failure, not the run's signal
    interrupts.reraise_run_signal(_wrapped(SystemExit(3)))
    assert exit_exception_in(ValueError("plain")) is None


def test_a_ctrl_c_wrapped_by_compiled_code_stops_the_run_and_records_nothing(tmp_path):
    """A Ctrl-C that reaches the run inside a compiled kernel comes back as a SystemError
    (numba's dispatcher): the run stops as for any Ctrl-C; the job is not recorded."""
    def cost(K):
        raise _wrapped(SignalInterrupt(signal.SIGINT))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="wrapped")
    with pytest.raises(RunInterruptedError) as info:
        penaltyrun.tune(prob, n_starts=2, optimizer="baseline", workers=1, run_dir=tmp_path)
    assert info.value.signum == signal.SIGINT
    assert not list((tmp_path / "jobs").glob("*.json"))


def test_a_run_stopped_part_way_leaves_no_earlier_results_file(tmp_path):
    """A finished run of 2 starts, then the same cell with 4 starts resumed and stopped:
    the earlier results.parquet is gone (a results file means the folder's last run
    finished), the finished records stay, and the resume completes the 4 rows."""
    calls = {"n": 0, "stop": False}

    def cost(K):
        if calls["stop"]:
            raise SignalInterrupt(signal.SIGTERM)
        calls["n"] += 1
        return float(np.trace(K))

    prob = penaltyrun.from_cost(cost, {"K": (2, (0.1, 10.0))}, name="stale")
    penaltyrun.tune(prob, n_starts=2, optimizer="baseline", workers=1, run_dir=tmp_path,
                    seed=3)
    assert (tmp_path / "results.parquet").is_file()
    calls["stop"] = True
    with pytest.raises(RunInterruptedError):
        penaltyrun.tune(prob, n_starts=4, optimizer="baseline", workers=1,
                        run_dir=tmp_path, seed=3, resume=True)
    assert not (tmp_path / "results.parquet").exists()
    assert len(list((tmp_path / "jobs").glob("*.json"))) == 2
    calls["stop"] = False
    res = penaltyrun.tune(prob, n_starts=4, optimizer="baseline", workers=1,
                          run_dir=tmp_path, seed=3, resume=True)
    assert len(res.records) == 4
