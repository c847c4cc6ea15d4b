"""The deviation of every start's matrices from the published ones, computed as stacks
(:func:`penaltyrun.report.sections.deviations`), is the per-start deviation of the stored
matrices computed one start and one matrix at a time here."""

import json

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.report.sections import deviations, matrices_of


def relative_deviation(K, ref):
    """max |K − ref| / max |ref|; ∞ for a missing matrix or one of another shape."""
    if K is None or np.shape(K) != np.shape(ref):
        return float("inf")
    return float(np.max(np.abs(K - ref)) / np.max(np.abs(ref)))


def one_by_one(texts, refs):
    return [max(relative_deviation(matrices_of({"matrices": t}).get(k), r)
                for k, r in refs.items()) for t in texts]


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_deviations_equal_the_per_start_deviation(seed):
    rng = np.random.default_rng(seed)
    refs = {"Q": rng.standard_normal((3, 3)), "R": rng.uniform(0.5, 2.0, (1, 1))}
    texts = []
    for _ in range(rng.integers(0, 12)):
        kind = rng.integers(0, 5)
        if kind == 0:  # no matrices stored
            texts.append(None)
        elif kind == 1:  # one published matrix missing
            texts.append(json.dumps({"Q": rng.standard_normal((3, 3)).tolist()}))
        elif kind == 2:  # a matrix of another shape
            texts.append(json.dumps({"Q": rng.standard_normal((2, 2)).tolist(),
                                     "R": [[1.0]]}))
        else:  # near the published ones, with an extra matrix the reference lacks
            texts.append(json.dumps({
                "Q": (refs["Q"] + 1e-3 * rng.standard_normal((3, 3))).tolist(),
                "R": (refs["R"] * rng.uniform(0.9, 1.1)).tolist(), "S": [[2.0]]}))
    got = deviations(texts, refs)
    assert got.shape == (len(texts),)
    np.testing.assert_array_equal(got, one_by_one(texts, refs))
