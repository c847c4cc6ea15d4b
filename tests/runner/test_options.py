"""runner.* option checks, the scheduler address and reachability."""

import socket

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.runner.options import (
    check_runner_options,
    check_scheduler,
    parse_address,
    workers_argument,
)

GOOD = {"n_starts": 2, "seed": 0, "workers": 1, "backend": "local", "scheduler": None,
        "resume": False, "retry_failed": False, "report": True, "holdout": True,
        "max_retries": 1, "worker_timeout": 60, "warm_start": False, "warm_start_share": 0.3,
        "evaluate_on": "local", "chunks": "auto",
        "cutoff": True}


def test_shipped_defaults_pass():
    check_runner_options(GOOD)


@pytest.mark.parametrize(("key", "value", "fragment"), [
    ("seed", "abc", "non-negative integer"), ("seed", -1, "non-negative"),
    ("seed", 1.5, "integer"), ("n_starts", 0, "positive"), ("workers", True, "positive"),
    ("backend", "slurm", "allowed: local, dask"), ("resume", "yes", "true or false"),
    ("max_retries", -1, "non-negative"), ("worker_timeout", 0, "positive number"),
    ("worker_timeout", float("inf"), "positive number"), ("scheduler", "nope", "tcp://"),
    ("warm_start", 1, "true or false"), ("warm_start_share", 1.0, "(0, 1)"),
    ("evaluate_on", "gpu", "allowed: local, dask"), ("evaluate_on", None, "local or dask"),
    ("chunks", 0, "auto or a positive integer"), ("chunks", "4", "positive integer"),
    ("chunks", True, "positive integer"), ("chunks", 2.0, "positive integer"),
    ("cutoff", "yes", "true or false"),
])
def test_bad_values_name_the_key(key, value, fragment):
    with pytest.raises(ConfigError, match=f"runner.{key}") as err:
        check_runner_options({**GOOD, key: value})
    assert fragment in str(err.value)


def test_unknown_option_and_scheduler_without_dask():
    with pytest.raises(ConfigError, match="runner.fast: unknown runner option"):
        check_runner_options({**GOOD, "fast": True})
    with pytest.raises(ConfigError, match="backend=dask"):
        check_runner_options({**GOOD, "scheduler": "tcp://127.0.0.1:8786"})


def test_swarm_level_needs_the_dask_backend():
    with pytest.raises(ConfigError, match="runner.evaluate_on: dask needs runner.backend=dask"):
        check_runner_options({**GOOD, "evaluate_on": "dask"})
    check_runner_options({**GOOD, "evaluate_on": "dask", "backend": "dask", "chunks": 3})


@pytest.mark.parametrize(("text", "expected"), [("auto", "auto"), ("1", 1), ("12", 12)])
def test_workers_argument_accepts_auto_and_positive_integers(text, expected):
    assert workers_argument(text) == expected


@pytest.mark.parametrize("text", ["0", "-2", "two", "1.5", ""])
def test_workers_argument_refuses_the_rest_naming_the_option(text):
    with pytest.raises(ConfigError, match=r"^--jobs: must be a positive integer or auto"):
        workers_argument(text, option="--jobs")


def test_addresses():
    assert parse_address("tcp://127.0.0.1:8786") == ("127.0.0.1", 8786)
    assert parse_address("host-1.example:99") == ("host-1.example", 99)
    assert parse_address("tls://[::1]:8786") == ("::1", 8786)
    for bad in ("notanaddress", "tcp://h:0", "tcp://h:70000", "ucx://h:1", "h:1:2", 3):
        with pytest.raises(ConfigError, match="runner.scheduler"):
            parse_address(bad)


def test_reachability():
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen()
        check_scheduler(f"tcp://127.0.0.1:{srv.getsockname()[1]}")
        port = srv.getsockname()[1]
    with pytest.raises(ConfigError, match="cannot reach a scheduler"):
        check_scheduler(f"tcp://127.0.0.1:{port}", timeout_s=2)
    with pytest.raises(ConfigError, match="cannot reach"):
        check_runner_options({**GOOD, "backend": "dask", "scheduler": f"127.0.0.1:{port}"})
