"""Checks of every ``runner.*`` option before a run starts (one clear error each)."""

from __future__ import annotations

import math
import os
import re
import socket
from collections.abc import Mapping
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.runner.plan import check_n_starts
from penaltyrun.typed import is_int, is_number

#: Most timed batches the forecast may run before a run (each one batch of candidates).
MAX_FORECAST_SAMPLES = 1000

#: runner option → (kind, description of the allowed values).
RUNNER_OPTIONS: dict[str, tuple[str, str]] = {
    "n_starts": ("pos_int", "a positive integer"),
    "seed": ("nonneg_int", "a non-negative integer"),
    "workers": ("workers", "a positive integer or auto (all cores)"),
    "backend": ("choice", "local or dask"),
    "scheduler": ("address", "null or a dask scheduler address tcp://host:port"),
    "resume": ("bool", "true or false"),
    "retry_failed": ("bool", "true or false"),
    "report": ("bool", "true or false"),
    "holdout": ("bool", "true or false"),
    "max_retries": ("nonneg_int", "a non-negative integer"),
    "worker_timeout": ("pos_float", "a positive number of seconds"),
    "stall_timeout": ("pos_float", "a positive number of seconds"),
    "job_timeout": ("opt_pos_float", "null (no limit) or a positive number of seconds"),
    "warm_start": ("bool", "true or false"),
    "warm_start_share": ("unit_open", "a number in (0, 1)"),
    "progress": ("progress", "auto, true or false"),
    "forecast_samples": ("forecast_samples", "an integer from 0 (no forecast) to "
                                             f"{MAX_FORECAST_SAMPLES}"),
    "evaluate_on": ("evaluate_on", "local or dask"),
    "chunks": ("chunks", "auto or a positive integer"),
    "cutoff": ("bool", "true or false"),
}
BACKENDS = ("local", "dask")
#: Where a job's candidates are evaluated: in the job's process, or as chunks on Dask workers.
EVALUATE_ON = ("local", "dask")
#: ``report.*`` option → the types it may have (the report a run writes at its end, and
#: ``mode=report``).
REPORT_OPTIONS: dict[str, tuple[type, ...]] = {"input": (str, type(None)),
                                               "output": (str, type(None)), "paper": (bool,)}
_ADDRESS = re.compile(r"^(?:(?P<proto>tcp|tls)://)?(?P<host>\[[0-9a-fA-F:.]+\]|[A-Za-z0-9_.-]+)"
                      r":(?P<port>\d{1,5})$")


_ALLOWED = {"choice": BACKENDS, "evaluate_on": EVALUATE_ON,
            "progress": ("auto", "true", "false")}


def check_value(key: str, kind: str, value: Any, what: str) -> None:
    """Check one option ``value`` of ``kind`` (pos_int, nonneg_int, bool, pos_float,
    opt_pos_float, unit_open, choice, evaluate_on, chunks, progress, address)."""
    ok = {
        "pos_int": lambda v: is_int(v) and v >= 1,
        "workers": lambda v: v == "auto" or (is_int(v) and v >= 1),
        "nonneg_int": lambda v: is_int(v) and v >= 0,
        "forecast_samples": lambda v: is_int(v) and 0 <= v <= MAX_FORECAST_SAMPLES,
        "bool": lambda v: isinstance(v, bool),
        "pos_float": lambda v: is_number(v) and math.isfinite(v) and v > 0,
        "opt_pos_float": lambda v: v is None or (is_number(v) and math.isfinite(v) and v > 0),
        "unit_open": lambda v: is_number(v) and 0 < v < 1,
        "choice": lambda v: v in BACKENDS,
        "evaluate_on": lambda v: v in EVALUATE_ON,
        "chunks": lambda v: v == "auto" or (is_int(v) and v >= 1),
        "progress": lambda v: v == "auto" or isinstance(v, bool),
        "address": lambda v: v is None or (isinstance(v, str) and bool(_ADDRESS.match(v))),
    }[kind](value)
    if not ok:
        raise ConfigError(f"runner.{key}", f"must be {what}, got {value!r}",
                          allowed=_ALLOWED.get(kind))


