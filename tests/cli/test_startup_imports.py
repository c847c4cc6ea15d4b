"""What the command line imports: a run without a report never imports the report
(matplotlib, scipy.stats), and a refused value override is answered before numba or Hydra
is imported. Each case runs in its own interpreter, which reports its ``sys.modules``."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

#: Runs the command line with the arguments given, then prints which of the watched
#: modules were imported, as a JSON list on the last line of standard output.
_SCRIPT = """
import json, sys
import penaltyrun.cli as cli

WATCH = ("matplotlib", "penaltyrun.report", "scipy.stats", "numba", "hydra")
sys.argv = ["penaltyrun", *sys.argv[1:]]
try:
    cli.main()
except SystemExit as exc:
    print("exit", exc.code, file=sys.stderr)
print(json.dumps(sorted(m for m in WATCH if m in sys.modules)))
"""


def _run(args: list[str], cwd: Path) -> tuple[list[str], str]:
    proc = subprocess.run([sys.executable, "-c", _SCRIPT, *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)
    return json.loads(proc.stdout.strip().splitlines()[-1]), proc.stderr


def test_a_run_without_report_imports_no_report(tmp_path):
    loaded, err = _run(["problem=zermelo", "optimizer=baseline", "runner.n_starts=2",
                        "runner.report=false", f"hydra.run.dir={tmp_path / 'run'}"],
                       tmp_path)
    assert "2 jobs: 2 ok" in err
    assert not {"matplotlib", "penaltyrun.report", "scipy.stats"} & set(loaded)
    assert (tmp_path / "run" / "results.parquet").is_file()


def test_a_run_with_report_writes_it(tmp_path):
    """The same run with ``runner.report=true`` still imports the report and writes it."""
    loaded, err = _run(["problem=zermelo", "optimizer=baseline", "runner.n_starts=2",
                        "runner.report=true", f"hydra.run.dir={tmp_path / 'run'}"], tmp_path)
    assert "penaltyrun.report" in loaded
    assert (tmp_path / "run" / "report").is_dir()


@pytest.mark.parametrize(("argv", "line"), [
    (["problem=zermelo", "runner.n_starts=0"],
     "penaltyrun: error: runner.n_starts: must be a positive integer, got 0"),
    (["optimizer=cmaes", "optimizer.popsize=-2"], "penaltyrun: error: optimizer.popsize: "),
])
def test_a_refused_value_is_answered_before_numba_and_hydra(argv, line, tmp_path):
    loaded, err = _run(argv, tmp_path)
    assert line in err
    assert "exit 2" in err
    assert not {"numba", "hydra"} & set(loaded)
    assert list(tmp_path.iterdir()) == []  # no run directory


def test_a_refused_choice_still_names_the_allowed_ones(tmp_path):
    """What the quick check leaves alone is answered by the preflight as before."""
    loaded, err = _run(["param=bogus", "runner.n_starts=2"], tmp_path)
    assert "penaltyrun: error: param: unknown choice 'bogus' (allowed:" in err
    assert "exit 2" in err and "numba" not in loaded
