"""Write the seeded random plants of the study ``lqr_scaling`` as experiment profiles.

One profile per size n ∈ {4, 8, 16, 32}: ``penaltyrun/conf/experiment/lqr_scaling_n<n>.yaml``
holds the plant and the performance weights of ``problem=lqr`` as plain numbers (6
decimals), so the study's objective is defined by the committed YAML alone; this script only
documents where the numbers came from and rewrites them identically. For size n, from
``numpy.random.default_rng(SEED_BASE + n)``:

* m = max(1, n // 4) inputs; A = N(0, 1)^{n×n} / √n (a few unstable modes), B = N(0, 1)^{n×m}
  (controllable almost surely; checked here by the rank of the controllability matrix);
* W_x = V diag(u) Vᵀ and W_u likewise, V the Q factor of a Gaussian matrix and u uniform in
  [0.5, 5]: non-diagonal weights whose eigenvalues lie well inside the eigenvalue box
  [0.05, 50], so the optimum Q = c W_x, R = c W_u (a ray, c > 0) is inside the box for the
  full maps and out of reach of the diagonal map;
* the training starts are the n unit vectors (the default), horizon t_max (default 60) long
  enough that the finite-horizon cost at (W_x, W_u) is within 1e-12 of J* (checked here).

Usage: ``python bench/lqr_scaling_plants.py`` (prints per n the variables of each map, the
open-loop unstable modes, J* and the horizon gap).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from penaltyrun.problems import lqr

SEED_BASE = 20261203
SIZES = (4, 8, 16, 32)
BOUNDS = (0.05, 50.0)
T_MAX = 60.0
OUT = Path(__file__).resolve().parents[1] / "penaltyrun" / "conf" / "experiment"


def plant(n: int) -> dict[str, list]:
    """A, B, W_x, W_u of size n (rounded to 6 decimals, weights exactly symmetric)."""
    rng = np.random.default_rng(SEED_BASE + n)
    m = max(1, n // 4)

    def spd(k: int) -> np.ndarray:
        V = np.linalg.qr(rng.normal(size=(k, k)))[0]
        W = np.round(V @ np.diag(rng.uniform(0.5, 5.0, k)) @ V.T, 6)
        return np.triu(W) + np.triu(W, 1).T

    A = np.round(rng.normal(size=(n, n)) / np.sqrt(n), 6)
    B = np.round(rng.normal(size=(n, m)), 6)
    Wx, Wu = spd(n), spd(m)
    ctrb = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])
    if np.linalg.matrix_rank(ctrb) < n:
        raise RuntimeError(f"n={n}: the plant is not controllable; change SEED_BASE")
    return {"A": A.tolist(), "B": B.tolist(), "state_weight": Wx.tolist(),
            "input_weight": Wu.tolist()}


def flow(matrix: list) -> str:
    rows = ", ".join("[" + ", ".join(f"{v:.6f}".rstrip("0").rstrip(".") if v else "0"
                                     for v in row) + "]" for row in matrix)
    return f"[{rows}]"


def profile(n: int, values: dict[str, list]) -> str:
    m = len(values["input_weight"])
    lines = [
        "# @package _global_",
        f"# The seeded random plant of n = {n} states and {m} input(s) of the study lqr_scaling "
        "(A, B and",
        "# non-diagonal performance weights; optimum Q = c W_x, R = c W_u). The study's "
        "commands set the",
        "# optimizer, the map and the budget. Numbers drawn by bench/lqr_scaling_plants.py "
        f"(seed {SEED_BASE} + {n}).",
        "defaults:",
        "  - override /problem: lqr",
        "",
        "problem:",
        "  params:",
        f"    t_max: {T_MAX}",
        f"    q_bounds: [{BOUNDS[0]}, {BOUNDS[1]}]",
        f"    r_bounds: [{BOUNDS[0]}, {BOUNDS[1]}]",
        "    holdout_n: 0",
    ]
    for key in ("A", "B", "state_weight", "input_weight"):
        lines.append(f"    {key}: {flow(values[key])}")
    return "\n".join(lines) + "\n"


def main() -> None:
    for n in SIZES:
        values = plant(n)
        path = OUT / f"lqr_scaling_n{n}.yaml"
        path.write_text(profile(n, values), encoding="utf-8")
        prob = lqr.make_problem("default", {**values, "t_max": T_MAX, "q_bounds": list(BOUNDS),
                                            "r_bounds": list(BOUNDS), "holdout_n": 0})
        m = len(values["input_weight"])
        at = prob.evaluate({"Q": np.asarray(values["state_weight"]),
                            "R": np.asarray(values["input_weight"])})
        unstable = int(np.sum(np.linalg.eigvals(np.asarray(values["A"])).real > 0))
        full = n * (n + 1) // 2 + m * (m + 1) // 2
        print(f"n={n:2d} m={m} diagonal {n + m:3d} / full {full:3d} variables, "
              f"{unstable} unstable modes, J*={prob.optimum:.12g}, "
              f"J_T(W_x, W_u)/J* - 1 = {at['cost'] / prob.optimum - 1:.2e} -> {path.name}")


if __name__ == "__main__":
    main()
