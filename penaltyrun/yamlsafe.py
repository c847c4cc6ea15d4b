"""YAML read with bounds: every YAML file penaltyrun reads from a user or a data file.

A YAML file can be small and still cost unbounded time or memory: deep nesting
(``[[[[…]]]]``) overflows the parser's recursion, and a few anchors referred to by many
aliases (``&a [*b, *b, …]``, the "billion laughs") expand to billions of values in whatever
walks the data afterwards (OmegaConf, JSON, a report). :func:`load_file` and
:func:`load_text` read with PyYAML's safe loader (no Python objects, no code) and refuse,
with one :class:`YamlLimitError` naming the file and the limit:

* a file larger than :data:`MAX_BYTES` (1 MiB; checked before it is read);
* nesting deeper than :data:`MAX_DEPTH` (50 levels of mappings and lists), counted after
  aliases are followed, and OmegaConf interpolations ``${...}`` nested deeper than that;
* aliases that add more than :data:`MAX_ALIAS_VALUES` (100 000) values when expanded, or
  an alias inside the node it refers to (a recursive structure).

:class:`YamlLimitError` is a :class:`yaml.YAMLError`, so a caller that already turns
malformed YAML into a one-line :class:`~penaltyrun.errors.ConfigError` does the same with
these.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import yaml
from yaml.events import AliasEvent
from yaml.nodes import MappingNode, Node, SequenceNode

#: Largest YAML file read (bytes): 1 MiB.
MAX_BYTES = 1 << 20
#: Deepest nesting of mappings and lists (after aliases are followed).
MAX_DEPTH = 50
#: Most values aliases may add when expanded (each alias counts the values it stands for).
MAX_ALIAS_VALUES = 100_000


class YamlLimitError(yaml.YAMLError):
    """A YAML file beyond one of the limits of :mod:`penaltyrun.yamlsafe`; the message is
    one line naming the file and the limit."""


class _Bounded:
    """Mixin for a PyYAML loader class: depth and alias-expansion limits while composing."""

    _name = "YAML"

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(AliasEvent):  # type: ignore[attr-defined]
            return super().compose_node(parent, index)  # type: ignore[misc]
        self._depth = getattr(self, "_depth", 0) + 1
        if self._depth > MAX_DEPTH:
            raise YamlLimitError(f"{self._name}: nesting deeper than {MAX_DEPTH} levels "
                                 f"(the limit)")
        try:
            return super().compose_node(parent, index)  # type: ignore[misc]
        finally:
            self._depth -= 1

    def get_single_node(self) -> Any:
        node = super().get_single_node()  # type: ignore[misc]
        if node is not None:
            _check_expansion(node, self._name)
        return node


def _check_expansion(root: Node, name: str) -> None:
    """Refuse a node graph whose expanded tree is deeper than :data:`MAX_DEPTH` or larger
    than its own node count by more than :data:`MAX_ALIAS_VALUES`, or is recursive.

    Each distinct node is visited once (sizes and heights memoized), so the check costs
    time linear in the file, whatever the expansion; an anchor is composed before its
    aliases, so the walk is never deeper than the file's own nesting.
    """
    done: dict[int, tuple[int, int]] = {}  # id(node) -> (expanded values, height)
    open_: set[int] = set()

    def visit(node: Node, depth: int) -> tuple[int, int]:
        key = id(node)
        if key in open_:
            raise YamlLimitError(f"{name}: an alias refers to a node that contains it (a "
                                 f"recursive structure is not read)")
        if key in done:
            size, height = done[key]
        else:
            children: list[Node] = []
            if isinstance(node, SequenceNode):
                children = list(node.value)
            elif isinstance(node, MappingNode):
                children = [part for pair in node.value for part in pair]
            open_.add(key)
            size, height = 1, 0
            for child in children:
                child_size, child_height = visit(child, depth + 1)
                size += child_size
                height = max(height, child_height + 1)
            open_.discard(key)
            done[key] = (size, height)
        if depth + height + 1 > MAX_DEPTH:  # levels: the root is level 1
            raise YamlLimitError(f"{name}: nesting deeper than {MAX_DEPTH} levels (the "
                                 f"limit; counted with aliases expanded)")
        return size, height

    size, _ = visit(root, 0)
    if size - len(done) > MAX_ALIAS_VALUES:
        raise YamlLimitError(f"{name}: aliases expand to more than {MAX_ALIAS_VALUES} "
                             f"values (the limit; a file of many nested aliases is not "
                             f"read)")


def _bounded(loader: type) -> type:
    """The subclass of ``loader`` with the limits."""
    return type(f"Bounded{loader.__name__}", (_Bounded, loader), {})


def load_text(text: str, name: str = "YAML", loader: type | None = None) -> Any:
    """Parse ``text`` with the depth and alias limits (and the size limit, in UTF-8 bytes).

    Parameters
    ----------
    text : str
        The YAML document.
    name : str
        What to call it in a message (a file name, ``"stored config"``).
    loader : type, optional
        A :class:`yaml.SafeLoader` subclass (default :class:`yaml.SafeLoader`), e.g.
        OmegaConf's, whose resolvers are kept.

    Raises
    ------
    YamlLimitError
        Beyond a limit: one line naming ``name`` and the limit.
    yaml.YAMLError
        Malformed YAML.
    """
    base = loader or yaml.SafeLoader
    if not issubclass(base, yaml.SafeLoader):
        raise TypeError(f"{base.__name__} is not a yaml.SafeLoader")
    if len(text) > MAX_BYTES or len(text.encode("utf-8", "surrogatepass")) > MAX_BYTES:
        raise YamlLimitError(f"{name}: larger than {MAX_BYTES} bytes (the limit for a "
                             f"YAML file)")
    if _interpolation_depth(text) > MAX_DEPTH:
        raise YamlLimitError(f"{name}: interpolations ${{...}} nested deeper than "
                             f"{MAX_DEPTH} levels (the limit for a YAML file)")
    reader = _bounded(base)(text)
    reader._name = name
    try:
        return reader.get_single_data()
    finally:
        reader.dispose()


def _interpolation_depth(text: str) -> int:
    """The deepest nesting of OmegaConf interpolations ``${...}`` in ``text`` (a ``}`` closes
    the innermost open one): resolving them recurses once per level."""
    depth = deepest = 0
    previous = -2
    for opening in re.finditer(r"\$\{", text):
        closed = text.count("}", previous + 2, opening.start()) if depth else 0
        depth = max(depth - closed, 0) + 1
        deepest = max(deepest, depth)
        previous = opening.start()
    return deepest


def load_file(path: str | os.PathLike[str], loader: type | None = None) -> Any:
    """Read the YAML file ``path`` with the limits of this module.

    The size is checked before the file is read (and at most :data:`MAX_BYTES` + 1 bytes
    are read, for a file that grows or is not a regular file).

    Parameters
    ----------
    path : path-like
    loader : type, optional
        See :func:`load_text`.

    Raises
    ------
    YamlLimitError
        Beyond a limit: one line naming the file and the limit.
    yaml.YAMLError
        Malformed YAML.
    OSError, UnicodeDecodeError
        The file cannot be read as UTF-8 text.
    """
    file = Path(path)
    with open(file, "rb") as fh:
        if os.path.isfile(file) and os.fstat(fh.fileno()).st_size > MAX_BYTES:
            raise YamlLimitError(f"{file}: larger than {MAX_BYTES} bytes (the limit for a "
                                 f"YAML file)")
        raw = fh.read(MAX_BYTES + 1)
    if len(raw) > MAX_BYTES:
        raise YamlLimitError(f"{file}: larger than {MAX_BYTES} bytes (the limit for a "
                             f"YAML file)")
    return load_text(raw.decode("utf-8"), str(file), loader)


__all__ = ["MAX_ALIAS_VALUES", "MAX_BYTES", "MAX_DEPTH", "YamlLimitError", "load_file",
           "load_text"]
