"""MkDocs hook: the reference pages generated from the code join the site at build time
(``hooks:`` in ``mkdocs.yml``), so they are never stale and never committed."""

from __future__ import annotations

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
