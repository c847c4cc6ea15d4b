"""How many of a run's best gains still converge as the event check gets coarser?

The production kernel (DOP853) probes the terminal event on its dense output; here the probes
are set to ``n_event_samples`` points per step of at most ``max_step`` seconds (``event_spacing
= max_step / n_event_samples``), the detector of the earlier DOPRI5 kernel. This script re-
evaluates the best gains of recorded companion diagonal runs over a grid of (max step, samples
per step). ``n_event_samples = 1`` is a step-end-only detector (``event_spacing = inf``). It
counts how many bests converge and gives the median J of those that do.

Usage::

    python bench/fidelity_event_resolution.py LABEL=RUN/results.parquet [...] \
        --out studies/fidelity_gap/event_resolution.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
from fidelity_event import candidates, kernel_eval

#: (max step s, event samples per step); the first is the earlier kernel's production setting.
GRID = [(0.2, 4), (0.2, 1), (1.0, 1), (5.0, 1), (35.0, 1), (35.0, 4), (35.0, 16), (0.2, 16)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="LABEL=results.parquet")
    ap.add_argument("--out", default="studies/fidelity_gap/event_resolution.csv")
    args = ap.parse_args()
    rows = []
    for spec in args.runs:
        label, path = spec.split("=", 1)
        gains = np.stack(candidates([path], 0, 0.0, 0)["gains"].to_numpy())
        for max_step, samples in GRID:
            res = kernel_eval(gains, {"max_step": max_step, "n_event_samples": samples,
                                      "event_spacing": np.inf if samples == 1
                                      else max_step / samples})
            conv = res["converged"].to_numpy()
            rows.append({"bests_of": label, "max_step_s": max_step,
                         "n_event_samples": samples, "step_end_only": samples == 1,
                         "n_bests": len(res), "n_converged": int(conv.sum()),
                         "median_J_converged": float(np.median(res["J"][conv]))
                         if conv.any() else np.nan})
    table = pd.DataFrame(rows)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out, index=False, float_format="%.8g")
    print(table.to_string(index=False))


if __name__ == "__main__":
    main()
