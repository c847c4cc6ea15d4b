"""Fixtures of the API tests."""

from __future__ import annotations

import pytest
from known_optimum import frobenius_cost

import penaltyrun


@pytest.fixture
def quad():
    """The known-optimum problem (a fresh object per test)."""
    return penaltyrun.from_cost(frobenius_cost, {"K": (2, (0.1, 10.0))}, name="quad")
