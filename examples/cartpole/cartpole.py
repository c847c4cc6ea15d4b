"""Nonlinear cart-pole for ``problem=lqr`` (``dynamics: cartpole:dynamics``).

A pole (point mass m at distance l on a massless rod) hinged on a cart (mass M) pushed by a
horizontal force F. With θ the pole angle from upright, Lagrange's equations give

    ẍ = (F + m sin θ (l θ̇² − g cos θ)) / (M + m sin² θ),   θ̈ = (g sin θ − cos θ ẍ) / l.

State s = (x m, ẋ m/s, θ rad, θ̇ rad/s), input u = (F N,). penaltyrun linearizes this
function at the origin (upright, at rest) by central differences, designs the LQR gain of
each tuned (Q, R) on that model and runs the clipped law on this nonlinear plant.
"""

import numpy as np

CART_MASS = 1.0   # M, kg
POLE_MASS = 0.1   # m, kg
LENGTH = 0.5      # l, hinge to the pole's mass, m
GRAVITY = 9.81    # g, m/s²


def dynamics(X: np.ndarray, U: np.ndarray) -> np.ndarray:
    """ṡ for states X (R, 4) and forces U (R, 1); returns (R, 4)."""
    M, m, l, g = CART_MASS, POLE_MASS, LENGTH, GRAVITY
    th, om, F = X[:, 2], X[:, 3], U[:, 0]
    sin, cos = np.sin(th), np.cos(th)
    xdd = (F + m * sin * (l * om**2 - g * cos)) / (M + m * sin**2)
    thdd = (g * sin - cos * xdd) / l
    return np.stack([X[:, 1], xdd, om, thdd], axis=1)
