"""Re-evaluate every committed Zermelo job's best K with the production path.

For each Zermelo record in ``studies/*/results.parquet`` the stored best matrix is evaluated
again by ``evaluate_batch`` (closed form for symmetric PD K, the DOP853 integrator for the
rest) and by the DOP853 integrator alone, with the record's own problem parameters; printed:
per study the number of records, the largest relative difference to the stored best cost
and between the two paths, and whether every status matches. Usage::

    python bench/check_zermelo_studies.py [studies]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun import problems
from penaltyrun.dynamics.zermelo import simulate_batch


def integrator_cost(prob, K: np.ndarray) -> float:  # noqa: ANN001
    """Graded cost of ``K`` from the DOP853 integrator alone (single-scenario problems)."""
    p = prob.params
    res = simulate_batch(np.ascontiguousarray(K[None]), np.asarray(p.x0, float), p.t_max,
                         p.event_radius, p.rtol, p.atol, p.max_step, p.max_steps)
    return float(prob._graded(*res, float(np.hypot(*p.x0))).cost[0])


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "studies")
    for path in sorted(root.glob("*/results.parquet")):
        df = pd.read_parquet(path)
        df = df[(df.problem == "zermelo") & (df.status == "ok")]
        if df.empty:
            continue
        worst_stored = worst_paths = 0.0
        same_status = True
        for _, row in df.iterrows():
            params = {k: v for k, v in json.loads(row.problem_params).items() if v is not None}
            prob = problems.make("zermelo", row.case, params)
            K = np.asarray(json.loads(row.matrices)["K"], float)
            res = prob.evaluate_batch({"K": K[None]})
            cost = float(res.cost[0])
            worst_stored = max(worst_stored, abs(cost - row.best_cost) / abs(row.best_cost))
            same_status &= str(res.status[0]) == row.best_status
            if hasattr(prob, "params") and hasattr(prob.params, "x0"):
                ref = integrator_cost(prob, K)
                worst_paths = max(worst_paths, abs(cost - ref) / abs(ref))
        print(f"{path.parent.name}: {len(df)} records; max rel. diff to stored best cost "
              f"{worst_stored:.1e}; closed form vs DOP853 {worst_paths:.1e}; "
              f"statuses {'identical' if same_status else 'DIFFER'}")


if __name__ == "__main__":
    main()
