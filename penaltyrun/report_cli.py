"""``python -m penaltyrun.report_cli INPUT [-o OUTPUT]`` — same as ``penaltyrun-report``.

``python -m`` puts the current folder first on ``sys.path``. Run inside a received results
folder, a file there named like a module penaltyrun imports (``yaml.py``,
``matplotlib.py``) would run, so that folder is taken off ``sys.path`` before anything
else is imported — unless the user put it on ``PYTHONPATH``.
"""

import os
import sys


def _drop_current_folder() -> None:
    """Remove the current folder that ``python -m`` put first on ``sys.path``."""
    if not sys.path or sys.flags.safe_path:
        return
    here = os.path.abspath(os.getcwd())
    named = {os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
             if p}
    if os.path.abspath(sys.path[0] or os.curdir) == here and here not in named:
        del sys.path[0]


if __name__ == "__main__":
    _drop_current_folder()
    from penaltyrun.cli.report import report_main

    report_main()
