"""The exact LQR gradient's three Lyapunov solves: one shared Schur decomposition
(:class:`penaltyrun.dynamics.lyapunov.SchurLyapunov`) against three independent
Bartels–Stewart solves (``scipy.linalg.solve_continuous_lyapunov``, the baseline, measured
in the same run).

On the plants of the study ``lqr_scaling`` (map ``givens``), at ``--points`` candidates in
the middle of the box: each candidate's stabilizing gain K is computed first (untimed), then
:func:`penaltyrun.problems.lqr.gradient.gain_gradient` (the part of a gradient that solves
the Lyapunov equations) is timed with the shared decomposition and with the baseline,
interleaved, one BLAS thread. Prints per n the median milliseconds of each, the ratio
baseline / shared (min and median over the points) and the largest relative difference of
the two gradients.

Usage: ``OPENBLAS_NUM_THREADS=1 python bench/lyapunov_reuse.py [--sizes 4 8 16 32]
[--points 30]``.
"""

from __future__ import annotations

import argparse
from unittest import mock

import numpy as np
from lqr_scaling_ratio import problem
from machine import machine
from scipy.linalg import solve_continuous_lyapunov
from timing import interleaved

from penaltyrun.dynamics.lyapunov import SchurLyapunov
from penaltyrun.problems.lqr import gradient as lqr_gradient
from penaltyrun.runner.job import blas_limit
from penaltyrun.runner.setup import build_layout


class Solvers:
    """Stands in for ``SchurLyapunov`` in the gradient module during a measurement, so that
    both timed paths go through the same call: ``baseline`` chooses which solver it makes
    (setting it costs the same on both paths, and nothing is patched inside a timed call)."""

    baseline = False

    def __call__(self, A: np.ndarray) -> object:
        return IndependentSolves(A) if self.baseline else SchurLyapunov(A)


class IndependentSolves:
    """The baseline: every Lyapunov equation solved on its own by scipy (its own Schur
    decomposition each time), with the interface of ``SchurLyapunov``."""

    def __init__(self, A: np.ndarray) -> None:
        self.A = A

    def solve(self, C: np.ndarray, transpose: bool = False) -> np.ndarray:
        return solve_continuous_lyapunov(self.A.T if transpose else self.A, C)


def measure(n: int, points: int) -> str:
    """One row of the table: plant n, ``points`` candidates."""
    prob = problem(n)
    layout = build_layout(prob, "givens", {})
    lb, ub = layout.bounds()
    rng = np.random.default_rng(0)
    cases = []
    for z in lb + (ub - lb) * rng.uniform(0.3, 0.7, size=(points, lb.size)):
        mats, _ = layout.split(z[None])
        Q, R = mats["Q"][0], mats["R"][0]
        cases.append((Q, R, prob.rows(Q[None], R[None], prob.x0)["K"][0]))

    solvers = Solvers()

    def shared(k: np.ndarray) -> tuple:
        solvers.baseline = False
        return lqr_gradient.gain_gradient(prob, *cases[int(k[0])])

    def baseline(k: np.ndarray) -> tuple:
        solvers.baseline = True
        return lqr_gradient.gain_gradient(prob, *cases[int(k[0])])

    which = np.arange(points, dtype=float)[:, None]  # the "point" is the case's index
    with mock.patch.object(lqr_gradient, "SchurLyapunov", solvers):
        seconds = interleaved([shared, baseline], which)
        diff = max(float(np.abs(a - b).max() / np.abs(b).max())
                   for k in which for a, b in zip(shared(k)[1:], baseline(k)[1:]))
    ratio = seconds[:, 1] / seconds[:, 0]
    return (f"{n:>3} {1e3 * np.median(seconds[:, 0]):10.3f} "
            f"{1e3 * np.median(seconds[:, 1]):12.3f} {ratio.min():10.2f} "
            f"{np.median(ratio):7.2f} {diff:13.1e}")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", type=int, nargs="+", default=[4, 8, 16, 32])
    ap.add_argument("--points", type=int, default=30)
    args = ap.parse_args()
    print(machine())
    print(f"{'n':>3} {'shared ms':>10} {'baseline ms':>12} {'ratio min':>10} {'median':>7} "
          f"{'max rel diff':>13}")
    with blas_limit():
        for n in args.sizes:
            print(measure(n, args.points), flush=True)


if __name__ == "__main__":
    main()
