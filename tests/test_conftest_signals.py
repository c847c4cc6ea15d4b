"""The autouse fixture of tests/conftest.py gives each test the session's signal handlers.

The two tests run in file order: the first installs the command line's SIGTERM handler as
an in-process CLI run does, the second sees the handler the session started with."""

import signal

import pytest

from penaltyrun.cli import install_signal_handlers

_SESSION = {}


def test_a_test_may_install_the_command_line_handlers():
    _SESSION["sigterm"] = signal.getsignal(signal.SIGTERM)
    install_signal_handlers()
    assert signal.getsignal(signal.SIGTERM) is not _SESSION["sigterm"]


def test_the_next_test_has_the_session_handlers_again():
    if "sigterm" not in _SESSION:
        pytest.skip("checks what the test above left behind: run the whole file")
    assert signal.getsignal(signal.SIGTERM) is _SESSION["sigterm"]
