"""Property: whatever the overrides, the command line never ends in a traceback; it either
accepts them (exit 0) or names the problem in one line (exit 2)."""

import math
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from penaltyrun import cli
from penaltyrun.cli.app import guard
from penaltyrun.cli.preflight import preflight

KEYS = ["mode", "case", "problem", "param", "optimizer", "+experiment", "runner.seed",
        "runner.n_starts", "runner.workers", "runner.backend", "runner.resume",
        "runner.retry_failed", "runner.max_retries", "runner.worker_timeout", "runner.report",
        "report.paper", "report.input", "optimizer.w", "optimizer.iters",
        "optimizer.n_particles", "optimizer.vh_strategy", "optimizer.bh_strategy",
        "param.eig_bounds", "param.cayley_bound", "problem.params.x0", "problem.params.t_max",
        "matrices.K", "+foo", "+runner.bar", "+problem.params.speed", "~runner.seed"]
CHOICES = ["pso", "de", "baseline", "zermelo", "qlaw", "attitude_lqr", "full", "diagonal",
           "A", "detumble", "default", "report", "evaluate", "dask", "local", "nearest",
           "zermelo_paper", "unmodified"]


def _render(value):
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") \
            if math.isinf(value) else repr(value)
    if isinstance(value, list):
        return "[" + ",".join(_render(v) for v in value) + "]"
    return str(value)


scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6),
                    st.floats(allow_nan=True, allow_infinity=True, width=32),
                    st.sampled_from(CHOICES),
                    st.text(alphabet="ab1.-_,[]{}'\"=:$ /\\", max_size=8))
values = st.one_of(scalars, st.lists(st.one_of(st.integers(-5, 5), st.floats(-5, 5)),
                                     max_size=3))
overrides = st.lists(st.tuples(st.sampled_from(KEYS), values.map(_render)), max_size=4,
                     unique_by=lambda kv: kv[0])


def _argv(pairs):
    return [f"{k}" if k.startswith("~") and v == "null" else f"{k}={v}" for k, v in pairs]


@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
@given(pairs=overrides)
def test_preflight_accepts_or_gives_one_line(pairs, tmp_path_factory, capsys,
                                            monkeypatch):
    monkeypatch.chdir(tmp_path_factory.mktemp("cwd"))
    argv = _argv(pairs)
    try:
        guard(lambda: preflight(argv))
    except SystemExit as exc:
        assert exc.code == cli.EXIT_USAGE, argv
        err = capsys.readouterr().err
        assert err.startswith("penaltyrun: error: ") and len(err.strip().splitlines()) == 1
        assert "Traceback" not in err


@pytest.mark.parametrize("dummy", [0])
@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(pairs=overrides)
def test_command_line_exit_code_is_0_or_2(pairs, dummy, tmp_path_factory):
    """The real command (``--cfg job``: check, print the config, start nothing)."""
    cwd = tmp_path_factory.mktemp("cwd")
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "--cfg", "job",
                           *_argv(pairs)], cwd=cwd, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode in (0, 2), proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    if proc.returncode == 2:
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
