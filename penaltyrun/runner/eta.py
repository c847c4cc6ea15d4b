"""Time left in a run, from the jobs finished so far and the workers running the rest.

The runner dispatches its jobs to ``slots`` workers, each taking the next queued job as soon
as it falls free (:func:`penaltyrun.runner.execute`). Dividing the elapsed time by the jobs
done (``elapsed / i · (n − i)``) ignores that: with 2 workers the first job to finish has
had a twin running beside it, and the estimate is about twice the truth. :class:`DispatchEta`
replays the dispatch instead: it keeps the start time of each job in flight (the run's
start for the first ``slots`` jobs, then the time the job before it on that worker
finished) and expects every job to take the mean duration of the finished ones: of those
that were not a worker's first once there are as many of them as workers (a worker's first
job also loads the compiled kernels), and counting a job in flight for longer than that
mean as lasting at least its age (the first jobs to finish are the short ones). It then
schedules what is left: the jobs in flight end when their expected duration is used up,
the queued jobs go to the first worker that falls free. Without a known number of workers
(a remote dask cluster) it falls back to the elapsed-time rate.
"""

from __future__ import annotations

import heapq
import math


class DispatchEta:
    """Estimated time left in a run of ``n_jobs`` jobs on ``slots`` workers.

    Parameters
    ----------
    n_jobs : int
        Jobs of the run (those still to run when it starts).
    slots : int or None
        Jobs that run at once (worker processes; 1: in turn). ``None``: unknown, the
        estimate is the elapsed time per finished job times the jobs left.
    """

    def __init__(self, n_jobs: int, slots: int | None) -> None:
        self.n_jobs = int(n_jobs)
        self.slots = None if slots is None else max(1, min(int(slots), max(1, self.n_jobs)))
        self.done = 0
        self.durations: list[float] = []
        self.later: list[float] = []  # durations of jobs that were not a worker's first
        self.running = [0.0] * (self.slots or 0)  # start times of the jobs in flight (s)
        self.firsts = [True] * len(self.running)  # whether each is its worker's first job
        self.started = len(self.running)

    def finished(self, t: float, duration: float | None = None) -> float:
        """Count one finished job and return the estimated time left (s).

        Parameters
        ----------
        t : float
            Seconds since the run started, when the job finished.
        duration : float, optional
            The job's own run time (s; the record's ``wall_time_s``). Without it the job
            is taken to have run since the earliest start in flight.
        """
        self.done += 1
        known = duration is not None and math.isfinite(duration) and duration >= 0
        if known:
            self.durations.append(float(duration))
        if self.slots is None:
            return t / self.done * max(0, self.n_jobs - self.done)
        if self.running:
            began = t - float(duration) if known else min(self.running)
            k = min(range(len(self.running)), key=lambda k: abs(self.running[k] - began))
            self.running.pop(k)
            if not self.firsts.pop(k) and known:
                self.later.append(float(duration))
        if self.started < self.n_jobs:  # the freed worker takes the next queued job
            self.running.append(t)
            self.firsts.append(False)
            self.started += 1
        return self.left(t)

    def left(self, t: float) -> float:
        """Estimated time left at ``t`` (s since the run started): the jobs in flight
        finish at their expected duration, the queued ones on the first free worker."""
        if self.done >= self.n_jobs:
            return 0.0
        seen = self.later if len(self.later) >= self.slots else self.durations
        mean = sum(seen) / len(seen) if seen else t / max(1, self.done)
        ages = [t - began for began in self.running]
        longer = [age for age in ages if age > mean]
        if seen and longer:
            mean = (sum(seen) + sum(longer)) / (len(seen) + len(longer))
        ends = [max(0.0, mean - age) for age in ages]
        free = ends + [0.0] * (self.slots - len(ends))  # a worker idle: nothing queued
        heapq.heapify(free)
        for _ in range(self.n_jobs - self.started):
            end = heapq.heappop(free) + mean
            ends.append(end)
            heapq.heappush(free, end)
        return max(ends, default=0.0)
