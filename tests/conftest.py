"""Shared test settings: hypothesis profiles.

* ``dev`` (the default on a workstation): random examples, a new draw every run (pass
  ``--hypothesis-seed=N`` to pytest to replay one), no deadlines (numba compiles once);
* ``ci`` (selected when the environment variable ``CI`` is ``true``, as CI services and
  ``.ci/run`` set it): the same with ``derandomize=True``, so a CI run draws the same
  examples every time and its result does not depend on luck, and no example database.

``HYPOTHESIS_PROFILE=dev|ci`` chooses a profile explicitly.

And one guard: only the pytest process itself runs tests. A process forked from it that
came back into pytest's loop instead of exiting would run tests of its own and write their
progress into pytest's output (a stray "F" and dots in a progress line, with a summary that
says nothing failed). :func:`pytest_runtest_makereport` and :func:`pytest_runtest_protocol`
end such a process at once and silently, before it reports the test it was forked in or
runs another, and leave where it got to, with the exception, in
``<tmp>/penaltyrun-escaped-child-<pid>.txt``. The one such escape seen (a pool worker
terminated an instant after its fork ran the command line's SIGTERM handler, left installed
by an in-process CLI test, and raised before multiprocessing could end it) is prevented in
the pool itself (``tests/runner/test_pool_fork_signals.py``); the guard stays as a net,
and every test gets the session's signal handlers back when it ends.

Every test gets its own empty report cache (``PENALTYRUN_CACHE_DIR``): a report drawn by
one test is never copied into another's, and no test writes into the user's cache.
"""

import os
import signal
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

#: The pytest process; any other process reaching the test loop was forked from it.
SESSION_PID = os.getpid()

# A shell starts a background job (``make test &``, ``nohup``) with SIGINT ignored, and the
# runner then cannot be stopped by Ctrl-C: the tests of Ctrl-C handling would see no
# interrupt. They test the runner as a terminal runs it, with Python's own SIGINT handler.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

settings.register_profile(
    "dev", deadline=None, max_examples=50, suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "ci", parent=settings.get_profile("dev"), derandomize=True, database=None,
    print_blob=True,
)
_in_ci = os.environ.get("CI", "").strip().lower() in ("true", "1", "yes")
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if _in_ci else "dev"))


def _end_escaped_child(what: str) -> None:
    """In a process forked from pytest: leave the note and exit at once (70)."""
    note = Path(tempfile.gettempdir()) / f"penaltyrun-escaped-child-{os.getpid()}.txt"
    try:
        with note.open("a") as out:
            out.write(f"forked from {SESSION_PID}; {what}\n")
    finally:
        os._exit(70)


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_makereport(item, call):
    """End a forked child that returned into the test it was forked in, before pytest
    reports that test from it; the note names the test, the phase and the exception."""
    if os.getpid() != SESSION_PID:
        exc = "" if call.excinfo is None else f": {call.excinfo.exconly()[:2000]}"
        _end_escaped_child(f"returned into {item.nodeid} ({call.when}){exc}")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    """End a forked child that came back into the test loop, before it runs a test."""
    if os.getpid() != SESSION_PID:
        _end_escaped_child(f"reached {item.nodeid}")
    return None


#: Signals whose handlers a test may install in the pytest process (the command line run
#: in-process sets its SIGTERM / SIGHUP handlers).
_RESTORED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                          if hasattr(signal, name))


@pytest.fixture(autouse=True)
def _restore_signal_handlers():
    """Give every test the signal handlers the session started with: a handler installed
    by one test (``penaltyrun.cli`` run in-process) must not act in later tests."""
    saved = {signum: signal.getsignal(signum) for signum in _RESTORED_SIGNALS}
    yield
    for signum, handler in saved.items():
        if signal.getsignal(signum) is not handler and handler is not None:
            signal.signal(signum, handler)


@pytest.fixture(autouse=True)
def _own_report_cache(tmp_path_factory, monkeypatch):
    """An empty report cache folder for each test (and the processes it starts)."""
    monkeypatch.setenv("PENALTYRUN_CACHE_DIR", str(tmp_path_factory.mktemp("report-cache")))
