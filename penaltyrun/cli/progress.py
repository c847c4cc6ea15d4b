"""Progress bar over the jobs of a run (tqdm), on an interactive terminal only.

On a terminal the bar shows jobs done, elapsed time and ETA, and log lines are printed
above it (``tqdm.contrib.logging``); elsewhere (a log file, CI, a pipe) there is no bar and
the runner's per-job log lines (``[i/n] job: status (... ETA ...)``) are the progress. Given
the workers, the bar's ETA is the runner's (:class:`~penaltyrun.runner.eta.DispatchEta`),
not tqdm's rate, which takes the first job to finish of several running at once for the
pace of the whole run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, TextIO

from penaltyrun.errors import ConfigError

#: ``runner.progress`` values: auto (bar on a terminal), true (always), false (never).
PROGRESS_CHOICES = ("auto", "true", "false")


def wanted(setting: Any, stream: TextIO | None = None) -> bool:
    """Whether to draw the bar for ``runner.progress`` = ``setting``.

    Raises
    ------
    ConfigError
        If ``setting`` is not auto, true or false.
    """
    text = str(setting).lower()
    if text not in PROGRESS_CHOICES:
        raise ConfigError("runner.progress", f"unknown value {setting!r}",
                          allowed=PROGRESS_CHOICES)
    if text == "auto":
        stream = stream or sys.stderr
        return bool(getattr(stream, "isatty", lambda: False)())
    return text == "true"


def finished_before(jobs: Sequence[Any], run_dir: Path, resume: bool,
                    retry_failed: bool) -> int:
    """Jobs a resumed run will skip: their record is readable and not a failure to retry
    (an unreadable record is moved aside and its job run again by the runner)."""
    from penaltyrun.jobrecord import NO_RESULT_STATUSES
    from penaltyrun.runner.records import job_path, read_record

    if not resume:
        return 0
    done = 0
    for job in jobs:
        path = job_path(run_dir, job)
        record = read_record(path) if path.exists() else None
        if record is not None and not (retry_failed
                                       and record["status"] in NO_RESULT_STATUSES):
            done += 1
    return done


def slots(runner: Mapping[str, Any], n_todo: int) -> int | None:
    """Jobs the runner settings ``runner`` run at once (None: unknown, a remote cluster);
    see :func:`penaltyrun.runner.executor.dispatch_slots`."""
    from penaltyrun.runner.executor import dispatch_slots
    from penaltyrun.runner.options import resolve_workers

    return dispatch_slots(resolve_workers(runner.get("workers", 1)), n_todo,
                          runner.get("backend", "local"), runner.get("scheduler"),
                          runner.get("evaluate_on", "local"))


@contextmanager
def job_bar(total: int, initial: int = 0, enabled: bool = True, file: TextIO | None = None,
            workers: int | None = 0) -> Iterator[Callable[[dict[str, Any]], None] | None]:
    """A callback for :func:`penaltyrun.runner.execute`'s ``on_record`` that advances a
    tqdm bar (``None`` when ``enabled`` is false: plain log lines only).

    Parameters
    ----------
    total : int
        Jobs of the run.
    initial : int
        Jobs already finished (resume).
    enabled : bool
        Draw the bar (see :func:`wanted`).
    file : text stream, optional
        Where to draw it (default stderr).
    workers : int or None
        Jobs run at once (:func:`slots`): the bar's ETA is then the runner's; ``None``: a
        cluster of unknown size; 0: tqdm's own ETA.
    """
    if not enabled or total <= initial:
        yield None
        return
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    from penaltyrun.runner.eta import DispatchEta

    counts: dict[str, int] = {}
    eta = DispatchEta(total - initial, workers) if workers != 0 else None
    fmt = None if eta is None else "{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}{postfix}]"
    t0 = time.perf_counter()
    with tqdm(total=total, initial=initial, unit="job", desc="jobs", file=file,
              dynamic_ncols=True, smoothing=0.1, bar_format=fmt) as bar, \
            logging_redirect_tqdm():
        def on_record(record: dict[str, Any]) -> None:
            status = str(record.get("status"))
            counts[status] = counts.get(status, 0) + 1
            shown: dict[str, Any] = dict(counts)
            if eta is not None:
                left = eta.finished(time.perf_counter() - t0, record.get("wall_time_s"))
                shown["ETA"] = tqdm.format_interval(left)
            bar.set_postfix(shown, refresh=False)
            bar.update(1)

        yield on_record
