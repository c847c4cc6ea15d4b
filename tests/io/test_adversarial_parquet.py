"""Damaged and adversarial Parquet files in a results folder: each is skipped with one
warning naming it, nothing is decoded beyond the limits, the rest of the folder is read."""

import logging
import os

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import filecheck, read
from penaltyrun.io.longholdout import LONG_FILE
from penaltyrun.io.schema import RESULTS_FILE, to_table

IDENTITY = filecheck.IDENTITY_COLUMNS


def _record(start: int) -> dict:
    return {"job_id": f"zermelo-default-full-pso-abc-s{start:03d}", "problem": "zermelo",
            "case": "default", "param": "full", "optimizer": "pso", "start": start,
            "seed": start, "status": "ok", "best_cost": 1.0 + start, "n_evals": 10,
            "config_hash": "h1"}


def _good(folder):
    folder.mkdir(parents=True, exist_ok=True)
    pq.write_table(to_table([_record(0)], "good"), folder / RESULTS_FILE)
    return folder / RESULTS_FILE


def _huge_rows(path):
    """A 1 MB file declaring more rows than the limit (all-null identity columns)."""
    n = filecheck.MAX_FILE_ROWS + 1
    pq.write_table(pa.table({c: pa.nulls(n) for c in IDENTITY}), path)


def _dictionary_bomb(path):
    """A 50 kB file whose ``job_id`` is one 1 MB text referred to by 5 000 rows: 5 GB once
    decoded, invisible in the footer."""
    n = 5000
    text = pa.DictionaryArray.from_arrays(pa.array(np.zeros(n, dtype=np.int32)),
                                          pa.array(["x" * 1_000_000]))
    pq.write_table(pa.table({"job_id": text, **{c: pa.array(["a"] * n) for c in IDENTITY
                                                 if c != "job_id"}}), path)


def _truncated(path):
    good = to_table([_record(1)], "t")
    pq.write_table(good, path)
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _random_bytes(path):
    rng = np.random.default_rng(7)
    path.write_bytes(rng.bytes(4096))


def _random_with_magic(path):
    """Parquet's magic bytes around random ones: the footer length read is garbage."""
    rng = np.random.default_rng(8)
    path.write_bytes(b"PAR1" + rng.bytes(4096) + b"PAR1")


def _wrong_types(path):
    """The identity columns present, but ``status`` a list of integers and ``best_cost``
    text."""
    pq.write_table(pa.table({**{c: ["a"] for c in IDENTITY if c != "status"},
                             "status": pa.array([[1, 2]]), "best_cost": ["cheap"]}), path)


def _wrong_schema(path):
    pq.write_table(pa.table({"x": [1.0, 2.0], "y": ["a", "b"]}), path)


def _deep_json(path):
    """Optimizer settings of 100 000 nested lists (JSON the reader must parse)."""
    record = {**_record(1), "optimizer": "pso_matlab",
              "optimizer_settings": "[" * 100_000 + "]" * 100_000}
    pq.write_table(to_table([record], "deep"), path)


def _deep_params(path):
    """Problem parameters of 100 000 nested lists (the report groups cells by them)."""
    record = {**_record(1), "problem_params": "[" * 100_000 + "]" * 100_000}
    pq.write_table(to_table([record], "deep"), path)


def _bad_options(path):
    pq.write_table(to_table([{**_record(1), "param_options": "{oops"}], "bad"), path)


def _null_problem(path):
    pq.write_table(to_table([{**_record(1), "problem": None}], "null"), path)


def _with(**values):
    """A writer of one record of :func:`_record` with ``values`` stored in its columns."""
    def make(path):
        pq.write_table(to_table([{**_record(1), **values}], "bad"), path)
    return make


def _no_start(path):
    pq.write_table(to_table([_record(1)], "bad").drop(["start"]), path)


