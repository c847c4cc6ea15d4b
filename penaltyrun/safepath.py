"""``python -m penaltyrun.report_cli`` in a received folder imports nothing from it.

``python -m`` puts the current folder first on ``sys.path``. Run inside a received results
folder, a file there named like a module that penaltyrun or the standard library imports
(``typing.py``, ``yaml.py``, ``matplotlib.py``) would run. Python imports the package
``penaltyrun`` before its module ``report_cli``, so the package's first statement calls
:func:`guard_report_cli`, which takes that folder off ``sys.path`` before anything that is
not already loaded is imported (this module imports only ``os`` and ``sys``, which every
interpreter has loaded at start-up) — unless the user put the folder on ``PYTHONPATH``.
Other entry points keep the folder: the runner imports user problem modules from it on
purpose.
"""

import os
import sys

#: The module whose ``python -m`` run must not import from the current folder.
REPORT_MODULE = "penaltyrun.report_cli"


def run_as(module: str, argv: list[str] | None = None) -> bool:
    """Whether this interpreter was started as ``python [options] -m module`` (from the
    interpreter's original command line, ``argv`` by default ``sys.orig_argv``)."""
    argv = list(getattr(sys, "orig_argv", []) if argv is None else argv)
    i = 1
    while i < len(argv):
        arg = argv[i]
        if arg == "-m":
            return i + 1 < len(argv) and argv[i + 1] == module
        if arg.startswith("-m"):
            return arg[2:] == module
        if not arg.startswith("-") or arg == "-c":
            return False  # a script or a command: not -m
        i += 2 if arg in ("-X", "-W") else 1  # these two take the next argument
    return False


def drop_current_folder() -> None:
    """Remove the current folder that ``python -m`` put first on ``sys.path`` (kept when
    the interpreter runs with ``-P``/``PYTHONSAFEPATH`` or the folder is on
    ``PYTHONPATH``)."""
    if not sys.path or sys.flags.safe_path:
        return
    here = os.path.abspath(os.getcwd())
    named = {os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
             if p}
    if os.path.abspath(sys.path[0] or os.curdir) == here and here not in named:
        del sys.path[0]


def guard_report_cli() -> None:
    """:func:`drop_current_folder` when this interpreter runs :data:`REPORT_MODULE`."""
    if run_as(REPORT_MODULE):
        drop_current_folder()
