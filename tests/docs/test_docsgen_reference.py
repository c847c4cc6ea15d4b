"""The reference pages are generated from the code: every optimizer option, runner option,
problem parameter, exit code and Parquet column appears, read from where it is defined."""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path

import pytest

from penaltyrun import cli
from penaltyrun.docsgen import reference
from penaltyrun.io import schema
from penaltyrun.optim import OPTIMIZERS
from penaltyrun.problems import REGISTRY
from penaltyrun.runner.options import RUNNER_OPTIONS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def pages() -> dict[str, str]:
    return reference.pages()


def test_every_config_key_is_listed(pages):
    text = pages["reference/config.md"]
    for name, entry in OPTIMIZERS.items():
        assert f"### `{name}`" in text
        for field in dataclasses.fields(entry.settings):
            assert f"`optimizer.{field.name}`" in text
    for key in RUNNER_OPTIONS:
        assert f"`runner.{key}`" in text
    for name, module_path in REGISTRY.items():
        params = importlib.import_module(module_path).Params
        for field in dataclasses.fields(params):
            assert f"`problem.params.{field.name}`" in text, (name, field.name)


def test_ranges_come_from_the_checks(pages):
    text = pages["reference/config.md"]
    row = next(line for line in text.splitlines() if line.startswith("| `optimizer.polish` |"))
    assert "`L-BFGS-B`" in row and "one of" in row
    row = next(line for line in text.splitlines()
               if line.startswith("| `optimizer.n_particles` |"))
    assert "a positive integer" in row


def test_exit_codes_and_schema(pages):
    codes = pages["reference/exit-codes.md"]
    for code, meaning in cli.EXIT_CODES.items():
        assert f"| {int(code)} |" in codes
        assert meaning.split("(")[0].strip().replace("|", "\\|") in codes
    assert "| 5 | `EXIT_ENVIRONMENT` |" in codes  # the machine refused a file operation
    columns = pages["reference/schema.md"]
    for name in schema.COLUMNS:
        assert f"| `{name}` |" in columns


def test_protocol_page_names_required_members(pages):
    text = pages["reference/problem-protocol.md"]
    from penaltyrun import problems
    for member in (*problems.MODULE_MEMBERS, *problems.PROBLEM_MEMBERS):
        assert f"`{member}`" in text
    for hook in ("report_info", "report_plots", "report_sections", "COST_UNIT",
                 "## `ReportInfo`", "## `PaperValues`", "## `ReportSection`"):
        assert hook in text


def test_problems_page_lists_every_registered_problem(pages):
    from penaltyrun import problems
    text = pages["reference/problems.md"]
    for name in problems.REGISTRY:
        assert f"| `{name}` |" in text
    assert "[Model predictive control](../explanation/mpc.md)" in text
    assert "[Tune your own controller](../tutorials/tune-your-lqr.md)" in text


def test_report_page_lists_every_report_table():
    from penaltyrun.report.build import TABLES
    text = (ROOT / "docs" / "reference" / "report.md").read_text()
    for stem in TABLES:
        assert f"`{stem}.csv`" in text


def test_generated_text_has_no_tracker_references(pages):
    for text in pages.values():
        assert "issue " not in text.lower().replace("tissue", "")
        assert "spec/" not in text


def test_report_page_states_the_code_limits_it_names():
    """The limits the report page states are the code's: the rows above which results are
    read lazily and the dots a scatter draws of one group."""
    from penaltyrun.report.build import STREAM_MIN_ROWS
    from penaltyrun.report.tables import MAX_DOTS
    text = " ".join((ROOT / "docs" / "reference" / "report.md").read_text().split())
    assert f"Above {STREAM_MIN_ROWS:,} jobs".replace(",", " ") in text
    assert f"draw at most {MAX_DOTS:,} starts".replace(",", " ") in text