DEEP = "[" * 100_000 + "]" * 100_000
CONTENT = {"minus infinite cost": (_with(best_cost=-np.inf), "column best_cost holds -inf"),
           "ok job without a cost": (_with(best_cost=np.nan), "a job of status ok has no "
                                                             "finite best_cost"),
           "ok job of infinite cost": (_with(best_cost=np.inf), "a job of status ok has no "
                                                                "finite best_cost"),
           "matrices not an object": (_with(matrices=[1, 2]), "column matrices holds a JSON "
                                                              "list where an object"),
           "ragged matrix": (_with(matrices={"K": [[1.0, 2.0], [3.0]]}),
                             "matrix 'K', which is not a rectangular array"),
           "matrix of text": (_with(matrices={"K": [["a", "b"], ["c", "d"]]}),
                              "not a rectangular array of numbers"),
           "scalar matrix": (_with(matrices={"K": 5.0}), "not a rectangular array"),
           "deep matrices": (_with(matrices=DEEP), "column matrices holds text that is not "
                                                   "usable JSON (JSON nested"),
           "deep metrics": (_with(metrics=DEEP), "column metrics holds text"),
           "matrices not JSON": (_with(matrices="{oops"), "column matrices holds text"),
           "held-out costs not numbers": (_with(holdout={"cost": "cheap",
                                                                  "converged": [True]}),
                                          "held-out costs that are not a list of numbers"),
           "held-out lists of two lengths": (_with(holdout={"cost": [1.0], "x0": [1, 2]}),
                                             "held-out lists of different lengths"),
           "optimizer settings a list": (_with(optimizer_settings=[1, 2]),
                                         "column optimizer_settings holds a JSON list"),
           "no start column": (_no_start, "not penaltyrun results (no column start)"),
           "integer beyond the floats": (_with(matrices={"K": [[10 ** 400, 0], [0, 1]]}),
                                         "not a rectangular array of numbers"),
           "missing matrix entry": (_with(matrices={"K": [[1.0, None], [None, 1.0]]}),
                                    "not a rectangular array of numbers"),
           "held-out entry not a list": (_with(holdout={"cost": [1.0], "scenario": 7}),
                                         "per-scenario entries are not all lists"),
           "held-out cost of minus infinity": (_with(holdout={"cost": [1.0, -np.inf]}),
                                               "held-out costs of -inf"),
           "trace of minus infinity": (_with(trace_evals=[1, 2], trace_best=[1.0, -np.inf]),
                                       "column trace_best holds -inf"),
           "history of minus infinity": (_with(history=[-np.inf, np.inf, np.nan]),
                                         "column history holds -inf"),
           "negative arrival time": (_with(t_final=-np.inf), "column t_final holds negative"),
           "negative wall time": (_with(wall_time_s=-1.0), "column wall_time_s holds negative"),
           "negative CPU trace": (_with(trace_evals=[1], trace_best=[1.0],
                                        trace_cpu_s=[-0.5]), "trace_cpu_s holds negative"),
           "scalar that is an object": (_with(scalars={"t_max": {"deep": [1]}}),
                                        "scalars that are not all numbers"),
           "scalar that is text": (_with(scalars={"w": "heavy"}),
                                   "scalars that are not all numbers"),
           "scalar that is null": (_with(scalars={"w": None}),
                                   "scalars that are not all numbers"),
           "energy that is text": (_with(metrics={"criterion": "time_energy", "rho": 1.0,
                                                  "energy": "abc"}),
                                   "a metrics entry 'energy' that is not a number"),
           "optimum that is a list": (_with(metrics={"method": "care", "optimum": [1.0]}),
                                      "a metrics entry 'optimum' that is not a number"),
           "criterion that is a number": (_with(metrics={"criterion": 3}),
                                          "a metrics entry 'criterion' that is not text"),
           "held-out converged as text": (_with(holdout={"cost": [1.0, 2.0],
                                                         "converged": ["yes", "no"]}),
                                          "'converged' that is not a list of true/false"),
           "held-out converged as numbers": (_with(holdout={"cost": [1.0],
                                                            "converged": [1]}),
                                             "'converged' that is not a list of true/false"),
           "held-out arrival as text": (_with(holdout={"cost": [1.0],
                                                       "arrival_time": ["late"]}),
                                        "'arrival_time' that is not a list of numbers"),
           "held-out status as numbers": (_with(holdout={"cost": [1.0], "status": [0]}),
                                          "'status' that is not a list of texts"),
           "held-out horizon as text": (_with(holdout={"cost": [1.0], "horizon": "long"}),
                                        "'horizon' that is not a number"),
           "training scenario as text": (_with(holdout={"cost": [1.0], "training": "x"}),
                                         "'training' that is not an object"),
           "training cost as text": (_with(holdout={"cost": [1.0],
                                                    "training": {"converged": True,
                                                                 "cost": "low"}}),
                                     "'training' that is not an object")}

HOSTILE = {**CONTENT,
           "null problem": (_null_problem, "column problem has 1 empty values"),
           "deep JSON": (_deep_json, "column optimizer_settings holds text that is not"),
           "deep problem parameters": (_deep_params, "column problem_params holds text "
                                                     "that is not usable JSON (JSON nested"),
           "damaged parameterization options": (_bad_options, "column param_options"),
           "deep warm start": (_with(warm_start=DEEP), "column warm_start holds text that "
                                                       "is not usable JSON"),
           "huge declared row count": (_huge_rows, f"declares {filecheck.MAX_FILE_ROWS + 1} rows"),
           "dictionary bomb": (_dictionary_bomb, "bytes when read (the limit is"),
           "truncated": (_truncated, ""),
           "random bytes": (_random_bytes, ""),
           "random bytes in Parquet's magic": (_random_with_magic, ""),
           "wrong column types": (_wrong_types, "column"),
           "wrong schema": (_wrong_schema, "not penaltyrun results")}


