"""``penaltyrun-report`` run from inside a received folder: configuration files and modules
planted there (numba's ``.numba_config.yaml``, a ``matplotlibrc``, a ``pandas.py``) change
nothing, in the report's own process and in its worker processes."""

from __future__ import annotations

import os
import subprocess
import sys

import penaltyrun

PANDAS_CANARY = "import pathlib\npathlib.Path({canary!r}).write_text('ran')\n"


def test_a_received_folder_configures_nothing_and_runs_nothing(tmp_path):
    received = tmp_path / "received"
    for problem in ("zermelo", "lqr"):  # two problem cases: the sections go to workers
        penaltyrun.tune(problem, param="diagonal", n_starts=2, workers=1,
                        optimizer_options={"max_evals": 30}, run_dir=received / problem)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    canary = tmp_path / "pandas_ran"
    (received / ".numba_config.yaml").write_text(f"cache_dir: {elsewhere}\n",
                                                 encoding="utf-8")
    (received / "matplotlibrc").write_text("text.usetex: True\n", encoding="utf-8")
    (received / "pandas.py").write_text(PANDAS_CANARY.format(canary=str(canary)),
                                        encoding="utf-8")
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("NUMBA_", "MATPLOTLIB", "PYTHONPATH", "PYTHONSAFEPATH"))}
    script = os.path.join(os.path.dirname(sys.executable), "penaltyrun-report")
    done = subprocess.run([script, ".", "-o", str(tmp_path / "out"), "--workers", "2",
                           "--no-cache", "--progress", "false", "--basin-points", "0"],
                          cwd=received, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "worker died" not in done.stderr  # the sections were written by the workers
    assert not canary.exists()  # the workers imported the real pandas
    assert list(elsewhere.iterdir()) == []  # numba cached nothing where the file said
    assert "latex" not in done.stderr.lower()
    figures = list((tmp_path / "out").glob("*.png"))
    assert len(figures) >= 4
