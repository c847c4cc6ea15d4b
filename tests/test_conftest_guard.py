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


def in_forked_child(hook) -> tuple[int, str]:
    """Run ``hook()`` in a child forked from pytest, as if it had come back into pytest's
    loop; return the child's exit status and the note it left (removed afterwards)."""
    pid = os.fork()
    if pid == 0:
        hook()
        os._exit(0)  # not reached when the guard works
    _, status = os.waitpid(pid, 0)
    note = Path(tempfile.gettempdir()) / f"penaltyrun-escaped-child-{pid}.txt"
    try:
        return (os.WEXITSTATUS(status) if os.WIFEXITED(status) else -1), note.read_text()
    finally:
        note.unlink(missing_ok=True)


def test_a_forked_child_reaching_the_test_loop_exits_and_leaves_a_note():
    item = types.SimpleNamespace(nodeid="tests/x.py::test_y")
    assert conftest.pytest_runtest_protocol(item, None) is None  # pytest itself: runs on
    status, note = in_forked_child(lambda: conftest.pytest_runtest_protocol(item, None))
    assert status == 70
    assert note == f"forked from {os.getpid()}; reached tests/x.py::test_y\n"


def test_a_forked_child_returning_into_its_test_exits_before_the_report():
    item = types.SimpleNamespace(nodeid="tests/x.py::test_z")
    call = types.SimpleNamespace(when="call", excinfo=None)
    status, note = in_forked_child(lambda: conftest.pytest_runtest_makereport(item, call))
    assert status == 70
    assert note == f"forked from {os.getpid()}; returned into tests/x.py::test_z (call)\n"
