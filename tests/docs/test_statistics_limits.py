"""The statistics page states the sample sizes at which the report's intervals change
method as the code defines them."""

from pathlib import Path

from penaltyrun.report.stats import BCA_MAX_N

PAGE = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "statistics.md"


def _thousands(n: int) -> str:
    """``5000`` as the page writes it: ``5 000``."""
    return f"{n:,}".replace(",", " ")


def test_interval_thresholds_on_the_statistics_page_are_the_code_s():
    text = " ".join(PAGE.read_text(encoding="utf-8").split())
    assert f"more than {_thousands(BCA_MAX_N)} converged starts" in text
    assert "Large samples are resampled in batches" in text
