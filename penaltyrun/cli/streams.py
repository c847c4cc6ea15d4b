"""The process's streams: UTF-8 whatever the locale, and a stdout that cannot be written
(``/dev/full``, a closed pipe) as one line on stderr and exit code :data:`EXIT_ENVIRONMENT`
instead of a traceback at interpreter shutdown; help and version text piped into a reader
that stops early (``| head``) end quietly (:func:`print_for_reader`). Used by
:mod:`penaltyrun.cli`.
"""

from __future__ import annotations

import sys
from typing import Any

from penaltyrun.errors import EXIT_ENVIRONMENT


def print_error(line: str) -> None:
    """``penaltyrun: error: <line>`` on stderr, even when stdout is broken."""
    try:
        print(f"penaltyrun: error: {line}", file=sys.stderr, flush=True)
    except OSError:
        pass


def ensure_utf8_mode(argv: list[str]) -> None:
    """Run in Python's UTF-8 mode whatever the locale: under a non-UTF-8 locale (e.g.
    ``LC_ALL=C PYTHONUTF8=0``) re-execute the interpreter with ``-X utf8``, so every text
    file, log line and printed line is UTF-8 instead of failing on a non-ASCII character."""
    import locale
    import os

    if sys.flags.utf8_mode or locale.getpreferredencoding(False).lower().replace("-", "") \
            == "utf8" or os.environ.get("PENALTYRUN_NO_REEXEC"):
        return
    os.environ["PENALTYRUN_NO_REEXEC"] = "1"  # never loop
    os.environ["PYTHONUTF8"] = "1"
    os.execv(sys.executable, [sys.executable, "-X", "utf8", *sys.orig_argv[1:]]
             if hasattr(sys, "orig_argv") else [sys.executable, "-X", "utf8", *argv])


class WatchedStream:
    """A text stream that remembers the OSError of its last failed write or flush (so that
    a failure to print is told apart from other file errors)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.error: OSError | None = None

    def write(self, text: str) -> int:
        try:
            return self._inner.write(text)
        except OSError as exc:
            self.error = exc
            raise

    def flush(self) -> None:
        try:
            self._inner.flush()
        except OSError as exc:
            self.error = exc
            raise

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


def watch_stdout() -> None:
    """Wrap ``sys.stdout`` in a :class:`WatchedStream` (once)."""
    if not isinstance(sys.stdout, WatchedStream) and sys.stdout is not None:
        sys.stdout = WatchedStream(sys.stdout)


def stdout_broken() -> OSError | None:
    """The error of writing stdout, or None if it can be written. A broken stdout
    (``/dev/full``, a closed pipe) is replaced by ``/dev/null`` at the file-descriptor
    level, so that no later flush (at interpreter shutdown) fails again."""
    import os

    try:
        sys.stdout.flush()
        error = getattr(sys.stdout, "error", None)
        if error is not None:
            raise error
    except OSError as exc:
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, sys.stdout.fileno())
            os.close(null)
        except (OSError, ValueError):
            pass
        return exc
    except ValueError:  # stdout closed by the caller
        return None
    return None


def stdout_error_line(exc: OSError) -> str:
    """The one line of a stdout that cannot be written."""
    return f"cannot write standard output: {exc.strerror or exc}"


def print_for_reader(text: str) -> None:
    """Print ``text`` (help, version) on stdout. A reader that stopped reading early
    (``penaltyrun --help | head``) has what it wanted: the process ends quietly with exit
    code 0; any other failure to write is :func:`flush_stdout`'s one line."""
    try:
        print(text)
    except BrokenPipeError:
        pass
    end_if_pipe_closed()
    flush_stdout()


def end_if_pipe_closed() -> None:
    """Exit quietly (code 0) if stdout is a pipe its reader has closed; stdout then goes to
    ``/dev/null``, so nothing fails again at interpreter shutdown."""
    if isinstance(stdout_broken(), BrokenPipeError):
        sys.exit(0)


def flush_stdout() -> None:
    """Flush stdout; a stdout that cannot be written (``/dev/full``, a closed pipe) is one
    line on stderr and exit code 5, not a traceback at interpreter shutdown."""
    exc = stdout_broken()
    if exc is not None:
        print_error(stdout_error_line(exc))
        sys.exit(EXIT_ENVIRONMENT)
