"""The answer table of the README and the docs home: every row states its held-out result
beside its training result, and the held-out words come from the report's held-out table."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from penaltyrun.docsgen import resultpages, results

ROOT = Path(__file__).resolve().parents[2]
#: Rows that answer a question about an optimizer's fidelity, not diagonal against full.
FIDELITY = ("reproduce the authors'", "differ from the authors'")


def answer_rows(path: Path) -> list[tuple[str, str]]:
    text = path.read_text(encoding="utf-8")
    block = text[text.index(resultpages.README_START):text.index(resultpages.README_END)]
    rows = [line for line in block.splitlines() if line.startswith("| ")][1:]  # no header
    cells = [[c.strip() for c in re.split(r"(?<!\\)\|", row)[1:-1]] for row in rows]
    assert all(len(c) == 3 for c in cells), "a row of the answer table lost a cell"
    return [(c[0], c[1]) for c in cells]


@pytest.mark.parametrize("page", [ROOT / "README.md", ROOT / resultpages.DOCS_HOME],
                         ids=["README", "docs-home"])
def test_every_answer_states_its_held_out_result(page):
    rows = answer_rows(page)
    assert len(rows) >= 9
    for question, answer in rows:
        assert "held-out" in answer.lower(), question
        if any(f in question for f in FIDELITY):
            assert "Held-out: not part of this question" in answer, question
            continue
        # the statistic, its n and the horizon the held-out scenarios were judged at
        assert "J_full/J_diag" in answer and "Wilcoxon signed-rank" in answer, question
        assert re.search(r"full cheaper on \d+/\d+|costs more in \d+ of \d+", answer), question
        assert "judged at horizon T = " in answer or "horizon T = " in answer, question


def test_held_out_words_are_the_held_out_tables():
    ctx = results.Context(ROOT)
    table = ctx.study("referee_zermelo").table("holdout")
    row = table[table["optimizer"] == "best-known (all optimizers)"].iloc[0]
    words = ctx.held_out_words("referee_zermelo", "zermelo", "default")
    assert f"full cheaper on {int(row['full_cheaper'])}/{int(row['scenarios'])}" in words
    assert f"median J_full/J_diag {results.fmt(row['ratio_median'], '.3g')}" in words
    assert f"judged at horizon T = {row['horizon']:g}" in words
    with pytest.raises(ValueError, match="best-known held-out rows"):
        ctx.held_out_words("referee_zermelo", "zermelo", "no_such_case")


def test_answers_are_the_verdict_sentences():
    ctx = results.Context(ROOT)
    verdict = pd.read_csv(ROOT / "studies" / "mpc_rendezvous" / "tables" / "verdict.csv")
    assert ctx.answers("mpc_rendezvous", {"problem": "mpc_rendezvous"}) == \
        list(verdict["sentence"])
    with pytest.raises(ValueError, match="no verdict row"):
        ctx.answers("mpc_rendezvous", {"problem": "zermelo"})
