"""report.html from the report's Markdown: tables, lists, embedded figures."""

from __future__ import annotations

import base64

from penaltyrun.report.html import inline, to_html

PNG = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8Dw"
                       "HwAFBQIAX8jx0gAAAABJRU5ErkJggg==")


def test_page_embeds_figures_and_renders_tables(tmp_path):
    (tmp_path / "fig.png").write_bytes(PNG)
    md = "\n".join(["# title", "", "| a | b |", "|---|---|", "| 1 | x \\| y |", "",
                    "- **item** one", "- two", "", "![a figure](fig.png)", "",
                    "text with `code` and *emphasis*", ""])
    page = to_html(md, tmp_path)
    assert "<h1>title</h1>" in page
    assert "<th>a</th><th>b</th>" in page and "<td>x | y</td>" in page
    assert "<li><b>item</b> one</li>" in page
    assert "data:image/png;base64," + base64.b64encode(PNG).decode() in page
    assert "<code>code</code>" in page and "<i>emphasis</i>" in page
    assert "http" not in page  # nothing to fetch


def test_inline_escapes_and_leaves_formula_stars():
    assert inline("a < b & f* + ε·|f*|") == "a &lt; b &amp; f* + ε·|f*|"


def test_fenced_blocks_are_preformatted_and_folds_pass_through(tmp_path):
    text = ("<details><summary>best full: matrices</summary>\n\nK =\n```\n  1 <2\n-3  4\n```\n\n"
            "</details>\n\nafter\n")
    page = to_html(text, tmp_path)
    assert "<details><summary>best full: matrices</summary>" in page
    assert "<p>K =</p>" in page and "<pre>  1 &lt;2\n-3  4</pre>" in page
    assert "</details>" in page and "<p>after</p>" in page and "```" not in page
