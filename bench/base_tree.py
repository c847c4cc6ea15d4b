"""The code of another git revision, checked out beside this tree for a before/after benchmark
(``bench_report.py --base``, ``lbfgs_base.py --base``): a detached git worktree whose folder
goes first on ``PYTHONPATH`` of the processes that run it."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@contextmanager
def base_worktree(revision: str, folder: Path) -> Iterator[Path]:
    """Check ``revision`` out (detached) into ``folder / "base"``; yield that path; remove the
    worktree on exit."""
    tree = Path(folder) / "base"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree),
                    revision], check=True, capture_output=True)
    try:
        yield tree
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                       check=False, capture_output=True)
