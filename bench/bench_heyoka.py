"""penaltyrun's closed-loop kernels against heyoka (Taylor method, LLVM-compiled) in one run.

The same random candidates (uniform in the full GEAGSP box of each tuned matrix) are evaluated
by penaltyrun's production path and by heyoka with the same dynamics, tolerance, terminal
event and horizon:

* attitude (``attitude_lyapunov`` and ``attitude_lqr``, detumble, t_max = 100 s, tol 1e-10,
  event ‖(q0 − 1, q_v, ω)‖ = 1e-4 as a terminal heyoka event on the squared distance);
* Zermelo (tol 1e-10, event ‖X‖ = 1e-3, t_max = 1000).

penaltyrun is timed as one batch call of ``evaluate_batch`` (decode of the gain included for
LQR: the Riccati solves), as B calls of one candidate and, for LQR, as the closed loop alone
with the gains given (as heyoka gets them); heyoka as ``taylor_adaptive``
(scalar: one candidate after another, runtime parameters reset each time) and
``taylor_adaptive_batch`` with 4 and 8 SIMD lanes (the gain, for heyoka, is computed
beforehand and not timed). CPU time (``time.process_time``), best of ``--repeats`` after
warm-up. Printed: evaluations per CPU-second, the ratios, whether the converged flags agree and
the largest relative cost difference on converged candidates.

heyoka (PyPI ``heyoka``) is a bench-only dependency: ``pip install heyoka``.

Usage::

    python bench/bench_heyoka.py [--n 200] [--repeats 3] [--tol 1e-10]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from machine import machine

from penaltyrun import problems
from penaltyrun.penalty import make as make_param
from penaltyrun.penalty.layout import build_layout


def cpu_best(fn, repeats: int) -> float:  # noqa: ANN001
    """Smallest CPU time (s) of ``repeats`` calls of ``fn``."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def candidates(name: str, case: str, n: int, overrides: dict):  # noqa: ANN201
    """Problem and n random full-parameterization candidates (seed 0)."""
    prob = problems.make(name, case, overrides)
    lay = build_layout([(m.name, make_param("full", m.size, m.eig_bounds))
                        for m in prob.matrices])
    lb, ub = lay.bounds()
    Z = np.random.default_rng(0).uniform(lb, ub, size=(n, lay.dim))
    return prob, lay.split(Z)[0]


def attitude_system(hy, prob):  # noqa: ANN001, ANN201
    """heyoka ODE system of the attitude closed loop; the gain G (3×6) as 18 parameters."""
    q0, q1, q2, q3, w1, w2, w3, _ = hy.make_vars("q0", "q1", "q2", "q3", "w1", "w2", "w3", "J")
    inertia = prob.inertia
    inv = prob.inertia_inv
    x = [q1, q2, q3, w1, w2, w3]
    u = [-sum(hy.par[6 * i + j] * x[j] for j in range(6)) for i in range(3)]
    w = [w1, w2, w3]
    h = [sum(float(inertia[i, j]) * w[j] for j in range(3)) for i in range(3)]
    m = [u[0] - (w2 * h[2] - w3 * h[1]), u[1] - (w3 * h[0] - w1 * h[2]),
         u[2] - (w1 * h[1] - w2 * h[0])]
    wdot = [sum(float(inv[i, j]) * m[j] for j in range(3)) for i in range(3)]
    state = hy.make_vars("q0", "q1", "q2", "q3", "w1", "w2", "w3", "J")
    rhs = [0.5 * (-w1 * q1 - w2 * q2 - w3 * q3), 0.5 * (w1 * q0 + w3 * q2 - w2 * q3),
           0.5 * (w2 * q0 - w3 * q1 + w1 * q3), 0.5 * (w3 * q0 + w2 * q1 - w1 * q2),
           *wdot, 0.5 * (u[0] * u[0] + u[1] * u[1] + u[2] * u[2])]
    dist2 = (q0 - 1.0) ** 2 + q1 ** 2 + q2 ** 2 + q3 ** 2 + w1 ** 2 + w2 ** 2 + w3 ** 2
    return list(zip(state, rhs)), dist2 - float(prob.params.tol) ** 2


def zermelo_system(hy, prob):  # noqa: ANN001, ANN201
    """heyoka ODE system of the Zermelo closed loop; K (2×2, row-major) as 4 parameters."""
    x, y, j = hy.make_vars("x", "y", "J")
    s = hy.cos(y) * hy.sin(x)
    dx, dy = -x * s, -y * s
    u1 = -dx - (hy.par[0] * x + hy.par[2] * y)
    u2 = -dy - (hy.par[1] * x + hy.par[3] * y)
    r = float(prob.params.event_radius)
    return [(x, u1 + dx), (y, u2 + dy), (j, 0.5 * (u1 * u1 + u2 * u2))], x * x + y * y - r * r


