"""Readers for what the reference pages are generated from: numpydoc ``Attributes``
sections and the inline comments of penaltyrun's YAML configs."""

from __future__ import annotations

import inspect
import re
from pathlib import Path
from typing import Any

from penaltyrun import yamlsafe

_KEY_LINE = re.compile(r"^(?P<indent> *)(?P<key>[A-Za-z_][\w]*):(?P<value>[^#]*?)"
                       r"\s*(?:#\s?(?P<comment>.*))?$")
_COMMENT_LINE = re.compile(r"^(?P<indent> *)#\s?(?P<comment>.*)$")


def rst_to_md(text: str) -> str:
    """Inline reStructuredText of a docstring as Markdown (``x`` → `x`, roles dropped)."""
    text = re.sub(r":(?:class|func|mod|data|meth|attr):`~?\.?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def numpydoc_to_md(doc: str) -> str:
    """A numpydoc docstring as Markdown: section titles in bold, ``name : type`` entries
    as list items with their indented descriptions joined."""
    lines = doc.splitlines()
    out: list[str] = []
    in_section = False
    i = 0
    while i < len(lines):
        line = lines[i]
        nxt = lines[i + 1] if i + 1 < len(lines) else ""
        if line.strip() and nxt.strip() and set(nxt.strip()) == {"-"}:
            out += ["", f"**{line.strip()}**", ""]
            in_section = True
            i += 2
            continue
        if in_section and line and not line.startswith(" "):
            name, _, kind = line.partition(" : ")
            item = f"* `{name.strip()}`" + (f" ({kind.strip()})" if kind else "")
            desc = []
            i += 1
            while i < len(lines) and (lines[i].startswith(" ") or not lines[i].strip()):
                if lines[i].strip():
                    desc.append(lines[i].strip())
                elif desc:
                    break
                i += 1
            out.append(item + (": " + " ".join(desc) if desc else ""))
            continue
        out.append(line)
        i += 1
    return rst_to_md("\n".join(out))


def attribute_docs(cls: type) -> dict[str, str]:
    """Field name → description from the numpydoc ``Attributes`` sections of ``cls`` and
    its bases (a line ``a, b : type`` documents both names).

    Returns
    -------
    dict of str to str
        One-line descriptions (continuation lines joined), Markdown.
    """
    out: dict[str, str] = {}
    for klass in reversed(inspect.getmro(cls)):
        doc = inspect.getdoc(klass) or ""
        lines = doc.splitlines()
        try:
            start = next(i for i, line in enumerate(lines)
                         if line.strip() == "Attributes" and i + 1 < len(lines)
                         and set(lines[i + 1].strip()) == {"-"})
        except StopIteration:
            continue
        names: list[str] = []
        for line in lines[start + 2:]:
            if line and not line.startswith(" "):
                if set(line.strip()) == {"-"} or (names and line.strip() and
                                                  ":" not in line and "," not in line
                                                  and not line.strip().isidentifier()):
                    break
                head = line.split(" : ")[0]
                names = [n.strip() for n in head.split(",") if n.strip().isidentifier()]
                if not names:
                    break
                for name in names:
                    out[name] = ""
            elif line.strip() and names:
                for name in names:
                    out[name] = (out[name] + " " + line.strip()).strip()
            elif not line.strip() and names:
                continue
    return {k: rst_to_md(v) for k, v in out.items()}


def yaml_entries(path: Path) -> list[dict[str, Any]]:
    """Every key of a YAML config with its dotted path, value and inline comment.

    Comment lines right below a key (indented deeper than the key, or aligned comment
    continuation lines) extend its comment; a key without an inline comment takes the
    comment block right above it. Keys under ``hydra`` and ``defaults`` are kept;
    the caller filters.

    Returns
    -------
    list of dict
        ``{"key": dotted path, "value": parsed value or None for a mapping,
        "comment": str}`` in file order.
    """
    data = yamlsafe.load_file(path) or {}
    entries: list[dict[str, Any]] = []
    stack: list[tuple[int, str]] = []
    last: dict[str, Any] | None = None
    above: list[str] = []
    for line in path.read_text().splitlines():
        comment = _COMMENT_LINE.match(line)
        if comment:
            if last is not None and len(comment["indent"]) > last["indent"]:
                last["comment"] = (last["comment"] + " " + comment["comment"]).strip()
            else:
                last = None
                above.append(comment["comment"].strip())
            continue
        match = _KEY_LINE.match(line)
        if not match or line.lstrip().startswith("-"):
            last = None
            above = []
            continue
        indent = len(match["indent"])
        while stack and stack[-1][0] >= indent:
            stack.pop()
        dotted = ".".join([k for _, k in stack] + [match["key"]])
        stack.append((indent, match["key"]))
        value = _lookup(data, dotted)
        last = {"key": dotted, "value": value, "indent": indent,
                "comment": (match["comment"] or "").strip() or " ".join(
                    a for a in above if not a.startswith("-")).strip()}
        above = []
        entries.append(last)
    for entry in entries:
        entry.pop("indent", None)
    return entries


def _lookup(data: Any, dotted: str) -> Any:
    node = data
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def header_comment(path: Path) -> str:
    """The leading comment block of a YAML file (``# @package`` lines skipped), one
    paragraph."""
    lines = []
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            break
        text = line.lstrip("#").strip()
        if not text.startswith("@package"):
            lines.append(text)
    return " ".join(lines).strip()
