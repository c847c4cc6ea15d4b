"""`make` installs penaltyrun once (a stamp in the environment), not before every target;
`make install` and `make install-dev` always reinstall. Checked with ``make -n`` (prints the
commands, runs nothing) against an environment folder of the test's own."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="no make")


def dry(venv: Path, *goals: str) -> str:
    proc = subprocess.run(["make", "-n", f"VENV={venv}", *goals], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def installs(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if "pip install" in ln]


@pytest.fixture
def venv(tmp_path):
    """An environment whose Python exists (make does not create it again)."""
    (tmp_path / "env" / "bin").mkdir(parents=True)
    (tmp_path / "env" / "bin" / "python").write_text("")
    return tmp_path / "env"


def test_first_target_installs_then_no_target_does(venv):
    assert installs(dry(venv, "test")) == [f'{venv}/bin/python -m pip install -q -e ".[dev]"']
    assert len(installs(dry(venv, "run"))) == 1  # the runtime stamp is not there either
    for stamp in (".installed", ".installed-dev"):
        (venv / stamp).write_text("")
    assert installs(dry(venv, "test", "run", "lint", "test-random", "docs", "bench")) == []


def test_install_always_reinstalls_and_a_changed_pyproject_too(venv):
    for stamp in (".installed", ".installed-dev"):
        (venv / stamp).write_text("")
    assert installs(dry(venv, "install")) == [f"{venv}/bin/python -m pip install -q -e ."]
    assert len(installs(dry(venv, "install-dev"))) == 1
    older = (ROOT / "pyproject.toml").stat().st_mtime - 60
    for stamp in (".installed", ".installed-dev"):
        os.utime(venv / stamp, (older, older))
    assert len(installs(dry(venv, "test"))) == 1
    assert len(installs(dry(venv, "run"))) == 1
