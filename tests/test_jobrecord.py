"""The job record is defined once (penaltyrun.jobrecord): the Parquet schema and the record
checks are derived from its fields, and no other module restates its statuses."""

from __future__ import annotations

import ast
from pathlib import Path

import pyarrow as pa
import pytest

import penaltyrun
from penaltyrun import jobrecord
from penaltyrun.io import schema
from penaltyrun.runner import validate

PACKAGE = Path(penaltyrun.__file__).parent
STATUSES = set(jobrecord.JOB_STATUSES)
#: Kinds the record checks do not check (nested values, times).
UNCHECKED = {jobrecord.JSON, jobrecord.TIME}


def test_parquet_columns_are_the_record_fields_in_order():
    columns = [name for name, field in jobrecord.FIELDS.items() if field.column]
    assert list(schema.COLUMNS) == columns
    assert schema.SCHEMA.names == columns
    assert {name for name, f in jobrecord.FIELDS.items() if not f.column} == {"module_hash"}


def test_parquet_types_follow_the_kinds():
    for name, field in jobrecord.FIELDS.items():
        if field.column:
            assert schema.SCHEMA.field(name).type == schema.ARROW_TYPES[field.kind], name
    assert schema.SCHEMA.field("status").type == pa.string()
    assert schema.SCHEMA.field("start").type == pa.int64()
    assert schema.SCHEMA.field("trace_evals").type == pa.list_(pa.int64())
    assert schema.SCHEMA.field("started_at").type == pa.timestamp("us", tz="UTC")
    assert schema.JSON_COLUMNS == ("matrices", "scalars", "metrics", "holdout", "closed_loop",
                                   "warm_start", "optimizer_settings", "problem_params",
                                   "param_options", "packages")
    assert schema.TIMESTAMP_COLUMNS == ("started_at", "finished_at")


def test_the_record_checks_cover_every_checkable_field_once():
    checked = [*validate.REQUIRED, *validate.REQUIRED_FINISHED, *validate.OPTIONAL]
    assert len(checked) == len(set(checked))
    assert set(checked) == {name for name, f in jobrecord.FIELDS.items()
                            if f.kind not in UNCHECKED}
    assert list(validate.REQUIRED) == ["job_id", "problem", "case", "param", "optimizer",
                                       "start", "seed", "status"]
    assert validate.REQUIRED_FINISHED == {"best_cost": jobrecord.NUMBER}
    for name, kind in {**validate.REQUIRED, **validate.OPTIONAL}.items():
        assert jobrecord.FIELDS[name].kind == kind


@pytest.mark.parametrize("name", [n for n, f in jobrecord.FIELDS.items()  # its own message
                                  if f.kind not in UNCHECKED and not f.required
                                  and n != "schema_version"])
def test_every_checked_optional_field_refuses_a_wrong_type(name):
    record = {"job_id": "j", "problem": "p", "case": "c", "param": "full",
              "optimizer": "pso", "start": 0, "seed": 1, "status": jobrecord.OK,
              "best_cost": 1.0, name: {"not": "this"}}
    assert validate.record_problem(record) == (
        f"{name} must be {jobrecord.FIELDS[name].kind}, got {{'not': 'this'}}")


def _string_elements(node: ast.AST) -> list[str] | None:
    if not isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return None
    if not all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in node.elts):
        return None
    return [e.value for e in node.elts]


def _is_status_lookup(node: ast.AST) -> bool:
    """``x["status"]`` or ``x.get("status")``."""
    if isinstance(node, ast.Subscript):
        return isinstance(node.slice, ast.Constant) and node.slice.value == "status"
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
        return (node.func.attr == "get" and bool(node.args)
                and isinstance(node.args[0], ast.Constant) and node.args[0].value == "status")
    return False


def restated_statuses(source: str) -> list[int]:
    """Lines of ``source`` that restate job statuses: a literal collection of two or more
    of them, or a record's status compared with a literal status."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        strings = _string_elements(node)
        if strings is not None and len(strings) >= 2 and set(strings) <= STATUSES:
            lines.append(node.lineno)
        if isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            literal = any(isinstance(s, ast.Constant) and s.value in STATUSES for s in sides)
            if literal and any(_is_status_lookup(s) for s in sides):
                lines.append(node.lineno)
    return lines


def test_the_scan_finds_restated_statuses():
    assert restated_statuses('ok = j["status"] not in ("failed", "timeout")') == [1]
    assert restated_statuses('if record.get("status") == "failed": pass') == [1]
    assert restated_statuses('ok = (df["status"] == "ok")') == [1]
    assert restated_statuses('codes = ("diverged", "step_failure")') == []
    assert restated_statuses('reply = ("ok", 3)') == []


def test_no_module_restates_the_job_statuses():
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path == PACKAGE / "jobrecord.py":
            continue
        for line in restated_statuses(path.read_text(encoding="utf-8")):
            found.append(f"{path.relative_to(PACKAGE.parent)}:{line}")
    assert found == [], ("job statuses restated instead of imported from "
                         f"penaltyrun.jobrecord: {found}")


@pytest.mark.parametrize("search", ["max_evals", "ftol", "grid+local", "warm:iters|max_evals"])
@pytest.mark.parametrize("outcome", [jobrecord.POLISH_CONVERGED, "no_gradient", "max_evals"])
def test_a_polished_stop_reason_splits_back_into_the_search_and_the_polish_ending(search,
                                                                                  outcome):
    reason = jobrecord.polished_stop(search, outcome)
    assert reason.startswith(search + jobrecord.POLISH_TAG)
    assert jobrecord.split_stop(reason) == (search, outcome)


def test_a_stop_reason_without_a_polish_is_the_search_s_own():
    assert jobrecord.split_stop("grid+local") == ("grid+local", None)
    assert jobrecord.split_stop("max_evals") == ("max_evals", None)


@pytest.mark.parametrize("full", ["max_evals", jobrecord.polished_stop("ftol", "no_gradient")])
def test_the_final_search_of_a_warm_started_job_is_its_full_stage(full):
    diagonal = jobrecord.polished_stop("max_evals", jobrecord.POLISH_CONVERGED)
    reason = jobrecord.warm_stop(diagonal, full)
    assert reason.startswith(jobrecord.WARM_TAG)
    assert jobrecord.final_search_stop(reason) == jobrecord.split_stop(full)[0]
    assert jobrecord.final_search_stop(full) == jobrecord.split_stop(full)[0]
