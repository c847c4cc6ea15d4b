"""``report.html``: the report as one self-contained page (figures embedded as base64, no
network access), from the Markdown the report writes.

Only the Markdown the report itself produces is converted: headings, paragraphs, ``- ``
lists, pipe tables, images, ``**bold**``, ```code```, fenced code blocks (kept as
preformatted text) and folds (a line ``<details><summary>TITLE</summary>`` or
``</details>``). Every text is HTML-escaped, fold titles too; an image is embedded only when
it is a ``.png`` file of the report folder itself. Tables sort by a click on a column header
(a few lines of inline JavaScript).
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Iterator
from pathlib import Path

from penaltyrun.report.outdir import plain_name

STYLE = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:2em auto;max-width:1300px;
padding:0 1.5em;line-height:1.45;color:#222}
h1{border-bottom:2px solid #444}h2{border-bottom:1px solid #bbb;margin-top:2em}
table{border-collapse:collapse;margin:0.8em 0;font-size:0.9em}
th,td{border:1px solid #ccc;padding:0.3em 0.6em;vertical-align:top}
th{background:#eef;cursor:pointer;user-select:none;position:sticky;top:0}
tr:nth-child(even) td{background:#f8f8f8}
img{max-width:100%;height:auto;margin:0.5em 0;border:1px solid #eee}
code{background:#f2f2f2;padding:0 0.2em}
pre{background:#f6f6f6;padding:0.5em;overflow-x:auto;font-size:0.85em}
summary{cursor:pointer;margin:0.4em 0}
li{margin:0.3em 0}
"""
SCRIPT = """
document.querySelectorAll('table').forEach(function(t){
 t.querySelectorAll('th').forEach(function(th,i){th.title='click to sort';
  th.addEventListener('click',function(){
   var rows=Array.from(t.tBodies[0].rows),asc=th.dataset.asc!=='1';th.dataset.asc=asc?'1':'0';
   var key=function(r){var s=r.cells[i].innerText,x=parseFloat(s.replace('\\u2212','-'));
    return isNaN(x)?s:x;};
   rows.sort(function(a,b){var x=key(a),y=key(b);
    if(typeof x===typeof y){return (x<y?-1:x>y?1:0)*(asc?1:-1);}
    return (typeof x==='number'?-1:1)*(asc?1:-1);});
   rows.forEach(function(r){t.tBodies[0].appendChild(r);});});});});
"""

_IMAGE = re.compile(r"^!\[([^\]]*)\]\(([^)]+)\)$")
#: How the lines of a fold start.
FOLD_LINES = ("<details>", "</details>")
_FOLD_OPEN = re.compile(r"^<details><summary>(.*)</summary>$")


_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")
#: Private-use offset holding a backslash-escaped character while the markup is rendered.
_HELD = 0xE000


def inline(text: str) -> str:
    """Escape ``text`` and render ``**bold**``, ``*italic*`` and ```code```; a
    backslash-escaped punctuation character (``\\[``) stands for itself."""
    held = _ESCAPED.sub(lambda m: chr(_HELD + ord(m.group(1))), text)
    out = html.escape(held, quote=False)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<b>\1</b>", out)
    out = re.sub(r"(?<![*\w])\*([^*\s][^*]*?[^*\s])\*(?![*\w])", r"<i>\1</i>", out)
    return re.sub("[\ue000-\ue07f]", lambda m: html.escape(chr(ord(m.group()) - _HELD)),
                  out)


def _fold(line: str) -> str:
    """A fold line as HTML: its title escaped; any other text after ``<details>`` is text."""
    title = _FOLD_OPEN.match(line)
    if title:
        return f"<details><summary>{inline(title.group(1))}</summary>"
    if line in FOLD_LINES:
        return line
    return f"<p>{inline(line)}</p>"


def _cells(line: str) -> list[str]:
    body = line.strip()[1:-1]
    return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", body)]


def _image(alt: str, name: str, folder: Path) -> str:
    """A figure of the report folder, embedded; only a plain ``.png`` name of a regular file
    in ``folder`` (never a path, a link or another file) is read."""
    path = folder / name
    if not plain_name(name, (".png",)) or path.is_symlink() or not path.is_file():
        return f"<p>(missing figure {html.escape(name)})</p>"
    data = base64.b64encode(path.read_bytes()).decode("ascii")
    return (f'<figure><img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{html.escape(alt)}</figcaption></figure>")


def to_html(markdown: str, folder: Path) -> str:
    """One HTML page of the report's Markdown; images are read from ``folder``."""
    return "".join(_page(markdown, folder))


def _page(markdown: str, folder: Path) -> Iterator[str]:
    """:func:`to_html` piece by piece (a figure at a time: the page of a large report
    embeds hundreds of megabytes of figures, never held at once)."""
    yield ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
           "<title>penaltyrun report</title>"
           f"<style>{STYLE}</style></head><body>\n")
    for k, part in enumerate(_blocks(markdown, folder)):
        if k:
            yield "\n"
        yield part
    yield f"\n<script>{SCRIPT}</script></body></html>\n"


def _blocks(markdown: str, folder: Path) -> Iterator[str]:
    """The HTML of each block of ``markdown`` (heading, table, list, figure, ...)."""
    lines = markdown.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
        elif line.startswith("#"):
            level = len(line) - len(line.lstrip("#"))
            yield f"<h{level}>{inline(line[level:].strip())}</h{level}>"
            i += 1
        elif line.startswith("```"):
            block = []
            i += 1
            while i < len(lines) and not lines[i].startswith("```"):
                block.append(lines[i])
                i += 1
            yield "<pre>" + html.escape("\n".join(block), quote=False) + "</pre>"
            i += 1
        elif line.startswith(FOLD_LINES):
            yield _fold(line.strip())
            i += 1
        elif line.startswith("|"):
            block = []
            while i < len(lines) and lines[i].startswith("|"):
                block.append(lines[i])
                i += 1
            head = "".join(f"<th>{inline(c)}</th>" for c in _cells(block[0]))
            rows = "".join("<tr>" + "".join(f"<td>{inline(c)}</td>" for c in _cells(r))
                           + "</tr>" for r in block[2:])
            yield f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>"
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{inline(lines[i][2:])}</li>")
                i += 1
            yield "<ul>" + "".join(items) + "</ul>"
        elif _IMAGE.match(line.strip()):
            alt, name = _IMAGE.match(line.strip()).groups()
            yield _image(alt, name, folder)
            i += 1
        else:
            para = []
            while i < len(lines) and lines[i].strip() and not lines[i].startswith(
                    ("#", "|", "- ", "![", "```") + FOLD_LINES):
                para.append(lines[i])
                i += 1
            yield f"<p>{inline(' '.join(para))}</p>"


def write_html(markdown: str, folder: Path, path: Path) -> Path:
    """Write :func:`to_html` of ``markdown`` (figures from ``folder``) to ``path``, one
    piece at a time."""
    with path.open("w", encoding="utf-8") as fh:
        for piece in _page(markdown, folder):
            fh.write(piece)
    return path


__all__ = ["inline", "to_html", "write_html"]
