"""The guard bound, the stiffness threshold and the flat failure factor stated in
docs/explanation/attitude.md are the code's."""

from __future__ import annotations

from pathlib import Path

from penaltyrun.dynamics import attitude as at
from penaltyrun.dynamics import integrate
from penaltyrun.problems.attitude.reference import HARD_FAILURE_FACTOR

PAGE = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "attitude.md"


def _num(x: float) -> str:
    return f"{x:g}"


def test_attitude_page_states_the_code_constants():
    text = " ".join(PAGE.read_text().split())
    assert (f"‖ω‖ ≤ max({_num(at.OMEGA_GUARD_MIN)} rad/s, {_num(at.OMEGA_GUARD_FACTOR)} "
            "‖ω(0)‖)") in text
    assert f"above {_num(at.STIFF_RATE)} 1/s" in text
    assert f"cost {_num(HARD_FAILURE_FACTOR)} · `failure_penalty`" in text
    for name in ("horizon", "diverged", "step_failure", "nonfinite", "cutoff"):
        assert name in integrate.STATUS_NAMES and f"`{name}`" in text
