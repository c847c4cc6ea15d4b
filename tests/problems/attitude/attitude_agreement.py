"""The reference-agreement check shared by the attitude problem tests (``attitude_lqr``,
``attitude_lyapunov``): production costs of a batch of candidate matrices against each
problem's independent scipy reference (``reference_cost``), over three initial conditions
(detumble, rest-to-rest, and a third attitude with full inertia)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from penaltyrun.problems import make

#: A full (non-diagonal) inertia, kg·m².
I_FULL = ((10.0, 1.0, 0.5), (1.0, 15.0, -0.7), (0.5, -0.7, 20.0))
#: (case, parameter overrides) of the initial conditions the check runs.
INITIAL_CONDITIONS = (
    ("detumble", {}),
    ("rest_to_rest", {}),
    ("detumble", {"attitude": (-120.0, 30.0, 150.0), "omega0": (0.02, 0.0, -0.01),
                  "inertia": I_FULL}),
)


def random_spd(rng: np.random.Generator, n: int, lo: float, hi: float) -> np.ndarray:
    """Random SPD matrix: random rotation, eigenvalues uniform in [lo, hi]."""
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return Q @ np.diag(rng.uniform(lo, hi, n)) @ Q.T


def agreement(problem: str, cands: list[dict[str, np.ndarray]], keys: tuple[str, ...],
              gains: Callable[[dict[str, np.ndarray], object], np.ndarray],
              reference_cost: Callable[..., dict], check_gains: bool = False) -> tuple[int, int]:
    """Check that production agrees with the reference for every candidate and initial
    condition; count the converged and failed reference runs.

    Parameters
    ----------
    problem : str
        Registered problem name.
    cands : list of dict
        Candidate matrices, each with the entries ``keys``.
    keys : tuple of str
        The problem's matrix names, e.g. ``("Q", "R")``.
    gains : callable
        ``gains(batch, prob)``: the batch's feedback gains, shape (B, 3, 6), as
        ``prob.run`` takes them (it may assert on the way).
    reference_cost : callable
        ``reference_cost(cand, params)``: the independent reference's ``cost``,
        ``converged``, ``energy``, ``t_final`` (and ``gain``).
    check_gains : bool
        Also compare each gain with the reference's ``gain``.

    Returns
    -------
    (int, int)
        Reference runs that converged, and that did not.
    """
    n_conv = n_fail = 0
    for case, over in INITIAL_CONDITIONS:
        prob = make(problem, case, over)
        batch = {k: np.stack([c[k] for c in cands]) for k in keys}
        be = prob.evaluate_batch(batch)
        G = gains(batch, prob)
        t_end, energy, _, _ = prob.run(G)
        for b, cand in enumerate(cands):
            ref = reference_cost(cand, prob.params)
            if check_gains:
                np.testing.assert_allclose(G[b], ref["gain"], rtol=1e-8, atol=1e-12)
            assert bool(be.converged[b]) == ref["converged"], (case, b)
            assert be.cost[b] == pytest.approx(ref["cost"], rel=1e-6)
            assert energy[b] == pytest.approx(ref["energy"], rel=1e-6)
            assert t_end[b] == pytest.approx(ref["t_final"], rel=1e-6)
            n_conv += int(ref["converged"])
            n_fail += int(not ref["converged"])
    return n_conv, n_fail
