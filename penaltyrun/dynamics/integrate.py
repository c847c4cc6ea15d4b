"""Integration status codes shared by the compiled integrators, and the Dormand–Prince 5(4)
coefficients.

The statuses are what every closed-loop kernel returns (DOP853 in
:mod:`penaltyrun.dynamics.dop853`, RODAS4 in :mod:`penaltyrun.dynamics.rosenbrock`, the
Zermelo closed form, the batched linear-feedback integration). The Dormand–Prince 5(4)
tableau (Dormand & Prince 1980; Shampine 1986 quartic dense output) is the method of the
batched integration of user plants in :mod:`penaltyrun.dynamics.linear_feedback`.
"""

from __future__ import annotations

import numpy as np

#: Integration status codes returned by the closed-loop kernels.
EVENT = 0
HORIZON = 1
STEP_FAILURE = 2
NONFINITE = 3
CUTOFF = 4
#: A divergence guard of the closed loop fired (the state left its documented bound; only
#: integrators built with a guard return it, e.g. the attitude kernels).
DIVERGED = 5
STATUS_NAMES = ("event", "horizon", "step_failure", "nonfinite", "cutoff", "diverged")


def dopri54_tableau() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Dormand–Prince 5(4) coefficients: A (6, 5), B (6,), C (6,) and the error weights
    E (7,) (the last one weighs the FSAL stage)."""
    C = np.array([0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0])
    A = np.array(
        [
            [0.0, 0.0, 0.0, 0.0, 0.0],
            [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0],
            [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0],
            [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0],
            [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0],
            [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0],
        ]
    )
    B = np.array([35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0])
    E = np.array(
        [
            -71.0 / 57600.0,
            0.0,
            71.0 / 16695.0,
            -71.0 / 1920.0,
            17253.0 / 339200.0,
            -22.0 / 525.0,
            1.0 / 40.0,
        ]
    )
    return A, B, C, E