def heyoka_runs(hy, sys_ev, y0, pars, t_max, tol, batch):  # noqa: ANN001, ANN201
    """Run every candidate with heyoka; returns (time for all, converged, final J)."""
    sysm, ev_expr = sys_ev
    n = pars.shape[0]
    n_state = len(sysm)
    conv = np.zeros(n, dtype=bool)
    cost = np.zeros(n)
    if batch == 1:
        ev = hy.t_event(ev_expr, direction=hy.event_direction.negative)
        ta = hy.taylor_adaptive(sysm, list(y0), tol=tol, t_events=[ev], pars=list(pars[0]))

        def run() -> None:
            for b in range(n):
                ta.time = 0.0
                ta.state[:] = y0
                ta.pars[:] = pars[b]
                out = ta.propagate_until(t_max)
                conv[b] = int(out[0]) == -1
                cost[b] = ta.state[n_state - 1]
        return ta, run, conv, cost
    ev = hy.t_event_batch(ev_expr, direction=hy.event_direction.negative)
    ta = hy.taylor_adaptive_batch(sysm, np.repeat(np.asarray(y0)[:, None], batch, axis=1),
                                  tol=tol, t_events=[ev],
                                  pars=np.ascontiguousarray(pars[:batch].T))

    def run() -> None:
        for b0 in range(0, n, batch):
            lanes = min(batch, n - b0)
            block = np.repeat(pars[b0:b0 + 1], batch, axis=0)
            block[:lanes] = pars[b0:b0 + lanes]
            ta.set_time(0.0)
            ta.state[:] = np.asarray(y0)[:, None]
            ta.pars[:] = block.T
            done = np.zeros(batch, dtype=bool)
            done[lanes:] = True
            # A terminal event in one lane interrupts the whole batch: resume until every
            # lane has either fired (recorded at its first event) or reached t_max.
            while not done.all():
                ta.propagate_until(t_max)
                for k in np.flatnonzero(~done):
                    out = ta.propagate_res[k][0]
                    if int(out) == -1 or out == hy.taylor_outcome.time_limit:
                        conv[b0 + k] = int(out) == -1
                        cost[b0 + k] = ta.state[n_state - 1, k]
                        done[k] = True
    return ta, run, conv, cost


def compare(hy, label: str, prob, mats, pars, sys_ev, y0, t_max: float, tol: float,  # noqa: ANN001
            repeats: int, gains: np.ndarray | None = None) -> None:
    """Time penaltyrun and heyoka on the same candidates and print the comparison."""
    n = pars.shape[0]
    prob.evaluate_batch({k: v[:2] for k, v in mats.items()})  # JIT warm-up
    res = prob.evaluate_batch(mats)
    t_batch = cpu_best(lambda: prob.evaluate_batch(mats), repeats)
    singles = [{k: v[b:b + 1] for k, v in mats.items()} for b in range(n)]
    t_single = cpu_best(lambda: [prob.evaluate_batch(m) for m in singles], repeats)
    rates = {"penaltyrun batch": n / t_batch, "penaltyrun one by one": n / t_single}
    if gains is not None:  # the closed loop alone, gains given as to heyoka
        t_kernel = cpu_best(lambda: prob.run(gains), repeats)
        rates["penaltyrun kernel only"] = n / t_kernel
    print(f"{label}: {res.converged.sum()} of {n} random full candidates converge")
    for lanes in (1, 4, 8):
        _, run, conv, cost = heyoka_runs(hy, sys_ev, y0, pars, t_max, tol, lanes)
        t_hy = cpu_best(run, repeats)
        key = "heyoka scalar" if lanes == 1 else f"heyoka batch-{lanes}"
        rates[key] = n / t_hy
        both = conv & res.converged
        err = np.max(np.abs(cost[both] - res.cost[both]) / np.abs(res.cost[both])) \
            if both.any() else float("nan")
        print(f"  {key:22s} flags agree {bool(np.all(conv == res.converged))}, "
              f"max relative J difference (converged) {err:.1e}")
    ref = rates["heyoka scalar"]
    for key, rate in rates.items():
        print(f"  {key:22s} {rate:10.0f} evaluations/CPU-s   {rate / ref:5.2f} x heyoka scalar")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="candidates")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--tol", type=float, default=1e-10, help="rtol = atol and heyoka tol")
    args = parser.parse_args()
    try:
        import heyoka as hy
    except ImportError:
        print("heyoka not importable (pip install heyoka): nothing to compare")
        return
    print(f"machine: {machine()}; heyoka {hy.__version__}")
    tol = {"rtol": args.tol, "atol": args.tol}
    for name in ("attitude_lyapunov", "attitude_lqr"):
        prob, mats = candidates(name, "detumble", args.n, tol)
        G, ok = prob.gains(mats)
        pars = np.ascontiguousarray(G.reshape(args.n, 18))
        compare(hy, f"{name} / detumble", prob, mats, pars, attitude_system(hy, prob),
                np.concatenate([prob.y0, [0.0]]), float(prob.params.t_max), args.tol,
                args.repeats, G if name == "attitude_lqr" else None)
    prob, mats = candidates("zermelo", "default", args.n, tol)
    pars = np.ascontiguousarray(mats["K"].reshape(args.n, 4))
    x0 = np.asarray(prob.params.x0, dtype=float)
    compare(hy, "zermelo", prob, mats, pars, zermelo_system(hy, prob),
            np.array([x0[0], x0[1], 0.0]), float(prob.params.t_max), args.tol, args.repeats)


if __name__ == "__main__":
    main()
