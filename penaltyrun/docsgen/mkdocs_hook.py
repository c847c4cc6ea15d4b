"""MkDocs hook: the reference pages are generated from the code again at build time
(``hooks:`` in ``mkdocs.yml``), so the site never shows a stale page even where the
committed copies (checked by ``make check-docs``) lag behind; and the Sphinx roles of the
docstrings in the Python API reference read as plain code."""

from __future__ import annotations

import re
from typing import Any

from mkdocs.structure.files import File, Files


def on_files(files: Files, config: Any) -> Files:
    """Add every page of :func:`penaltyrun.docsgen.reference.pages` to the site."""
    from penaltyrun.docsgen.reference import pages
    for rel, text in pages().items():
        existing = files.get_file_from_path(rel)
        if existing is not None:
            files.remove(existing)
        files.append(File.generated(config, rel, content=text))
    return files


#: A Sphinx cross-reference role as the API reference renders it from a numpydoc docstring
#: (``:func:`~penaltyrun.tune``` → ``:func:<code>~penaltyrun.tune</code>``).
_ROLE = re.compile(r":(?:py:)?(?:func|class|data|mod|meth|attr|exc|obj|const):<code>~?")


def on_page_content(html: str, **kwargs: Any) -> str:
    """Show the docstrings' Sphinx roles as plain code in the API reference
    (``:func:`~penaltyrun.tune``` reads ``penaltyrun.tune``)."""
    return _ROLE.sub("<code>", html)
