"""The Dormand–Prince 5(4) coefficients of the batched linear-feedback integration satisfy
the method's order conditions (Hairer, Nørsett & Wanner, Solving ODEs I, II.2)."""

import numpy as np

from penaltyrun.dynamics import integrate


def test_the_fifth_order_weights_satisfy_the_order_conditions():
    A, B, C, E = integrate.dopri54_tableau()
    a = np.zeros((6, 6))
    a[:, :5] = A
    b, c = B, C
    np.testing.assert_allclose(a.sum(axis=1), c, atol=1e-15)  # row sums are the nodes
    conditions = {  # (value, order condition) for the trees up to order four, bushy to five
        "b·1": (b.sum(), 1.0),
        "b·c": (b @ c, 1 / 2),
        "b·c²": (b @ c**2, 1 / 3),
        "b·Ac": (b @ (a @ c), 1 / 6),
        "b·c³": (b @ c**3, 1 / 4),
        "b·(c∘Ac)": (b @ (c * (a @ c)), 1 / 8),
        "b·Ac²": (b @ (a @ c**2), 1 / 12),
        "b·AAc": (b @ (a @ (a @ c)), 1 / 24),
        "b·c⁴": (b @ c**4, 1 / 5),
    }
    for name, (value, exact) in conditions.items():
        assert abs(value - exact) < 1e-15, name


def test_the_error_weights_are_a_difference_of_two_solutions():
    _, _, _, E = integrate.dopri54_tableau()
    assert E.shape == (7,) and abs(E.sum()) < 1e-15
