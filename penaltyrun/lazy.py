"""Lazy package attributes: a package names its public objects and the submodule defining
each, and imports a submodule only when one of its names is first used (``import
penaltyrun`` stays cheap, and numba compiles only what a run needs).

A package writes::

    _NAMES = {"tune": "tuning", ...}
    __all__ = sorted(_NAMES)
    __getattr__, __dir__ = lazy.exports(__name__, _NAMES, globals())

No public name may be the name of a submodule of the same package: importing that
submodule would replace the attribute (``tests/test_public_names.py`` checks it).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def exports(package: str, names: Mapping[str, str], namespace: dict[str, Any]
            ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module-level ``__getattr__`` and ``__dir__`` (PEP 562) of ``package``.

    Parameters
    ----------
    package : str
        The package's ``__name__``.
    names : mapping
        Public name → submodule (relative to ``package``) that defines it.
    namespace : dict
        The package's ``globals()``: a resolved name is cached there.
    """

    def attribute(name: str) -> Any:
        module = names.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{module}"), name)
        namespace[name] = value
        return value

    def listing() -> list[str]:
        return sorted(set(namespace) | set(names))

    return attribute, listing
