"""The report's case sections in worker processes.

A report spends almost all its time in its case sections: figures (matplotlib), the
reference integrations that draw the best starts, basin maps and the cliff probe. The
sections of different problem cases share nothing but read-only tables, so they can be
written side by side: :func:`ordered_map` hands bundles of them to a pool of worker
processes and gives their results back in the order of the bundles, so the report is the
same file for file whatever the number of workers.

Workers are started from a fresh interpreter (``forkserver`` where the platform has it,
else ``spawn``), never forked from the report's own process: that process holds the
thread pools of the Parquet reader and of BLAS, which a fork would copy in an undefined
state. Each worker receives the settings that decide what reading results may import
(:func:`penaltyrun.problems.trust.snapshot`), so a worker imports exactly what the report
itself would. A worker that dies (a signal, memory) costs nothing but time: its bundles
are written again in the report's own process.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

logger = logging.getLogger(__name__)

#: Bundles submitted ahead of the ones being worked on, per worker: enough to keep every
#: worker busy, few enough that the rows waiting to be sent stay a small part of the results.
AHEAD_PER_WORKER = 2
#: Modules a worker imports once in the fork server (each worker starts with them).
PRELOAD = ("penaltyrun.report.cases",)


def pool_context() -> multiprocessing.context.BaseContext:
    """``forkserver`` where available (POSIX), else ``spawn``: never a plain fork."""
    methods = multiprocessing.get_all_start_methods()
    if "forkserver" in methods:
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(list(PRELOAD))
        return context
    return multiprocessing.get_context("spawn")


def ordered_map(work: Callable[[Any], Any], bundles: Iterable[tuple[Any, Any]], workers: int,
                initializer: Callable[..., None], initargs: tuple,
                local: Callable[[Any], Any], done: Callable[[Any], None] | None = None
                ) -> Iterator[Any]:
    """``work(bundle)`` of each ``(label, bundle)`` in ``bundles``, in their order.

    Parameters
    ----------
    work : callable
        A module-level function (pickled by name) run in a worker.
    bundles : iterable of (object, object)
        What to work on, each with a label for progress; read lazily, at most
        ``AHEAD_PER_WORKER · workers`` bundles ahead of the first unfinished one.
    workers : int
        Worker processes (≥ 2; the caller runs a single worker in its own process).
    initializer, initargs
        Run once in each worker before its first bundle.
    local : callable
        ``work`` as this process runs it, for a bundle whose worker died.
    done : callable, optional
        Called with a bundle's label when it is finished (progress).

    Yields
    ------
    object
        ``work(bundle)`` for each bundle in order (``local(bundle)`` for a bundle whose
        worker died).
    """
    pending: dict[int, tuple[Any, Any, Future | None]] = {}
    finished: dict[int, Any] = {}
    source = enumerate(bundles)
    next_out = 0
    exhausted = False
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=pool_context(),
                               initializer=_start_in, initargs=(os.getcwd(), initializer,
                                                                initargs))
    empty = tempfile.mkdtemp(prefix="penaltyrun-workers-")  # lives as long as the pool
    finished_all = False
    try:
        with _clean_start(empty):  # every worker starts here, with a task doing nothing
            for _ in range(workers):
                _submit(pool, _ready, None)
        while True:
            while not exhausted and len(pending) < AHEAD_PER_WORKER * workers:
                item = next(source, None)
                if item is None:
                    exhausted = True
                    break
                index, (label, bundle) = item
                pending[index] = (label, bundle, _submit(pool, work, bundle))
            if not pending:
                break
            wait([f for _, _, f in pending.values() if f is not None],
                 return_when=FIRST_COMPLETED)
            for index in sorted(pending):
                label, bundle, future = pending[index]
                if future is not None and not future.done():
                    continue
                del pending[index]
                finished[index] = _result(local, label, bundle, future)
                if done is not None:
                    done(label)
            while next_out in finished:
                yield finished.pop(next_out)
                next_out += 1
        finished_all = True
    finally:
        if not finished_all:  # an error, Ctrl-C, SIGTERM: the bundles in flight are dropped
            _terminate(pool)
        pool.shutdown(wait=True, cancel_futures=True)
        shutil.rmtree(empty, ignore_errors=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop the pool's workers now, in the middle of their bundles (a stopped report
    writes nothing; waiting for them could take minutes)."""
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    for process in list(getattr(pool, "_processes", {}).values()):
        process.terminate()


@contextlib.contextmanager
def _clean_start(empty: str) -> Iterator[None]:
    """Start worker processes (and the fork server) that find nothing in the working
    directory: with ``PYTHONSAFEPATH`` set (``python -c``, which starts the fork server,
    would put that directory first on ``sys.path``: a ``pandas.py`` in a received folder
    reported from inside it ran) and from the empty directory ``empty`` (kept while the
    pool lives: a process starts in its parent's directory of the moment), where their
    first imports read no ``.numba_config.yaml`` or ``matplotlibrc``
    (:func:`penaltyrun.safepath.ignore_folder_config`). :func:`_start_in` takes each worker
    to the report's working directory."""
    here, before = os.getcwd(), os.environ.get("PYTHONSAFEPATH")
    os.environ["PYTHONSAFEPATH"] = "1"
    os.chdir(empty)
    try:
        yield
    finally:
        os.chdir(here)
        if before is None:
            os.environ.pop("PYTHONSAFEPATH", None)
        else:
            os.environ["PYTHONSAFEPATH"] = before


def _ready(_: Any) -> None:
    """A task that does nothing: submitted once per worker so that every worker process
    starts inside :func:`_clean_start`."""


def _start_in(cwd: str, initializer: Callable[..., None], initargs: tuple) -> None:
    """A worker's start: numba and matplotlib imported blind to folder configuration, then
    the report's working directory (relative paths mean the same in every process), then
    ``initializer(*initargs)``."""
    from penaltyrun.safepath import ignore_folder_config

    ignore_folder_config()
    os.chdir(cwd)
    initializer(*initargs)


def _submit(pool: ProcessPoolExecutor, work: Callable[[Any], Any], bundle: Any
            ) -> Future | None:
    """The future of ``work(bundle)`` in the pool, None when the pool is broken."""
    try:
        return pool.submit(work, bundle)
    except BrokenProcessPool:
        return None


def _result(local: Callable[[Any], Any], label: Any, bundle: Any, future: Future | None
            ) -> Any:
    """A finished bundle's result; ``local(bundle)`` when its worker died."""
    if future is not None:
        try:
            return future.result()
        except BrokenProcessPool:
            pass
    logger.warning("a report worker died; %s is written in the report's own process", label)
    return local(bundle)


__all__ = ["AHEAD_PER_WORKER", "PRELOAD", "ordered_map", "pool_context"]
