"""The two pieces of Hydra's private API the command line uses, kept in this one module.

penaltyrun checks a command line before Hydra runs it (one-line refusals, ``mode=plan``,
the allowed values of a config group) and must see it exactly as Hydra's app will: with
Hydra's own argument parser, and with the config search path Hydra's app builds (the
primary config's folder, then each ``--config-dir``, then the ``hydra.searchpath``
entries). Hydra 1.3 offers neither through a public function: its ``initialize_config_dir``
takes one folder, and passing the ``--config-dir`` folders as ``hydra.searchpath`` would
replace the search path a user's config or command line sets. Both are imported from
``hydra._internal`` here and nowhere else; ``hydra-core`` is pinned to 1.3.x in
``pyproject.toml`` and ``tests/cli/test_hydra_private.py`` checks them against the
installed Hydra.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path


def args_parser() -> argparse.ArgumentParser:
    """Hydra's own command-line parser (the one ``@hydra.main`` parses ``sys.argv`` with)."""
    from hydra._internal.utils import get_args_parser

    return get_args_parser()


def init_global_hydra(app_name: str, primary: Path, config_dirs: Sequence[Path]) -> None:
    """Initialize Hydra's global state with the search path Hydra's app uses.

    Parameters
    ----------
    app_name : str
        The task name Hydra's app runs under.
    primary : pathlib.Path
        Directory of the primary config.
    config_dirs : sequence of pathlib.Path
        The ``--config-dir`` directories, searched after ``primary`` and before the
        structured configs (as Hydra's own ``--config-dir`` handling does).

    Notes
    -----
    Clear the state afterwards with ``GlobalHydra.instance().clear()`` (public API).
    """
    from hydra._internal.hydra import Hydra
    from hydra._internal.utils import create_config_search_path
    from hydra.core.config_search_path import SearchPathQuery
    from hydra.core.global_hydra import GlobalHydra

    search_path = create_config_search_path(str(primary))
    for extra in config_dirs:
        search_path.prepend(provider="command-line", path=f"file://{extra}",
                            anchor=SearchPathQuery(provider="schema"))
    GlobalHydra.instance().clear()
    Hydra.create_main_hydra2(app_name, search_path)
