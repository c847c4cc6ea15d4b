"""The report's content is unchanged by how it is computed: every table (CSV and
Markdown), ``report.md`` and the list of figures of a report on committed results equal the
stored output of the report before its speed and memory work.

The expected files are under ``tests/report/golden/<name>/expected``; after an intended
change of the report's content, regenerate them with
``python tests/report/test_report_golden.py`` and review the diff.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest

from penaltyrun.report import build_report

GOLDEN = Path(__file__).parent / "golden"


def _report(name: str, out: Path, workers: int = 1) -> Path:
    return build_report(GOLDEN / name / "input", out, source_label="fixture", workers=workers)


def _compare(name: str, out: Path) -> None:
    expected = GOLDEN / name / "expected"
    figures = sorted(p.name for p in out.glob("*.png"))
    assert figures == (expected / "figures.txt").read_text(encoding="utf-8").split()
    for png in figures:
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    written = sorted(p.name for p in out.iterdir() if p.suffix in (".csv", ".md"))
    assert written == sorted(p.name for p in expected.iterdir()
                             if p.suffix in (".csv", ".md"))
    for stem in written:
        if stem.endswith(".csv"):
            pd.testing.assert_frame_equal(pd.read_csv(out / stem), pd.read_csv(expected / stem),
                                          check_exact=False, rtol=1e-9, obj=stem)
        else:
            assert (out / stem).read_text(encoding="utf-8") == \
                (expected / stem).read_text(encoding="utf-8"), stem


def test_report_of_one_study_is_unchanged(tmp_path):
    _compare("zermelo", _report("zermelo", tmp_path / "report"))


@pytest.mark.slow
def test_report_of_two_studies_is_unchanged(tmp_path):
    _compare("two_studies", _report("two_studies", tmp_path / "report"))


@pytest.mark.slow
def test_report_of_two_studies_is_unchanged_with_its_sections_in_two_workers(tmp_path):
    """The case sections (figures, probes, basin maps) written in worker processes."""
    _compare("two_studies", _report("two_studies", tmp_path / "report", workers=2))


def regenerate() -> None:
    """Rewrite the expected files from the current code (after an intended change)."""
    import tempfile

    for case in sorted(p.name for p in GOLDEN.iterdir() if p.is_dir()):
        expected = GOLDEN / case / "expected"
        with tempfile.TemporaryDirectory() as tmp:
            out = _report(case, Path(tmp) / "report")
            shutil.rmtree(expected, ignore_errors=True)
            expected.mkdir()
            for f in out.iterdir():
                if f.suffix in (".csv", ".md"):
                    shutil.copy(f, expected / f.name)
            (expected / "figures.txt").write_text(
                "".join(f"{p.name}\n" for p in sorted(out.glob("*.png"))), encoding="utf-8")
        print(f"regenerated {expected}", file=sys.stderr)


if __name__ == "__main__":
    regenerate()
