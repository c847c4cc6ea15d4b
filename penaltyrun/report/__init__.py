"""Tables and figures from Parquet results only."""

from penaltyrun.report.build import build_report

__all__ = ["build_report"]
