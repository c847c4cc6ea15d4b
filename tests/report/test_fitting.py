"""Rows whose stored matrices do not fit their problem are left out of the report once,
with one warning, instead of breaking the sections that decode them."""

import json
import logging
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import RESULTS_FILE
from penaltyrun.report import protocol
from penaltyrun.report.fitting import fitting_rows

GOLDEN = Path(__file__).parent / "golden" / "zermelo" / "input" / RESULTS_FILE


def _frame(matrices: list) -> pd.DataFrame:
    return pd.DataFrame({"problem": "zermelo", "case": "default", "problem_params": "{}",
                         "run_id": [f"r{i}" for i in range(len(matrices))],
                         "status": "ok", "matrices": [None if m is None else json.dumps(m)
                                                      for m in matrices]})


def test_matrices_of_another_problem_or_size_are_left_out_with_one_warning(caplog):
    protocol.reset()
    good = {"K": [[1.0, 0.0], [0.0, 1.0]]}
    df = _frame([good, {"Q": [[1.0, 0.0], [0.0, 1.0]]}, {"K": [[1.0, 2.0, 3.0]]},
                 {"K": [[1.0, 0.0], [0.0]]}, None, good])
    with caplog.at_level(logging.WARNING):
        kept = fitting_rows(df)
    assert list(kept.index) == [0, 4, 5]  # a job storing no matrices (e.g. failed) stays
    lines = [r.getMessage() for r in caplog.records if "do not fit" in r.getMessage()]
    assert len(lines) == 1 and "left out 3 job(s) of zermelo / default" in lines[0]
    assert "(K 2×2, eigenvalues 1e-08 to 10)" in lines[0] and "r1, r2, r3" in lines[0]


def test_matrices_no_search_of_the_problem_gives_are_left_out_with_one_warning(caplog):
    """Not symmetric, not positive definite, or eigenvalues outside the problem's bounds
    (Zermelo: 1e-8 to 10): no search gives them; one warning, not one per section."""
    protocol.reset()
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.normal(size=(2, 2)))
    edge = (q @ np.diag([1e-8, 10.0]) @ q.T).tolist()  # the bounds, up to rounding
    df = _frame([{"K": [[1.0, 0.5], [0.0, 1.0]]}, {"K": [[1.0, 0.0], [0.0, -1.0]]},
                 {"K": [[1e308, 0.0], [0.0, 1e308]]}, {"K": [[11.0, 0.0], [0.0, 1.0]]},
                 {"K": [[1e-9, 0.0], [0.0, 1.0]]}, {"K": edge}])
    with caplog.at_level(logging.WARNING):
        kept = fitting_rows(df)
    assert list(kept.index) == [5]
    lines = [r.getMessage() for r in caplog.records if "do not fit" in r.getMessage()]
    assert len(lines) == 1 and "left out 5 job(s) of zermelo / default" in lines[0]


def test_no_fitting_row_is_one_error_not_an_empty_report():
    protocol.reset()
    with pytest.raises(ResultsUnreadableError, match="no usable results"):
        fitting_rows(_frame([{"Q": [[1.0]]}]))


def test_a_report_beside_a_file_of_misfit_matrices_reports_the_rest(tmp_path, caplog):
    from penaltyrun.cli import report_main

    (tmp_path / "good").mkdir()
    shutil.copy(GOLDEN, tmp_path / "good" / RESULTS_FILE)
    table = pq.read_table(GOLDEN)
    table = table.set_column(table.column_names.index("matrices"), "matrices",
                             pa.array([json.dumps({"K": [[1.0, 2.0, 3.0]]})] * len(table)))
    table = table.set_column(table.column_names.index("config_hash"), "config_hash",
                             pa.array(["other"] * len(table)))
    (tmp_path / "bad").mkdir()
    pq.write_table(table, tmp_path / "bad" / RESULTS_FILE)
    with caplog.at_level(logging.WARNING):
        report_main([str(tmp_path), "-o", str(tmp_path / "report"), "--no-probe",
                     "--basin-points", "0"])
    text = (tmp_path / "report" / "report.md").read_text(encoding="utf-8")
    assert f"left out {len(table)} job(s) of zermelo / default" in text
    lines = [r.getMessage() for r in caplog.records if "do not fit the problem" in
             r.getMessage()]
    assert len(lines) == 1 and str(tmp_path / "bad" / RESULTS_FILE) in lines[0]
    assert str(tmp_path / "good") not in lines[0]


def test_arithmetic_warnings_on_extreme_stored_values_stay_off_the_terminal(tmp_path):
    """A stored cost of -1e308 (finite, extreme) overflows numpy's and matplotlib's
    arithmetic: ``penaltyrun-report`` writes the report and prints no RuntimeWarning."""
    import warnings

    import pyarrow as pa
    import pyarrow.parquet as pq

    from penaltyrun.cli import report_main

    table = pq.read_table(GOLDEN)
    costs = table["best_cost"].to_pylist()
    costs[0] = -1e308
    folder = tmp_path / "extreme"
    folder.mkdir()
    pq.write_table(table.set_column(table.schema.get_field_index("best_cost"), "best_cost",
                                    pa.array(costs, pa.float64())), folder / RESULTS_FILE)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        report_main([str(folder), "-o", str(tmp_path / "report"), "--no-cache",
                     "--basin-points", "0", "--no-probe", "--workers", "1"])
    assert (tmp_path / "report" / "report.md").is_file()
    assert not [w for w in caught if issubclass(w.category, RuntimeWarning)]


def test_a_damaged_copy_sorted_first_never_hides_the_good_file(tmp_path):
    """The same jobs in two files, the copy first in path order with matrices that do not
    fit: its rows are left out as unusable before duplicates are, so the report is the
    good file's (it was 'no usable results': the good rows had been dropped as
    duplicates of the damaged ones)."""
    from penaltyrun.cli import report_main

    table = pq.read_table(GOLDEN)
    bad = [json.dumps({"K": [[1.0, 2.0], [3.0, 4.0]]})] * table.num_rows
    (tmp_path / "a_copy").mkdir()
    (tmp_path / "b_good").mkdir()
    pq.write_table(table.set_column(table.schema.get_field_index("matrices"), "matrices",
                                    pa.array(bad, pa.string())),
                   tmp_path / "a_copy" / RESULTS_FILE)
    shutil.copy(GOLDEN, tmp_path / "b_good" / RESULTS_FILE)
    protocol.reset()
    report_main([str(tmp_path), "-o", str(tmp_path / "report"), "--no-cache",
                 "--basin-points", "0", "--no-probe", "--workers", "1"])
    text = (tmp_path / "report" / "report.md").read_text()
    assert f"{table.num_rows} jobs" in text
