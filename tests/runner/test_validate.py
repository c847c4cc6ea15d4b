"""Record checks on read: each way a record can be wrong has its reason."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from penaltyrun.runner.validate import SCHEMA_VERSION, record_problem

GOOD = {"job_id": "j-s000", "problem": "zermelo", "case": "default", "param": "full",
        "optimizer": "pso", "start": 0, "seed": 7, "status": "ok", "best_cost": 1.5,
        "n_evals": 300}


def test_a_good_record_passes():
    assert record_problem(GOOD, "j-s000") is None
    assert record_problem({**GOOD, "status": "failed", "best_cost": None}, "j-s000") is None
    assert record_problem({**GOOD, "status": "diverged", "best_cost": math.inf}) is None
    assert record_problem({**GOOD, "schema_version": SCHEMA_VERSION}) is None


@pytest.mark.parametrize(("change", "fragment"), [
    ({"job_id": "other-s001"}, "is not the file's job"),
    ({"best_cost": math.nan}, "NaN"),
    ({"status": "diverged", "best_cost": math.nan}, "NaN"),
    ({"best_cost": math.inf}, "ok record"),
    ({"best_cost": "abc"}, "best_cost must be a number"),
    ({"best_cost": None}, "best_cost is missing"),
    ({"status": "weird"}, "status 'weird'"),
    ({"n_evals": 3.5}, "n_evals must be an integer"),
    ({"start": True}, "start must be an integer"),
    ({"start": -1}, "start must be"),
    ({"schema_version": SCHEMA_VERSION + 1}, "unknown schema_version"),
    ({"history": ["x"]}, "history"),
    # what a results file cannot store: integers beyond 64 bits
    ({"seed": 2 ** 64}, "seed must be an integer"),
    ({"best_cost": 10 ** 20}, "best_cost must be a number"),
    ({"trace_evals": [1, 2 ** 63]}, "trace_evals"),
])
def test_bad_records_are_named(change, fragment):
    assert fragment in record_problem({**GOOD, **change}, "j-s000")


def test_a_status_only_record_is_refused():
    assert "required field" in record_problem({"status": "ok"})
    assert "not a JSON object" in record_problem([1, 2])


@given(st.dictionaries(st.text(max_size=8), st.one_of(st.none(), st.integers(),
                                                      st.floats(), st.text(max_size=5))))
def test_never_raises(record):
    result = record_problem(record, "j")
    assert result is None or isinstance(result, str)
