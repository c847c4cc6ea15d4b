"""Near-best candidate set of the attitude LQR cells (seeded, from committed study data).

The best-known attitude LQR candidates of the budget study ``studies/attitude_convergence``
(the lowest ``best_cost`` of each (case, parameterization) cell with a full map, read from
its committed ``results.parquet`` at full precision) are perturbed in their decision vector
z: z + σ·(upper − lower)·N(0, 1), clipped to the box, decoded by the cell's
parameterization. Near the optimum some eigenvalues of R sit at the lower bound (1e-8), so
small perturbations give gains up to ~1e4 and closed-loop poles down to ~−900 1/s: the
candidates an optimizer visits late in its budget.

``near_best_set(n_per_cell, sigma, seed)`` returns a list of cells, each a dict with
``case``, ``param``, ``problem_params`` (the study's problem overrides), ``best`` (the
decoded best matrices) and ``Q``, ``R`` (arrays (n, 6, 6) and (n, 3, 3)).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun import penalty

STUDY = Path(__file__).resolve().parents[1] / "studies" / "attitude_convergence"
#: Full (non-diagonal) maps of the study's LQR cells.
PARAMS = ("geagsp", "cayley")


def best_rows() -> list[Any]:
    """Best committed job record of every attitude LQR (case, full map) cell of the study."""
    df = pd.read_parquet(STUDY / "results.parquet",
                         columns=["problem", "case", "param", "status", "best_cost", "best_z",
                                  "z_names", "problem_params", "param_options"])
    df = df[(df.problem == "attitude_lqr") & (df.status == "ok") & df.param.isin(PARAMS)]
    return [g.sort_values("best_cost").iloc[0] for _, g in df.groupby(["case", "param"])]


def near_best_set(n_per_cell: int = 64, sigma: float = 0.01, seed: int = 20261203
                  ) -> list[dict[str, Any]]:
    """Seeded perturbations of the best-known candidates (see the module docstring)."""
    rng = np.random.default_rng(seed)
    cells = []
    for row in best_rows():
        opts = json.loads(row.param_options)
        eb = tuple(opts.get("eig_bounds") or (1e-8, 10.0))
        maps = {"Q": penalty.make(row.param, 6, eb, opts.get("cayley_bound", 100.0)),
                "R": penalty.make(row.param, 3, eb, opts.get("cayley_bound", 100.0))}
        z_best = np.asarray(row.best_z, dtype=float)
        names = list(row.z_names)
        out: dict[str, Any] = {"case": row.case, "param": row.param,
                               "problem_params": json.loads(row.problem_params),
                               "best_cost": float(row.best_cost)}
        Z = np.repeat(z_best[None], n_per_cell, axis=0)
        for name, m in maps.items():
            idx = [i for i, k in enumerate(names) if k.startswith(name + ".")]
            lo, hi = m.bounds()
            Z[1:, idx] += sigma * (hi - lo) * rng.standard_normal((n_per_cell - 1, len(idx)))
            Z[:, idx] = np.clip(Z[:, idx], lo, hi)
            out[name] = m.decode(Z[:, idx])
            out["best_" + name] = out[name][0]
        cells.append(out)
    return cells
