"""Exceptions shared by every layer (no dependencies)."""

from __future__ import annotations

from collections.abc import Iterable


class ConfigError(ValueError):
    """A user-facing configuration error naming the offending key.

    Parameters
    ----------
    key : str
        Dotted config key, e.g. ``"problem"`` or ``"optimizer.n_particles"``.
    message : str
        What is wrong with the value.
    allowed : iterable of str, optional
        The allowed values, listed in the message when given.
    """

    def __init__(self, key: str, message: str, allowed: Iterable[str] | None = None) -> None:
        self.key = key
        self.allowed = tuple(allowed) if allowed is not None else None
        text = f"{key}: {message}"
        if self.allowed:
            text += f" (allowed: {', '.join(self.allowed)})"
        super().__init__(text)


class SignalInterrupt(KeyboardInterrupt):
    """SIGTERM or SIGHUP received: handled exactly like Ctrl-C (SIGINT).

    Parameters
    ----------
    signum : int
        The signal number.
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        super().__init__(f"signal {signum}")


class RunInterruptedError(Exception):
    """A run stopped by the user (Ctrl-C / SIGINT, SIGTERM, SIGHUP); its finished jobs stay
    on disk.

    Parameters
    ----------
    run_dir : str
        Run directory holding ``jobs/<job_id>.json``.
    n_done, n_todo : int
        Jobs finished in this call and jobs this call had to run.
    signum : int, optional
        The signal that stopped the run (default SIGINT = 2).
    """

    def __init__(self, run_dir: str, n_done: int, n_todo: int, signum: int = 2) -> None:
        self.run_dir = run_dir
        self.n_done = n_done
        self.n_todo = n_todo
        self.signum = int(signum)
        how = "interrupted" if self.signum == 2 else f"stopped by {signal_name(self.signum)}"
        super().__init__(
            f"{how} after {n_done} of {n_todo} jobs; finished jobs are kept in "
            f"{run_dir}/jobs; rerun the same command with runner.resume=true to run the rest")


class RunAbortedError(Exception):
    """A run that cannot go on for a reason outside the jobs (e.g. every dask worker lost);
    its finished jobs stay on disk for ``runner.resume=true``."""


class ResultsUnreadableError(ValueError):
    """No readable results file was found where results were expected."""


def signal_name(signum: int) -> str:
    """``SIGTERM`` for 15 etc. (``signal N`` if unknown)."""
    import signal

    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"
