"""MkDocs hook: the reference pages are generated from the code again at build time
(``hooks:`` in ``mkdocs.yml``), so the site never shows a stale page even where the
committed copies (checked by ``make check-docs``) lag behind."""

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
