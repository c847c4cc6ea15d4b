"""Closed-form Zermelo evaluation against the DOP853 kernel on many random gains.

``--n`` gains (seed 42) with eigenvalues log-uniform over the whole box [1e-8, 10] and a
uniform rotation, the first eighth with near-equal eigenvalues (relative gap ≤ 1e-6), from the
training start, t_max = 1000, kernel tolerances 1e-10. Printed: statuses (identical or not),
the largest relative cost difference and event-time difference, how many costs differ by
more than 1e-9 and 1e-8, and for the largest differences scipy ``solve_ivp`` (DOP853,
rtol 1e-13, atol 1e-14) as the referee. Usage::

    python bench/fidelity_zermelo_closed.py [--n 4000]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.integrate import solve_ivp

from penaltyrun.dynamics.zermelo import simulate_batch
from penaltyrun.dynamics.zermelo_closed import QUAD_RTOL, closed_batch

X0 = np.array([-8.0, 6.0])


def referee(K: np.ndarray) -> float:
    """J from solve_ivp at rtol 1e-13 (at the event, or at t_max)."""
    def rhs(t: float, z: np.ndarray) -> list[float]:
        d = -z[:2] * np.cos(z[1]) * np.sin(z[0])
        u = -d - K.T @ z[:2]
        return [*(u + d), 0.5 * float(u @ u)]

    def hit(t: float, z: np.ndarray) -> float:
        return float(np.hypot(z[0], z[1]) - 1e-3)

    hit.terminal = True
    sol = solve_ivp(rhs, (0.0, 1000.0), [X0[0], X0[1], 0.0], events=hit, rtol=1e-13,
                    atol=1e-14, method="DOP853")
    return float(sol.y_events[0][0][2] if sol.t_events[0].size else sol.y[2, -1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=4000)
    args = parser.parse_args()
    n = args.n
    rng = np.random.default_rng(42)
    lam = 10.0 ** rng.uniform(-8.0, 1.0, (n, 2))
    th = rng.uniform(0.0, np.pi, n)
    c, s = np.cos(th), np.sin(th)
    K = np.empty((n, 2, 2))
    K[:, 0, 0] = c * c * lam[:, 0] + s * s * lam[:, 1]
    K[:, 1, 1] = s * s * lam[:, 0] + c * c * lam[:, 1]
    K[:, 0, 1] = K[:, 1, 0] = c * s * (lam[:, 0] - lam[:, 1])
    m = n // 8
    K[:m, 1, 1] = K[:m, 0, 0] * (1.0 + rng.uniform(-1e-6, 1e-6, m))
    K[:m, 0, 1] = K[:m, 1, 0] = K[:m, 0, 0] * rng.uniform(-1e-7, 1e-7, m)

    t, J, _, st, covered = closed_batch(K, np.tile(X0, (n, 1)), 1000.0, 1e-3,
                                        np.full(n, np.inf), QUAD_RTOL)
    ts, Js, _, sts = simulate_batch(K, X0, 1000.0, 1e-3, 1e-10, 1e-10, np.inf, 1_000_000)
    same = st == sts
    rel = np.abs(J - Js) / np.abs(Js)
    ev = same & (st == 0)
    print(f"{n} gains: covered {int(covered.sum())}, statuses identical {int(same.sum())}, "
          f"events {int(ev.sum())}")
    print(f"max relative cost difference {rel[same].max():.1e}; > 1e-9: "
          f"{int((rel[same] > 1e-9).sum())}, > 1e-8: {int((rel[same] > 1e-8).sum())}; "
          f"max event-time difference {np.abs(t - ts)[ev].max():.1e}")
    for i in np.argsort(-np.where(same, rel, 0.0))[:4]:
        ref = referee(K[i])
        print(f"  gain {i}: eigenvalues {np.linalg.eigvalsh(K[i])}, closed form vs solve_ivp "
              f"{abs(J[i] - ref) / ref:.1e}, DOP853 kernel vs solve_ivp "
              f"{abs(Js[i] - ref) / ref:.1e}")


if __name__ == "__main__":
    main()
