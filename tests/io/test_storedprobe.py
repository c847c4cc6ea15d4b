"""Cliff probes stored beside results: written and read back exactly, used only for the
same start, point and ladder, and a damaged or hostile file is skipped with one warning
naming it (its probes are then computed)."""

from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import storedprobe
from penaltyrun.io.schema import read_results
from penaltyrun.optim.probe import STEPS, probe
from penaltyrun.report import cliffs
from penaltyrun.report.bestknown import best_rows

GOLDEN = Path(__file__).resolve().parents[1] / "report" / "golden" / "zermelo" / "input"


def _quadratic_probe(n: int = 3) -> tuple[np.ndarray, object]:
    z = np.linspace(0.0, 0.6, n)  # the first variable on its lower bound

    def cost(batch):
        batch = np.asarray(batch)
        return 1.0 + ((batch - 0.4) ** 2).sum(axis=1), batch[:, 0] < 0.9

    return z, probe(cost, z, np.zeros(n), np.ones(n) * 0.8 + 0.1 * np.arange(n), STEPS)


def test_written_probe_reads_back_bit_for_bit(tmp_path):
    z, result = _quadratic_probe()
    path = storedprobe.write(tmp_path / storedprobe.PROBE_FILE,
                             [storedprobe.record("job-1", "abc", z, result)],
                             {"git_commit": "x"})
    frame = storedprobe.read_one(path)
    got = storedprobe.lookup(frame, "job-1", "abc", z, STEPS)
    assert got is not None
    np.testing.assert_array_equal(got.steps, result.steps)
    np.testing.assert_array_equal(got.change, result.change)  # NaN where out of the box
    np.testing.assert_array_equal(got.status_change, result.status_change)
    assert got.cost == result.cost and got.converged == result.converged
    assert np.isnan(got.change).any()  # the ladder leaves the box at one side
    assert pq.read_metadata(path).metadata[storedprobe.METADATA_KEY] == b'{"git_commit": "x"}'


def test_used_only_for_the_same_start_point_and_ladder(tmp_path):
    z, result = _quadratic_probe()
    frame = storedprobe.read_one(storedprobe.write(
        tmp_path / storedprobe.PROBE_FILE, [storedprobe.record("job-1", None, z, result)], {}))
    assert storedprobe.lookup(frame, "job-1", None, z, STEPS) is not None
    assert storedprobe.lookup(frame, "job-1", float("nan"), z, STEPS) is not None  # missing
    assert storedprobe.lookup(frame, "job-2", None, z, STEPS) is None
    assert storedprobe.lookup(frame, "job-1", "other", z, STEPS) is None
    moved = z.copy()
    moved[1] = np.nextafter(moved[1], 1.0)  # one ulp away
    assert storedprobe.lookup(frame, "job-1", None, moved, STEPS) is None
    assert storedprobe.lookup(frame, "job-1", None, z[:2], STEPS) is None
    assert storedprobe.lookup(frame, "job-1", None, z, STEPS[:3]) is None
    assert storedprobe.lookup(None, "job-1", None, z, STEPS) is None


def _table(**replace) -> pa.Table:
    z, result = _quadratic_probe()
    row = storedprobe.record("job-1", "abc", z, result)
    row.update(replace)
    return pa.Table.from_pylist([row])


@pytest.mark.parametrize(("replace", "message"), [
    ({"change": [0.1] * 5}, "change does not hold 24"),
    ({"change": [float("inf")] * 24}, "change does not hold 24"),
    ({"status_change": [True] * 3}, "status_change does not hold 24"),
    ({"best_z": [float("nan"), 0.1, 0.2]}, "best_z is not a finite vector"),
    ({"best_z": []}, "best_z is not a finite vector"),
    ({"best_z": [None, 0.1, 0.2]}, "best_z is not a finite vector"),
    ({"best_z": None}, "best_z is not a finite vector"),
    ({"status_change": [True] * 23 + [None]}, "status_change does not hold 24"),
    ({"change": None}, "change does not hold 24"),
    ({"converged": None}, "converged is not true or false"),
    ({"steps": [1e-3, 1e-4, 1e-5, 1e-6]}, "steps are not increasing"),
    ({"steps": [-1.0, 1e-4, 1e-3, 1e-2]}, "steps are not increasing"),
    ({"cost": 0.0}, "cost is not a finite non-zero number"),
    ({"cost": float("inf")}, "cost is not a finite non-zero number"),
    ({"job_id": ""}, "a row without a job id"),
    ({"cost": "cheap"}, "a column of the wrong type"),
])
def test_a_row_failing_its_check_refuses_the_file(tmp_path, replace, message):
    path = tmp_path / storedprobe.PROBE_FILE
    pq.write_table(_table(**replace), path)
    with pytest.raises((ValueError, KeyError), match=message):
        storedprobe.read_one(path)


