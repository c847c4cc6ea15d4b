"""``python -m penaltyrun.report_cli`` in a received folder imports nothing from it, and
``penaltyrun-report`` reads no configuration file from it (:func:`ignore_folder_config`).

``python -m`` puts the current folder first on ``sys.path``. Run inside a received results
folder, a file there named like a module that penaltyrun or the standard library imports
(``typing.py``, ``yaml.py``, ``matplotlib.py``) would run. Python imports the package
``penaltyrun`` before its module ``report_cli``, so the package's first statement calls
:func:`guard_report_cli`, which takes that folder off ``sys.path`` before anything that is
not already loaded is imported (this module imports only ``os`` and ``sys``, which every
interpreter has loaded at start-up) — unless the user put the folder on ``PYTHONPATH``.
Other entry points keep the folder: the runner imports user problem modules from it on
purpose. What no package can guard against is a planted ``penaltyrun.py`` (or
``penaltyrun/``) in the folder, found before the package itself: in a folder received from
someone else, run the installed ``penaltyrun-report`` command (or ``python -P -m``), which
never puts the current folder on ``sys.path``.
"""

import os
import sys

#: The module whose ``python -m`` run must not import from the current folder.
REPORT_MODULE = "penaltyrun.report_cli"


def run_as(module: str, argv: list[str] | None = None,
           orig_argv: list[str] | None = None) -> bool:
    """Whether this interpreter runs ``python [options] -m module`` and is still locating
    it: Python sets ``sys.argv[0]`` to ``"-m"`` while it imports the module's packages,
    and the module's name is then the element of the original command line
    (``sys.orig_argv``) just before the script's arguments, alone or as the tail of a
    combined option (``-m module``, ``-mmodule``, ``-Bm module``, ``-Bmmodule``), whatever
    options come first."""
    argv = list(sys.argv if argv is None else argv)
    orig = list(getattr(sys, "orig_argv", []) if orig_argv is None else orig_argv)
    if not argv or argv[0] != "-m" or len(orig) < len(argv):
        return False
    name = orig[len(orig) - len(argv)]
    if name.startswith("-"):  # -mmodule or -Bmmodule: the name follows the m
        name = name[name.index("m") + 1:] if "m" in name[1:] else ""
    return name == module


def drop_current_folder() -> None:
    """Remove the current folder from ``sys.path``, where ``python -m`` put it first (and an
    empty ``PYTHONPATH`` entry may have put it again); kept when the interpreter runs with
    ``-P``/``PYTHONSAFEPATH`` or the user named the folder on ``PYTHONPATH``."""
    if not sys.path or sys.flags.safe_path:
        return
    here = os.path.abspath(os.getcwd())
    named = {os.path.abspath(p) for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
             if p}
    if here in named:
        return
    # the entry python -m put first, and any an empty PYTHONPATH entry ("a:" or ":a") put
    # there too (an accident, not a choice of the folder)
    sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != here]


def guard_report_cli() -> None:
    """:func:`drop_current_folder` when this interpreter runs :data:`REPORT_MODULE`."""
    if run_as(REPORT_MODULE):
        drop_current_folder()


#: numba's per-folder configuration file, read from the working directory at import and at
#: every later compilation (``numba.core.config``).
NUMBA_FOLDER_CONFIG = ".numba_config.yaml"


def ignore_folder_config() -> None:
    """Make a report over a received folder, run from inside it, blind to the configuration
    files that numba and matplotlib read from the working directory.

    numba reads ``.numba_config.yaml`` from the working directory (its ``cache_dir``
    made a report write compiled-code caches, and load pickled cache indexes, wherever the
    file said), and matplotlib a ``matplotlibrc`` there (it could switch text to LaTeX, so
    that no figure is drawn, or recolour every figure). Both are imported here with the
    working directory moved to an empty temporary folder, and numba is told to look for
    its file nowhere afterwards; settings from the environment (``NUMBA_*``,
    ``MATPLOTLIBRC``) still apply. For ``penaltyrun-report``, whose input may come from
    someone else, and its worker processes; a run (``penaltyrun``) keeps the folder's
    files, which are the user's. A library imported before is not imported again.
    """
    import tempfile

    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="penaltyrun-imports-") as empty:
        os.chdir(empty)
        try:
            import matplotlib
            import numba.core.config as numba_config

            matplotlib.get_backend()
        finally:
            os.chdir(here)
        if getattr(numba_config, "_config_fname", None) == NUMBA_FOLDER_CONFIG:
            numba_config._config_fname = os.path.join(empty, NUMBA_FOLDER_CONFIG)  # gone
