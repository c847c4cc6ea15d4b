"""pso_matlab: the algorithm page's reading against the shipped particleswarm.m's, on
standard test functions.

Prints, per function and reading (``neighbourhood`` / ``stall_test`` / ``inertia_update``),
the median best cost and the min / median / max evaluations of 10 seeded runs with MATLAB's
default options (swarm min(100, 10·nvars), ≤ 200·nvars iterations, stall 1e-6 over 20).
Numbers quoted in penaltyrun/optim/pso_matlab.py.

    python bench/pso_matlab_inertia.py
"""

from __future__ import annotations

import numpy as np

from penaltyrun.optim.pso_matlab import PSOMatlabSettings, run_pso_matlab

CENTER = np.array([0.3, -0.2, 0.5])
FUNCTIONS = {
    "sphere 3-D": (lambda Z: ((Z - CENTER) ** 2).sum(1), -np.ones(3), np.ones(3)),
    "sphere 12-D": (lambda Z: ((Z - 0.1) ** 2).sum(1), -np.ones(12), np.ones(12)),
    "Rastrigin 6-D": (lambda Z: 10 * Z.shape[1] + (Z**2 - 10 * np.cos(2 * np.pi * Z)).sum(1),
                      -5.12 * np.ones(6), 5.12 * np.ones(6)),
    "Rosenbrock 6-D": (lambda Z: (100 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2
                                  + (1 - Z[:, :-1]) ** 2).sum(1), -2 * np.ones(6), 2 * np.ones(6)),
}

#: (neighbourhood, stall_test, inertia_update): the page read literally, the page with the
#: inertia rule after every iteration (the default before 2026-11-30), the shipped code.
READINGS = (("others", "page", "on_improvement"), ("others", "page", "every_iteration"),
            ("with_self", "code", "every_iteration"))


def main() -> None:
    """Print the comparison table (markdown)."""
    print("| function | neighbourhood / stall_test / inertia_update | median best | "
          "evaluations min / median / max |")
    print("|---|---|---|---|")
    for name, (func, lb, ub) in FUNCTIONS.items():
        for reading in READINGS:
            settings = PSOMatlabSettings(**dict(zip(("neighbourhood", "stall_test",
                                                     "inertia_update"), reading)))
            runs = [run_pso_matlab(func, lb, ub, settings, seed) for seed in range(10)]
            evals = [r.n_evals for r in runs]
            print(f"| {name} | {' / '.join(reading)} | "
                  f"{np.median([r.best_cost for r in runs]):.2g} | "
                  f"{min(evals)} / {int(np.median(evals))} / {max(evals)} |")


if __name__ == "__main__":
    main()
