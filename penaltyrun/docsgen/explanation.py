"""Explanation pages rendered from committed data, with their figures.

Templates under ``studies/templates/explanation/*.md`` (Jinja, the same environment as the
results pages, :func:`penaltyrun.docsgen.resultpages.environment`) render to
``docs/explanation/<name>.md``. A template gets a study's mechanism data through
``full_matrix(study, example=(problem, case))`` (a :class:`penaltyrun.docsgen.fullmatrix.Page`)
and names its figures with ``page.figure(key)``.

What ``make check-docs`` checks, and what it does not:

* the page *text* is rendered afresh and compared line by line with the committed page, so
  an edited number, or data changed without ``make docs-results``, fails the check;
* the figures are drawn only by ``make docs-results`` (:meth:`Figures.write`, a few seconds:
  the example trajectories are integrated) and committed beside the page in
  ``docs/explanation/figures/``. The check asserts that every image the rendered pages link
  to exists, not that its pixels are current: PNG bytes change with the matplotlib and
  FreeType versions, so a byte comparison would fail on another machine for no change of
  data. Every number the figures show beside the text comes from the same computation as
  the text's numbers.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

#: Explanation templates, relative to the repository root.
TEMPLATES = Path("studies") / "templates" / "explanation"
#: Where they render, relative to the repository root.
DOCS = Path("docs") / "explanation"
#: A Markdown image link (its target).
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")


class Figures:
    """The data pages the templates opened while rendering, so their figures can be drawn
    after (one :class:`~penaltyrun.docsgen.fullmatrix.Page` per study and example cell)."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.pages: dict[tuple[str, tuple[str, str]], Any] = {}

    def full_matrix(self, name: str, example: tuple[str, str] | list[str]) -> Any:
        """The :class:`~penaltyrun.docsgen.fullmatrix.Page` of study ``name`` (built once)."""
        from penaltyrun.docsgen.fullmatrix import Page

        key = (str(name), (str(example[0]), str(example[1])))
        if key not in self.pages:
            self.pages[key] = Page(self.root, key[0], key[1])
        return self.pages[key]

    def write(self) -> list[Path]:
        """Draw the figures of every page opened so far into ``docs/explanation/figures``;
        return the paths (relative to the root) whose bytes changed."""
        from penaltyrun.docsgen.fullmatrix import FIGURE_DIR

        folder = self.root / DOCS / FIGURE_DIR
        before = {p: p.read_bytes() for p in folder.glob("*.png")} if folder.is_dir() else {}
        written = []
        for page in self.pages.values():
            written += [p for p in page.write_figures(folder)
                        if before.get(p) != p.read_bytes()]
        return [p.relative_to(self.root) for p in written]


def render(env: Any, root: Path, only: str | None = None) -> dict[Path, str]:
    """Rendered text of every explanation template (whose output path starts with
    ``only``, when given), by path relative to ``root``."""
    out = {}
    for path in sorted((Path(root) / TEMPLATES).glob("*.md")):
        rel = DOCS / path.name
        if only and not str(rel).startswith(only):
            continue
        out[rel] = env.get_template(f"explanation/{path.name}").render()
    return out


def missing_images(root: Path, rendered: dict[Path, str]) -> list[str]:
    """One line per image an explanation page links to that is not committed."""
    problems = []
    for rel, text in rendered.items():
        if rel.parent != DOCS:
            continue
        for target in IMAGE.findall(text):
            if "://" not in target and not (Path(root) / rel.parent / target).is_file():
                problems.append(f"{rel}: figure {target} missing (run `make docs-results` "
                                "and commit it)")
    return problems


__all__ = ["DOCS", "TEMPLATES", "Figures", "missing_images", "render"]
