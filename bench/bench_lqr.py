"""problem=lqr: CPU time per evaluation of a 10-state plant without saturation.

Production path (batched Hamiltonian Riccati solve + closed-form cost by batched
eigendecomposition) against two independent references measured in the same run: scipy
``solve_continuous_are`` + ``solve_continuous_lyapunov`` + ``expm`` (closed form), and scipy
``solve_continuous_are`` + ``solve_ivp`` (DOP853 on the state and the running cost). CPU time
(``time.process_time``). Usage: ``python bench/bench_lqr.py [--n 200] [--states 10]``.

CPU time counts every BLAS thread: for matrices this small a threaded BLAS spends more CPU
than it saves (mostly in the scipy references, called one matrix at a time), so the
script prints the thread setting; ``OPENBLAS_NUM_THREADS=1`` measures single-threaded
LAPACK on both sides.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from machine import machine

from penaltyrun import problems
from penaltyrun.problems.lqr import reference


def random_plant(rng: np.random.Generator, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """A random unstable n-state, m-input plant (controllable almost surely)."""
    return rng.normal(size=(n, n)) / np.sqrt(n), rng.normal(size=(n, m))


def spd_batch(rng: np.random.Generator, count: int, size: int) -> np.ndarray:
    L = rng.normal(size=(count, size, size))
    return L @ np.swapaxes(L, 1, 2) / size + 0.1 * np.eye(size)


def cpu_per_call(func, repeats: int) -> float:
    t0 = time.process_time()
    for _ in range(repeats):
        func()
    return (time.process_time() - t0) / repeats


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n", type=int, default=200, help="candidates per batch")
    parser.add_argument("--states", type=int, default=10)
    parser.add_argument("--inputs", type=int, default=3)
    parser.add_argument("--starts", type=int, default=5, help="training initial states")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    n, m = args.states, args.inputs
    A, B = random_plant(rng, n, m)
    X0 = rng.normal(size=(args.starts, n))
    prob = problems.make("lqr", None, {"A": A.tolist(), "B": B.tolist(), "x0": X0.tolist(),
                                       "t_max": 10.0})
    Q, R = spd_batch(rng, args.n, n), spd_batch(rng, args.n, m)
    Wx, Wu = prob.Wx, prob.Wu

    prob.evaluate_batch({"Q": Q[:2], "R": R[:2]})  # warm-up, not timed
    batch = cpu_per_call(lambda: prob.evaluate_batch({"Q": Q, "R": R}), args.repeats) / args.n
    single = cpu_per_call(lambda: [prob.evaluate_batch({"Q": Q[c:c + 1], "R": R[c:c + 1]})
                                   for c in range(20)], args.repeats) / 20

    n_ref = min(args.n, 50)
    ref_cost = np.empty(n_ref)

    def closed_form_reference() -> None:
        for c in range(n_ref):
            ref_cost[c] = reference.linear_cost(A, B, Q[c], R[c], Wx, Wu, X0, 10.0).mean()

    closed = cpu_per_call(closed_form_reference, 1) / n_ref
    n_ivp = 5
    ivp_cost = np.empty(n_ivp)

    def ivp_reference() -> None:
        for c in range(n_ivp):
            K = reference.gain(A, B, Q[c], R[c])
            ivp_cost[c] = np.mean([reference.integrated_cost(prob.plant.f, K, x, Wx, Wu, None,
                                                             10.0, rtol=1e-10, atol=1e-12)[0]
                                   for x in X0])

    ivp = cpu_per_call(ivp_reference, 1) / n_ivp
    cost = prob.evaluate_batch({"Q": Q, "R": R}).cost
    err_closed = np.max(np.abs(cost[:n_ref] / ref_cost - 1.0))
    err_ivp = np.max(np.abs(cost[:n_ivp] / ivp_cost - 1.0))

    print(f"machine: {machine()}")
    threads = {k: os.environ.get(k, "unset") for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    print("BLAS threads: " + ", ".join(f"{k}={v}" for k, v in threads.items()))
    print(f"plant: {n} states, {m} inputs, {args.starts} starts, T = 10, no saturation")
    print(f"production, batch of {args.n}:     {1e3 * batch:8.3f} ms CPU per evaluation")
    print(f"production, one at a time:       {1e3 * single:8.3f} ms CPU per evaluation")
    print(f"reference scipy CARE+Lyap+expm:  {1e3 * closed:8.3f} ms CPU per evaluation "
          f"(ratio {closed / batch:.1f}x batch, {closed / single:.1f}x single)")
    print(f"reference scipy CARE+solve_ivp:  {1e3 * ivp:8.3f} ms CPU per evaluation "
          f"(ratio {ivp / batch:.0f}x batch, {ivp / single:.0f}x single)")
    print(f"max relative cost difference: {err_closed:.1e} (closed form), "
          f"{err_ivp:.1e} (solve_ivp)")


if __name__ == "__main__":
    main()
