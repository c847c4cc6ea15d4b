"""The command line writes its figures with matplotlib's Agg backend unless MPLBACKEND
names another (the report modules themselves choose none)."""

from __future__ import annotations

import os


def test_the_command_line_writes_figures_with_agg(monkeypatch):
    from penaltyrun import cli

    monkeypatch.delenv("MPLBACKEND", raising=False)
    cli.use_file_backend()
    assert os.environ["MPLBACKEND"] == "Agg"
    monkeypatch.setenv("MPLBACKEND", "pdf")
    cli.use_file_backend()
    assert os.environ["MPLBACKEND"] == "pdf"