def test_a_missing_column_refuses_the_file(tmp_path):
    path = tmp_path / storedprobe.PROBE_FILE
    pq.write_table(_table().drop_columns(["status_change"]), path)
    with pytest.raises(KeyError, match="no column status_change"):
        storedprobe.read_one(path)


def _study(tmp_path: Path) -> Path:
    folder = tmp_path / "study"
    folder.mkdir()
    shutil.copy(GOLDEN / "results.parquet", folder / "results.parquet")
    return folder


def _stored_rows(df: pd.DataFrame) -> list[dict]:
    rows = []
    for row in best_rows(df).values():
        result, _ = cliffs.probe_row(row)
        rows.append(storedprobe.record(row["job_id"], row["config_hash"], row["best_z"],
                                       result))
    return rows


@pytest.mark.parametrize("damage", ["bytes", "directory", "symlink", "extension"])
def test_a_damaged_file_is_skipped_with_one_warning_naming_it(tmp_path, caplog, damage):
    folder = _study(tmp_path)
    path = folder / storedprobe.PROBE_FILE
    if damage == "bytes":
        path.write_bytes(b"PAR1 not parquet PAR1")
    elif damage == "directory":
        path.mkdir()
    elif damage == "symlink":
        target = tmp_path / "elsewhere.parquet"
        storedprobe.write(target, _stored_rows(read_results(folder / "results.parquet")), {})
        os.symlink(target, path)
    else:
        table = _table()
        meta = {b"ARROW:schema": b"ARROW:extension:name pickled"}
        pq.write_table(table.replace_schema_metadata(meta), path)
    with caplog.at_level(logging.WARNING):
        frame = storedprobe.read_beside([folder / "results.parquet"])
    assert frame.empty and list(frame.columns) == list(storedprobe.COLUMNS)
    warned = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    if damage in ("bytes", "extension"):
        assert len(warned) == 1 and str(path) in warned[0] and "skipped" in warned[0]
    else:  # not a regular file: not read at all
        assert warned == []


def test_the_report_reads_a_stored_probe_and_draws_the_same_section(tmp_path):
    folder = _study(tmp_path)
    df = read_results(folder / "results.parquet")
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
    computed = cliffs.section(df, tmp_path / "a", "z")
    storedprobe.write(folder / storedprobe.PROBE_FILE, _stored_rows(df), {})
    stored = storedprobe.read_beside([folder / "results.parquet"])
    assert len(stored) == 2
    read = cliffs.section(df, tmp_path / "b", "z", stored)
    note = [i for i, line in enumerate(read) if "read from `probe.parquet`" in line]
    assert len(note) == 1 and "diagonal and full point" in read[note[0]]
    assert read[:note[0]] + read[note[0] + 2:] == computed
    assert (tmp_path / "a" / "cliffs_z.png").read_bytes() == \
        (tmp_path / "b" / "cliffs_z.png").read_bytes()


def test_a_stored_probe_of_another_size_is_not_used(tmp_path):
    folder = _study(tmp_path)
    df = read_results(folder / "results.parquet")
    row = best_rows(df)["full"]
    z, result = _quadratic_probe(len(row["best_z"]) + 1)
    wrong = storedprobe.record(row["job_id"], row["config_hash"], row["best_z"], result)
    wrong["best_z"] = list(row["best_z"])  # the right point, a probe of another layout
    stored = pd.DataFrame([wrong])
    probed, names = cliffs.probe_row(row, stored=stored)
    assert probed.change.shape == (len(STEPS), len(row["best_z"]), 2)
    assert probed.cost == pytest.approx(row["best_cost"], rel=1e-9)
