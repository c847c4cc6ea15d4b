"""Helpers shared by the subprocess tests of the command line (the ``test_reliability*``
files and the external dask cluster test): run ``python -m penaltyrun.cli`` or
``penaltyrun.report_cli`` in a child process, wait for and read its job records, and pick
out the one ``penaltyrun...`` error line a bad input must give."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import psutil

#: Jobs of a few seconds each (long enough to kill something mid-run): about 2.5 s of CPU
#: each on a quiet core (Zermelo's closed form costs about 8 µs an evaluation; the stall
#: rule is off so that every job spends its 300 000 evaluations).
SLOW_JOBS = ["problem=zermelo", "param=diagonal", "optimizer.n_particles=200",
             "optimizer.iters=1500", "optimizer.ftol=0.0", "runner.report=false"]
#: Jobs of well under a second each (one evaluation of K = I).
FAST_JOBS = ["problem=zermelo", "optimizer=baseline", "runner.report=false"]


def cli(*args: str, cwd: Path, timeout: float = 600, **kw) -> subprocess.CompletedProcess:
    """Run ``python -m penaltyrun.cli *args`` in ``cwd`` to the end (``timeout`` in seconds),
    capturing its output as text; ``kw`` goes to :func:`subprocess.run` (``env=`` ...)."""
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=timeout, **kw)


#: One interpreter imports the command line once, then runs each case of the JSON list on
#: its standard input (``{"args": [...], "cwd": "..."}``) in a child forked for it, exactly
#: as ``python -m penaltyrun.cli`` would run it after its imports: own standard streams
#: (files), own exit code; the list of results is its standard output.
_FORKED_CLI = textwrap.dedent("""
    import json, logging, os, sys, traceback
    import penaltyrun.cli as cli

    results = []
    for case in json.load(sys.stdin):
        streams = [os.path.join(case["cwd"], name) for name in (".cli-out", ".cli-err")]
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                os.chdir(case["cwd"])
                for fd, path in zip((1, 2), streams):
                    os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), fd)
                sys.argv = ["penaltyrun", *case["args"]]
                try:
                    cli.main()
                    code = 0
                except SystemExit as exc:
                    code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
                    if exc.code is not None and not isinstance(exc.code, int):
                        print(exc.code, file=sys.stderr)
                except BaseException:
                    traceback.print_exc()
            finally:
                try:
                    sys.stdout.flush()
                    sys.stderr.flush()
                    logging.shutdown()
                finally:
                    os._exit(code)
        _, status = os.waitpid(pid, 0)
        out, err = (open(path, encoding="utf-8").read() for path in streams)
        for path in streams:
            os.remove(path)
        results.append({"returncode": os.waitstatus_to_exitcode(status),
                        "stdout": out, "stderr": err})
    json.dump(results, sys.stdout)
""")


def cli_forked(cases: list[tuple[list[str], Path]], timeout: float = 600
               ) -> list[subprocess.CompletedProcess]:
    """Run ``penaltyrun *args`` in ``cwd`` for every ``(args, cwd)`` of ``cases``, each in a
    process of its own forked from one interpreter that imported the command line once
    (the imports are most of a short run's time: bad-input checks then cost milliseconds,
    not seconds each). Returns one completed process per case, in order."""
    payload = json.dumps([{"args": list(args), "cwd": str(cwd)} for args, cwd in cases])
    proc = subprocess.run([sys.executable, "-X", "utf8", "-c", _FORKED_CLI], input=payload,
                          capture_output=True, text=True, timeout=timeout, check=True)
    return [subprocess.CompletedProcess(["penaltyrun", *args], r["returncode"], r["stdout"],
                                        r["stderr"])
            for (args, _), r in zip(cases, json.loads(proc.stdout))]


def bad_command_lines(cases: list[tuple[list[str], list[str]]], tmp_path_factory
                      ) -> list[tuple[subprocess.CompletedProcess, Path]]:
    """Run every ``(args, fragments)`` of ``cases`` as ``penaltyrun runner.n_starts=1 *args``
    in a fresh working directory of its own (with :func:`cli_forked`, all at once); returns
    each run and its directory, in order."""
    cwds = [tmp_path_factory.mktemp("bad") for _ in cases]
    runs = cli_forked([(["runner.n_starts=1", *args, f"hydra.run.dir={cwd / 'run'}"], cwd)
                       for (args, _), cwd in zip(cases, cwds)])
    return list(zip(runs, cwds))


def _default_sigint() -> None:
    """In the child before ``exec``: SIGINT at its default action, as under a terminal."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def popen(*args: str, cwd: Path) -> subprocess.Popen:
    """Start ``python -m penaltyrun.cli *args`` in ``cwd`` in a session of its own (so that
    ``os.killpg`` reaches its workers), its output piped as text.

    SIGINT starts at its default action: a shell runs a background job with SIGINT
    ignored, a child inherits that, and Python then installs no Ctrl-C handler, so a suite
    started with ``make test &`` would otherwise send Ctrl-C to a run that ignores it."""
    return subprocess.Popen([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, preexec_fn=_default_sigint)


def report(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run ``python -m penaltyrun.report_cli *args`` to the end, capturing its output."""
    return subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", *args],
                          capture_output=True, text=True, timeout=timeout)


def wait_for_records(run: Path, n: int = 1, timeout: float = 600) -> None:
    """Wait until the run directory ``run`` holds ``n`` job records (``timeout`` seconds)."""
    deadline = time.monotonic() + timeout
    while len(list((run / "jobs").glob("*.json"))) < n:
        assert time.monotonic() < deadline, "no job record appeared"
        time.sleep(0.2)


def records(run: Path) -> list[dict]:
    """The job records of the run directory ``run``, in file name order."""
    return [json.loads(p.read_text()) for p in sorted((run / "jobs").glob("*.json"))]


def alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    """The single ``penaltyrun...`` line on ``proc``'s standard error; fails on a traceback
    or on any other number of such lines (``proc.stdout`` may be ``None``: not captured)."""
    assert "Traceback" not in proc.stderr + (proc.stdout or ""), proc.stderr
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.startswith("penaltyrun")]
    assert len(lines) == 1, proc.stderr
    return lines[0]
