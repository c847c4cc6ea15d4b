"""``python -m penaltyrun.report_cli INPUT [-o OUTPUT]`` — same as ``penaltyrun-report``."""

from penaltyrun.cli import report_main

if __name__ == "__main__":
    report_main()
