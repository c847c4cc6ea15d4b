"""Zermelo: the closed-form production path vs the DOP853 batch kernel vs heyoka scalar.

All paths evaluate the same candidates (seed 0, uniform in the full GEAGSP box of K, as in
``bench_heyoka.py``; with ``--log-eigs LO`` instead eigenvalues log-uniform in [LO, 10] and a
uniform rotation, which puts more weight on the slow gains) at the paper's tolerances
(rtol = atol = 1e-10, event ‖X‖ = 1e-3, t_max = 1000):

* closed form: ``evaluate_batch`` (one call for the batch; eigen-decomposition, event root,
  Gauss–Kronrod energy);
* DOP853 batch: the compiled integrator on the same batch (the production path before the
  closed form; still used for gains the closed form does not cover);
* heyoka scalar (Taylor method; bench-only dependency, ``pip install heyoka``), one candidate
  after another, if importable;
* scipy ``solve_ivp`` (DOP853, terminal event) on the first ``--n-scipy`` candidates.

CPU time (``time.process_time``). The machine is shared, so the paths are timed in pairs
interleaved in one process: every round times each path once, in an order rotated from round
to round, and each ratio is formed within a round; printed are the min and median over the
rounds. Also printed: whether statuses agree and the largest relative cost difference.
Usage: ``python bench/bench_zermelo.py [--n 200] [--rounds 15] [--log-eigs 1e-3]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
from bench_heyoka import candidates, heyoka_runs, zermelo_system
from machine import machine

from penaltyrun.dynamics.zermelo import simulate_batch
from penaltyrun.problems.zermelo import reference_cost


def cpu(fn: Callable[[], object]) -> float:
    """CPU seconds of one call of ``fn``."""
    t0 = time.process_time()
    fn()
    return time.process_time() - t0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="candidates per batch")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--n-scipy", type=int, default=20)
    parser.add_argument("--log-eigs", type=float, default=None,
                        help="log-uniform eigenvalues in [LOG_EIGS, 10] instead of the box")
    args = parser.parse_args()

    prob, mats = candidates("zermelo", "default", args.n, {})
    K = np.ascontiguousarray(mats["K"])
    if args.log_eigs is not None:
        rng = np.random.default_rng(0)
        lam = np.exp(rng.uniform(np.log(args.log_eigs), np.log(10.0), (args.n, 2)))
        th = rng.uniform(0.0, np.pi, args.n)
        c, s = np.cos(th), np.sin(th)
        K[:, 0, 0] = c * c * lam[:, 0] + s * s * lam[:, 1]
        K[:, 1, 1] = s * s * lam[:, 0] + c * c * lam[:, 1]
        K[:, 0, 1] = K[:, 1, 0] = c * s * (lam[:, 0] - lam[:, 1])
    p = prob.params
    x0 = np.asarray(p.x0, dtype=float)
    d0 = float(np.hypot(*x0))

    def closed():  # noqa: ANN202
        return prob.evaluate_batch({"K": K})

    def dop853():  # noqa: ANN202
        res = simulate_batch(K, x0, p.t_max, p.event_radius, p.rtol, p.atol, p.max_step,
                             p.max_steps)
        return prob._graded(*res, d0)

    paths: dict[str, Callable[[], object]] = {"closed form": closed, "DOP853 batch": dop853}
    try:
        import heyoka as hy

        _, run_hy, conv_hy, cost_hy = heyoka_runs(
            hy, zermelo_system(hy, prob), np.array([x0[0], x0[1], 0.0]),
            np.ascontiguousarray(K.reshape(args.n, 4)), float(p.t_max), float(p.rtol), 1)
        paths["heyoka scalar"] = run_hy
        hy_version = hy.__version__
    except ImportError:
        hy_version = "not importable"
    ns = min(args.n_scipy, args.n)
    paths["scipy solve_ivp"] = lambda: [reference_cost(k, p) for k in K[:ns]]
    scale = {name: 1.0 for name in paths}
    scale["scipy solve_ivp"] = args.n / ns  # per-batch equivalent

    fast, slow = closed(), dop853()  # warm-up (JIT), results compared below
    for fn in paths.values():
        fn()
    times = {name: [] for name in paths}
    names = list(paths)
    for r in range(args.rounds):
        for name in names[r % len(names):] + names[:r % len(names)]:
            times[name].append(cpu(paths[name]) * scale[name])
    t = {name: np.asarray(v) for name, v in times.items()}

    print(f"machine: {machine()}; heyoka {hy_version}")
    kind = "GEAGSP box" if args.log_eigs is None else \
        f"log-uniform eigenvalues [{args.log_eigs:g}, 10]"
    print(f"{args.n} candidates ({kind}), {int(fast.converged.sum())} converge; {args.rounds} "
          f"interleaved rounds (scipy on {ns} candidates, scaled to {args.n})")
    for name, v in t.items():
        print(f"  {name:16s} median {args.n / np.median(v):10.0f} evaluations/CPU-s")
    for num, den in (("DOP853 batch", "closed form"), ("heyoka scalar", "closed form"),
                     ("DOP853 batch", "heyoka scalar"), ("scipy solve_ivp", "closed form")):
        if num in t and den in t:
            ratio = t[num] / t[den]
            print(f"  {den} faster than {num}: min {ratio.min():6.2f}x  "
                  f"median {np.median(ratio):6.2f}x")
    rel = np.abs(fast.cost - slow.cost) / np.abs(slow.cost)
    print(f"closed form vs DOP853: statuses identical {bool(np.all(fast.status == slow.status))}, "
          f"max relative cost difference {rel.max():.1e}")
    if "heyoka scalar" in paths:
        both = conv_hy & fast.converged
        err = np.max(np.abs(cost_hy[both] - fast.cost[both]) / fast.cost[both])
        differ = np.flatnonzero(conv_hy != fast.converged)
        print(f"closed form vs heyoka: converged flags differ on {differ.size} candidates "
              f"(closed form converged on {int(fast.converged[differ].sum())} of them), "
              f"max relative cost difference (converged in both) {err:.1e}")
    ref = [reference_cost(k, p) for k in K[:ns]]
    ok = np.array([r[2] for r in ref]) & fast.converged[:ns]
    ref_cost = np.array([r[0] for r in ref])
    print(f"closed form vs scipy: converged flags identical "
          f"{bool(np.all(np.array([r[2] for r in ref]) == fast.converged[:ns]))}, max "
          f"relative cost difference (converged) "
          f"{np.max(np.abs(fast.cost[:ns][ok] - ref_cost[ok]) / ref_cost[ok]):.1e}")


if __name__ == "__main__":
    main()