def available_cores() -> int:
    """Cores this process may run on (``sched_getaffinity``, else ``os.cpu_count``)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def resolve_workers(value: Any, key: str = "runner.workers") -> int:
    """A number of worker processes (``runner.workers``, or the setting ``key``):
    ``auto`` → :func:`available_cores`.

    Raises
    ------
    ConfigError
        Unless ``value`` is ``auto`` or an integer ≥ 1 (the error names ``key``).
    """
    if not (value == "auto" or (is_int(value) and value >= 1)):
        raise ConfigError(key, f"must be {RUNNER_OPTIONS['workers'][1]}, got {value!r}")
    return available_cores() if value == "auto" else int(value)


def workers_argument(text: str, option: str = "--workers") -> int | str:
    """A command-line worker count as given: ``auto`` or a positive integer.

    Raises
    ------
    ConfigError
        Unless ``text`` is ``auto`` or a positive integer (the error names ``option``).
    """
    if text == "auto":
        return text
    try:
        number = int(text)
    except ValueError:
        number = 0
    if number < 1:
        raise ConfigError(option, f"must be a positive integer or auto, got {text!r}")
    return number


def parse_address(address: str) -> tuple[str, int]:
    """(host, port) of a scheduler address ``[tcp://|tls://]host:port``.

    Raises
    ------
    ConfigError
        If the address is malformed or the port out of range.
    """
    match = _ADDRESS.match(address) if isinstance(address, str) else None
    if not match or not 0 < int(match["port"]) < 65536:
        raise ConfigError("runner.scheduler", f"not a scheduler address: {address!r} "
                          "(expected tcp://host:port, e.g. tcp://127.0.0.1:8786)")
    return match["host"].strip("[]"), int(match["port"])


def check_scheduler(address: str, timeout_s: float = 5.0) -> None:
    """Check that a dask scheduler listens at ``address`` (TCP connection within
    ``timeout_s`` seconds).

    Raises
    ------
    ConfigError
        Malformed address, unknown host, or nothing listening there.
    """
    host, port = parse_address(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        if isinstance(exc, TimeoutError):
            reason = f"no answer within {timeout_s:g} s"
        raise ConfigError("runner.scheduler", f"cannot reach a scheduler at {address}: "
                          f"{reason}; start one with `dask scheduler` or leave "
                          "runner.scheduler=null for a local cluster") from None


def check_job_timeout(job_timeout: Any, backend: Any) -> None:
    """``runner.job_timeout``: null or a positive number of seconds, with the local backend.

    Raises
    ------
    ConfigError
        A value out of range, or a limit with ``runner.backend=dask`` (a dask worker runs
        several jobs in threads of one process: one of them cannot be stopped alone).
    """
    if job_timeout is None:
        return
    check_value("job_timeout", RUNNER_OPTIONS["job_timeout"][0], job_timeout,
                RUNNER_OPTIONS["job_timeout"][1])
    if backend == "dask":
        raise ConfigError("runner.job_timeout", "is enforced by the local process pool only "
                          "(runner.backend=local); with dask leave it null")


def check_runner_options(options: Mapping[str, Any], connect: bool = True) -> None:
    """Check every ``runner.*`` option: known key, type and range, and (with ``connect``
    and the dask backend) that the scheduler can be reached.

    Raises
    ------
    ConfigError
        Naming the key and what it must be.
    """
    unknown = sorted(set(options) - set(RUNNER_OPTIONS))
    if unknown:
        raise ConfigError(f"runner.{unknown[0]}", "unknown runner option",
                          allowed=sorted(RUNNER_OPTIONS))
    for key, (kind, what) in RUNNER_OPTIONS.items():
        if key in options:
            check_value(key, kind, options[key], what)
    if "n_starts" in options:
        check_n_starts(options["n_starts"])
    if options.get("evaluate_on", "local") == "dask" and options.get("backend", "local") != "dask":
        raise ConfigError("runner.evaluate_on", "dask needs runner.backend=dask (a LocalCluster "
                          "of runner.workers processes, or runner.scheduler=tcp://host:port)")
    check_job_timeout(options.get("job_timeout"), options.get("backend", "local"))
    scheduler = options.get("scheduler")
    if scheduler is not None:
        if options.get("backend", "local") != "dask":
            raise ConfigError("runner.scheduler", "is used only with runner.backend=dask "
                              "(pass both, or drop runner.scheduler)")
        parse_address(scheduler)
        if connect:
            check_scheduler(scheduler)


def check_report_options(options: Mapping[str, Any]) -> None:
    """Check ``report.input``, ``report.output`` (path or null), ``report.paper`` (bool)."""
    for key, value in options.items():
        types = REPORT_OPTIONS.get(key)
        if types is None:
            raise ConfigError(f"report.{key}", "unknown report option",
                              allowed=sorted(REPORT_OPTIONS))
        if not isinstance(value, types) or (isinstance(value, str) and not value.strip()):
            what = "true or false" if types == (bool,) else "a path or null"
            raise ConfigError(f"report.{key}", f"must be {what}, got {value!r}")
