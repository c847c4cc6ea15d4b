"""The provenance paragraph of a results page: versions and machine, no commit hashes."""

import re
from types import SimpleNamespace

from penaltyrun.docsgen import results


def paragraph(info: dict, monkeypatch) -> str:
    """The provenance paragraph of a study ``demo`` whose provenance is ``info``."""
    monkeypatch.setattr(results.Context, "study",
                        lambda self, name: SimpleNamespace(provenance=info))
    return results.Context.__new__(results.Context).provenance("demo")


def test_paragraph_counts_commits_and_names_none(monkeypatch):
    text = paragraph({"jobs": 3, "status": {"ok": 3},
                      "machine": {"cpu": "cpu", "cores": 2, "os": "os"},
                      "packages": {"numpy": "2.0"}, "packages_in_records": [],
                      "git_commits": ["a" * 40, "b" * 40]}, monkeypatch)
    assert "numpy 2.0" in text and "2 cores" in text
    assert "git commits of the records: 2 (`studies/demo/provenance.json`)" in text
    assert not re.search(r"\b[0-9a-f]{40}\b", text)


def test_records_from_two_machines_name_both(monkeypatch):
    hosts = [{"cpu": "cpu A", "cores": 2, "os": "os"}, {"cpu": "cpu B", "cores": 4, "os": "os"}]
    text = paragraph({"jobs": 2, "status": {"ok": 2}, "machine": hosts[0], "machines": hosts,
                      "packages": {}, "packages_in_records": [], "git_commits": []},
                     monkeypatch)
    assert "machines: cpu A, 2 cores, os; cpu B, 4 cores, os;" in text


def test_versions_from_the_records_leave_their_commit_out(monkeypatch):
    record = '{"numpy": "2.0", "git_commit": "' + "c" * 40 + '"}'
    text = paragraph({"jobs": 1, "status": {"ok": 1}, "machine": {}, "packages": {},
                      "packages_in_records": [record], "git_commits": ["c" * 40]},
                     monkeypatch)
    assert "numpy 2.0" in text and "c" * 40 not in text


def test_no_user_page_carries_a_commit_hash():
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    pages = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    carrying = [p.relative_to(root).as_posix() for p in pages
                if re.search(r"\b[0-9a-f]{40}\b", p.read_text(encoding="utf-8"))]
    assert carrying == []