@pytest.mark.parametrize("kind", sorted(HOSTILE))
def test_b8_a_hostile_file_is_skipped_with_one_warning_and_the_rest_read(tmp_path, caplog, kind):
    make, words = HOSTILE[kind]
    _good(tmp_path / "good")
    bad = tmp_path / "bad" / RESULTS_FILE
    bad.parent.mkdir()
    make(bad)
    with caplog.at_level(logging.WARNING):
        df = read.read_results(tmp_path)
    assert list(df["start"]) == [0]
    assert set(df.attrs["skipped_files"]) == {str(bad)}
    lines = [r.getMessage() for r in caplog.records if str(bad) in r.getMessage()]
    assert len(lines) == 1 and words in lines[0], lines


def test_a_declared_uncompressed_size_over_the_limit_is_refused_from_the_footer(
        tmp_path, monkeypatch, caplog):
    _good(tmp_path / "good")
    bad = tmp_path / "bad" / RESULTS_FILE
    bad.parent.mkdir()
    table = to_table([_record(1)], "bad")
    pq.write_table(table.set_column(table.column_names.index("error"), "error",
                                    pa.array(["e" * 3_000_000])), bad, compression="zstd")
    assert os.path.getsize(bad) < 100_000  # compressed: small on disk
    monkeypatch.setattr(filecheck, "MAX_FILE_BYTES", 2_000_000)
    original = read.read_bounded

    def never_the_bad_file(path, columns=None):
        assert path != bad, "read beyond its footer"
        return original(path, columns)

    monkeypatch.setattr(read, "read_bounded", never_the_bad_file)
    df = read.read_results(tmp_path)
    assert list(df["start"]) == [0]
    assert "uncompressed (the limit is 2000000 per file)" in df.attrs["skipped_files"][str(bad)]


def test_text_within_the_limit_is_read_as_plain_text(tmp_path):
    path = _good(tmp_path)
    table = filecheck.read_bounded(path)
    assert table.equals(pq.read_table(path))
    assert not any(pa.types.is_dictionary(f.type) for f in table.schema)


def test_a_damaged_rejudged_file_leaves_the_stored_held_out_data(tmp_path, caplog):
    path = _good(tmp_path)
    (tmp_path / LONG_FILE).write_bytes(b"PAR1 damaged")
    with caplog.at_level(logging.WARNING):
        df = read.read_results(path)
    assert list(df["start"]) == [0] and not df.attrs["skipped_files"]
    assert f"skipped re-judged held-out file {tmp_path / LONG_FILE}" in caplog.text


def test_decode_json_turns_too_deep_into_a_value_error():
    from penaltyrun.io.schema import decode_json

    with pytest.raises(ValueError, match="nested too deep"):
        decode_json("[" * 100_000 + "]" * 100_000)
    assert decode_json('{"a": [1]}') == {"a": [1]}


def test_a_folder_named_like_a_results_file_is_named_once(tmp_path, caplog):
    """Counting the declared rows (which a report does first) says nothing; reading says
    once that the folder is not a regular file."""
    _good(tmp_path / "good")
    (tmp_path / "bad" / RESULTS_FILE).mkdir(parents=True)
    with caplog.at_level(logging.WARNING):
        assert read.declared_rows(tmp_path) == 1
        read.read_results(tmp_path)
    lines = [r.getMessage() for r in caplog.records if "not a regular file" in r.getMessage()]
    assert len(lines) == 1


def test_entries_of_the_problems_own_beside_the_typed_ones_are_read(tmp_path):
    """Only the entries the report reads are typed: a problem's own metrics and per-scenario
    held-out data of any kind, and null where a typed entry is missing, are read."""
    path = tmp_path / RESULTS_FILE
    _with(metrics={"objective": "min_fuel", "energy": None, "limits": {"u": [1, 2]}},
          holdout={"cost": [1.0, None], "converged": [True, None], "x0": [[1, 2], "a"],
                   "horizon": 10.0, "training": {"scenario": 3, "converged": None}},
          scalars={"t_max": 3, "w": 1e300})(path)
    df = read.read_results(path)
    assert list(df["start"]) == [1] and not df.attrs.get("skipped_files")
