"""The test-suite guard: a process forked from pytest never runs tests of its own."""

import importlib.util
import os
import tempfile
import types
from pathlib import Path

# tests/conftest.py by its path: several conftest modules share the name "conftest"
_SPEC = importlib.util.spec_from_file_location("penaltyrun_tests_conftest",
                                               Path(__file__).with_name("conftest.py"))
conftest = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(conftest)


def test_a_forked_child_reaching_the_test_loop_exits_and_leaves_a_note():
    item = types.SimpleNamespace(nodeid="tests/x.py::test_y")
    assert conftest.pytest_runtest_protocol(item, None) is None  # pytest itself: runs on
    pid = os.fork()
    if pid == 0:  # the child, as if it had come back into pytest's loop
        conftest.pytest_runtest_protocol(item, None)
        os._exit(0)  # not reached when the guard works
    _, status = os.waitpid(pid, 0)
    note = Path(tempfile.gettempdir()) / f"penaltyrun-escaped-child-{pid}.txt"
    try:
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 70
        assert note.read_text() == f"forked from {os.getpid()}; reached tests/x.py::test_y\n"
    finally:
        note.unlink(missing_ok=True)


def test_a_forked_child_returning_into_its_test_exits_before_the_report():
    item = types.SimpleNamespace(nodeid="tests/x.py::test_z")
    call = types.SimpleNamespace(when="call", excinfo=None)
    pid = os.fork()
    if pid == 0:
        conftest.pytest_runtest_makereport(item, call)
        os._exit(0)  # not reached when the guard works
    _, status = os.waitpid(pid, 0)
    note = Path(tempfile.gettempdir()) / f"penaltyrun-escaped-child-{pid}.txt"
    try:
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 70
        assert note.read_text() == (f"forked from {os.getpid()}; returned into "
                                    "tests/x.py::test_z (call)\n")
    finally:
        note.unlink(missing_ok=True)
