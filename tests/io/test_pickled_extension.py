"""A Parquet file declaring a pickled pyarrow extension type (``arrow.py_extension_type``,
CVE-2023-47248) is refused from its footer: nothing is unpickled, one warning names the
file, the rest of the folder is read; the dependency floor excludes vulnerable pyarrow."""

import logging
import pickle
import re
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import tomllib

from penaltyrun.io import filecheck, read
from penaltyrun.io.schema import RESULTS_FILE, to_table

ROOT = Path(__file__).resolve().parents[2]


class _Payload:
    """Unpickling this touches a marker file (what an attacker's os.system would do)."""

    def __init__(self, marker: str) -> None:
        self.marker = marker

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _record(start: int) -> dict:
    return {"job_id": f"zermelo-default-full-pso-abc-s{start:03d}", "problem": "zermelo",
            "case": "default", "param": "full", "optimizer": "pso", "start": start,
            "seed": start, "status": "ok", "best_cost": 1.0 + start, "n_evals": 10,
            "config_hash": "h1"}


def _with_pickled_extension(table: pa.Table, marker: Path) -> pa.Table:
    """``table`` whose ``job_id`` field declares the pickled Python extension type."""
    meta = {b"ARROW:extension:name": b"arrow.py_extension_type",
            b"ARROW:extension:metadata": pickle.dumps(_Payload(str(marker)))}
    fields = [f.with_metadata(meta) if f.name == "job_id" else f for f in table.schema]
    return table.cast(pa.schema(fields))


def test_a_pickled_extension_type_is_refused_and_the_rest_is_read(tmp_path, caplog):
    marker = tmp_path / "UNPICKLED"
    good, bad = tmp_path / "good", tmp_path / "bad"
    good.mkdir()
    bad.mkdir()
    pq.write_table(to_table([_record(0)], "good"), good / RESULTS_FILE)
    pq.write_table(_with_pickled_extension(to_table([_record(1)], "bad"), marker),
                   bad / RESULTS_FILE)
    with caplog.at_level(logging.WARNING):
        df = read.read_results(tmp_path)
    assert list(df["start"]) == [0]
    assert df.attrs["skipped_files"].keys() == {str(bad / RESULTS_FILE)}
    lines = [r.getMessage() for r in caplog.records if "extension type" in r.getMessage()]
    assert len(lines) == 1 and str(bad / RESULTS_FILE) in lines[0]
    assert not marker.exists()


def test_penaltyrun_output_declares_no_extension_type(tmp_path):
    pq.write_table(to_table([_record(0)], "run"), tmp_path / RESULTS_FILE)
    assert filecheck.check_footer(tmp_path / RESULTS_FILE) is None


def test_the_pyarrow_floor_excludes_the_unpickling_versions():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    floor = next(d for d in deps["project"]["dependencies"] if d.startswith("pyarrow"))
    version = tuple(int(x) for x in re.search(r">=\s*([\d.]+)", floor).group(1).split("."))
    assert version >= (14, 0, 1)
