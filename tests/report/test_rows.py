"""Report row helpers: :func:`penaltyrun.report.rows.groups` iterates like a pandas
groupby without holding a sorted copy of the frame."""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.report.rows import groups

KEYS = ["problem", "case", "variant"]


def _frame(codes: list[tuple[int, int, int]], categorical: bool) -> pd.DataFrame:
    names = (["b", "a", None], ["x", "y"], ["", "v=1", "v=2"])
    df = pd.DataFrame({key: [names[i][c[i]] for c in codes] for i, key in enumerate(KEYS)})
    df["value"] = np.arange(len(df), dtype=float)
    if categorical:  # categories out of lexical order: groupby sorts by category order
        df["problem"] = pd.Categorical(df["problem"], categories=["b", "a"])
    return df


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.integers(0, 1), st.integers(0, 2)),
                max_size=40), st.booleans())
def test_groups_equal_a_sorted_pandas_groupby(codes, categorical):
    """Same keys in the same order, same rows in the same order (a missing key is left
    out, as pandas does), for object and categorical key columns."""
    df = _frame(codes, categorical)
    expected = [(key, g) for key, g in df.groupby(KEYS, sort=True, observed=True)]
    got = list(groups(df, KEYS))
    assert [key for key, _ in got] == [key for key, _ in expected]
    for (_, a), (_, b) in zip(got, expected):
        pd.testing.assert_frame_equal(a, b)


def test_groups_of_an_empty_frame_yield_nothing():
    assert list(groups(_frame([], False), KEYS)) == []
