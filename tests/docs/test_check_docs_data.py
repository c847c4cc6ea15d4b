"""The docs check sees the committed data behind every table: a copy of a committed study
passes, and each of three edits to its data or tables fails the check (held-out costs, one
job's best cost, a stored p-value / share)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.docsgen import resultpages, tablecheck
from penaltyrun.io.longholdout import LONG_FILE

ROOT = Path(__file__).resolve().parents[2]
STUDY = "pso_matlab_zermelo"
TEMPLATE = ("# Demo\n\n{{ verdict(\"" + STUDY + "\") }}\n\n"
            "{{ held_out(\"" + STUDY + "\") }}\n")


@pytest.fixture()
def copy(tmp_path: Path) -> Path:
    shutil.copytree(ROOT / "studies" / STUDY, tmp_path / "studies" / STUDY)
    (tmp_path / "studies" / "templates").mkdir()
    (tmp_path / "studies" / "templates" / "demo.md").write_text(TEMPLATE)
    resultpages.render_all(tmp_path, reference=False)
    return tmp_path


def _rewrite(path: Path, edit) -> None:
    frame = pq.read_table(path).to_pandas()
    edit(frame)
    pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), path)


def _best_full(root: Path) -> str:
    df = pd.read_parquet(root / "studies" / STUDY / "results.parquet")
    full = df[(df["param"] != "diagonal") & df["best_converged"].astype(bool)]
    return str(full.loc[full["best_cost"].idxmin(), "job_id"])


def test_csv_comparison_tolerates_round_off_only(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("x,label\n1.0,p\n2.0,q\n")
    b.write_text("x,label\n1.0000000000001,p\n2.0,q\n")
    assert tablecheck.compare_csv(a, b) is None
    b.write_text("x,label\n1.001,p\n2.0,q\n")
    assert "column 'x', row 0" in tablecheck.compare_csv(a, b)
    b.write_text("x,label\n1.0,p\n2.0,r\n")
    assert "column 'label', row 1" in tablecheck.compare_csv(a, b)


def test_numbers_in_a_json_array_cell_compare_as_numbers(tmp_path):
    """A front's points (a JSON array in a text column) rounded differently in the last
    digits on another processor agree; a moved point, another shape or other text fails."""
    committed = '"[[0.0010113482412618746, 348.38821078816807], [0.036, 122.0]]"'
    (tmp_path / "a.csv").write_text(f"front,label\n{committed},p\n")
    for fresh, ok in (('"[[0.0010113482412618736, 348.38821078816807], [0.036, 122.0]]"', True),
                      ('"[[0.0010113, 348.38821078816807], [0.036, 122.0]]"', False),
                      ('"[[0.0010113482412618746, 348.38821078816807]]"', False),
                      ('"[[0.0010113482412618746, 348.38821078816807], [0.036, \'x\']]"',
                       False)):
        (tmp_path / "b.csv").write_text(f"front,label\n{fresh},p\n")
        assert (tablecheck.compare_csv(tmp_path / "a.csv", tmp_path / "b.csv") is None) == ok


def test_recomputed_closed_loop_diagnostics_tolerate_another_lapack(tmp_path):
    """A pole recomputed from the stored matrices moves with the processor's LAPACK build
    (1.8e-8 of itself seen); a change the pages could show (1e-4) still fails."""
    a = pd.DataFrame({"slowest_real": [-0.00949525366677024], "best_cost": [0.5]})
    a.to_csv(tmp_path / "a.csv", index=False)
    for value, ok in ((-0.009495253494748673, True), (-0.0094962, False)):
        a.assign(slowest_real=[value]).to_csv(tmp_path / "b.csv", index=False)
        assert (tablecheck.compare_csv(tmp_path / "a.csv", tmp_path / "b.csv") is None) == ok
    a.assign(best_cost=[0.5 * (1 + 1e-8)]).to_csv(tmp_path / "b.csv", index=False)
    assert "column 'best_cost'" in tablecheck.compare_csv(tmp_path / "a.csv", tmp_path / "b.csv")


@pytest.mark.slow
def test_committed_study_passes_and_each_mutation_fails(copy):
    assert resultpages.check(copy, reference=False) == []
    folder = copy / "studies" / STUDY
    job = _best_full(copy)

    # (a) held-out costs of the best full start scaled by 0.01
    source = folder / LONG_FILE if (folder / LONG_FILE).is_file() else \
        folder / "results.parquet"
    saved = source.read_bytes()

    def scale(frame: pd.DataFrame) -> None:
        k = frame.index[frame["job_id"] == job][0]
        held = json.loads(frame.at[k, "holdout"])
        held["cost"] = [0.01 * c for c in held["cost"]]
        frame.at[k, "holdout"] = json.dumps(held)

    _rewrite(source, scale)
    problems = resultpages.check(copy, reference=False)
    assert any("holdout.csv" in p for p in problems), problems
    source.write_bytes(saved)

    # (b) one job's best cost
    data = folder / "results.parquet"
    saved = data.read_bytes()

    def cheaper(frame: pd.DataFrame) -> None:
        frame.loc[frame["job_id"] == job, "best_cost"] *= 0.5

    _rewrite(data, cheaper)
    assert resultpages.check(copy, reference=False)
    data.write_bytes(saved)

    # (c) a stored p-value and, separately, a stored share
    table = folder / "tables" / "holdout.csv"
    saved = table.read_bytes()
    for column in ("ratio_p_holm", "full_cheaper_share"):
        frame = pd.read_csv(table)
        frame.loc[0, column] = 0.0123 if frame.loc[0, column] != 0.0123 else 0.5
        frame.to_csv(table, index=False)
        problems = resultpages.check(copy, reference=False)
        assert any("holdout.csv" in p and column in p for p in problems), problems
        table.write_bytes(saved)
    assert resultpages.check(copy, reference=False) == []
