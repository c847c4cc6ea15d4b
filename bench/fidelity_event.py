"""Does a step-end-only event detector (as MATLAB's ode113 uses) change the cost of good
candidates of the companion diagonal cell?

The production kernel (DOP853, the event probed on the dense output every ``event_spacing``
seconds near the threshold) finds the FIRST time the weighted distance falls to the threshold.
MATLAB's ``ode113`` (variable-order Adams–Bashforth–Moulton, default MaxStep = tf/10 = 35 s)
checks the event sign only at the ends of the steps it takes, so a short dip under the
threshold inside one step is not seen; the run then goes on, accumulating energy, to a later
crossing (a larger J) or to t_f (a failure). This script evaluates the best candidates of
recorded runs, and seeded perturbations of them, with four detectors:

* ``first_crossing``: the production kernel (reference);
* ``kernel_stepend_35s``: the same kernel with max step 35 s and the event at step ends only
  (``event_spacing = inf``);
* ``lsoda_stepend``: scipy ``LSODA`` (Adams methods on this non-stiff problem), no max step,
  events at step ends (``solve_ivp`` semantics), rel = abs tolerance 1e-10 — the closest
  scipy analogue of ode113;
* ``dop853_stepend``: scipy ``DOP853``, no max step, events at step ends.

Usage::

    python bench/fidelity_event.py RUN/results.parquet [...] --out studies/fidelity_gap \
        --n-perturb 6 --rel 0.05 --scipy-max 60

Writes ``event_detectors_candidates.csv`` (one row per candidate and detector; for the runs'
bests also the first stretch under the threshold: start, duration, depth 1 − min d / tol)
and ``event_detectors_summary.csv`` (per detector and candidate set: how many change
outcome, how many converged candidates become failures).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.problems import make
from penaltyrun.problems.attitude.reference import reference_run

CASE = "schaub_detumble"
#: Relative J change and event-time change (s) counted as "a different outcome".
REL_J, DT = 1e-6, 1e-3


def candidates(paths: list[str], n_perturb: int, rel: float, seed: int) -> pd.DataFrame:
    """Diagonal (Kp, Kd) of every run's best and ``n_perturb`` perturbations of each
    (every entry × (1 + rel · U(−1, 1)))."""
    rows = []
    rng = np.random.default_rng(seed)
    for path in paths:
        df = pd.read_parquet(path)
        for _, r in df[df["best_converged"].astype(bool)].iterrows():
            m = json.loads(r["matrices"])
            g = np.concatenate([np.diag(m["Kp"]), np.diag(m["Kd"])])
            rows.append({"source": f"{Path(path).parent.name}:best", "job_id": r["job_id"],
                         "gains": g})
            for k in range(n_perturb):
                rows.append({"source": f"{Path(path).parent.name}:perturbed",
                             "job_id": f"{r['job_id']}~{k}",
                             "gains": g * (1.0 + rel * rng.uniform(-1.0, 1.0, 6))})
    return pd.DataFrame(rows)


def kernel_eval(gains: np.ndarray, overrides: dict) -> pd.DataFrame:
    prob = make("attitude_lyapunov", CASE, {"objective_form": "cost", **overrides})
    mats = {"Kp": np.stack([np.diag(g[:3]) for g in gains]),
            "Kd": np.stack([np.diag(g[3:]) for g in gains])}
    G, ok = prob.gains(mats)
    res = prob._finish(G, ok, None, prob.d0)
    return pd.DataFrame({"J": res["energy"], "t_event": res["t_final"],
                         "converged": res["converged"]})


def scipy_eval(gains: np.ndarray, method: str) -> pd.DataFrame:
    params = make("attitude_lyapunov", CASE, {"max_step": np.inf}).params
    out = []
    for g in gains:
        G = np.concatenate([np.diag(g[:3]), np.diag(g[3:])], axis=1)
        r = reference_run(G, params, method=method)
        out.append({"J": r["energy"], "t_event": r["t_final"], "converged": r["converged"]})
    return pd.DataFrame(out)


def first_dip(gains: np.ndarray, n_points: int = 35001) -> pd.DataFrame:
    """Duration (s) and depth (1 − min d / tol) of the first stretch under the threshold,
    from scipy DOP853 dense output on [0, t_f] (max step 0.2 s, 0.01 s sampling)."""
    from penaltyrun.problems.attitude.reference import trajectory

    params = make("attitude_lyapunov", CASE).params
    out = []
    for g in gains:
        G = np.concatenate([np.diag(g[:3]), np.diag(g[3:])], axis=1)
        tr = trajectory(G, params, params.t_max, n_points)
        under = tr["dist"] <= params.tol
        if not under.any():
            out.append({"dip_start_s": np.nan, "dip_duration_s": np.nan, "dip_depth": np.nan})
            continue
        i = int(np.argmax(under))
        j = i + int(np.argmin(under[i:])) if not under[i:].all() else under.size
        out.append({"dip_start_s": float(tr["t"][i]),
                    "dip_duration_s": float(tr["t"][min(j, under.size - 1)] - tr["t"][i]),
                    "dip_depth": float(1.0 - tr["dist"][i:j].min() / params.tol)})
    return pd.DataFrame(out)


def summarize(table: pd.DataFrame) -> pd.DataFrame:
    """Per detector and candidate set: how many candidates converge under the reference
    and under the detector, how many change outcome, J and event-time changes."""
    summary = []
    for (name, source), g in table.groupby(["detector", "source"], sort=False):
        lost = g["converged_first_crossing"] & ~g["converged"]
        later = g["converged"] & (g["t_change_s"] > DT)
        summary.append({
            "detector": name, "candidates": source, "n": len(g),
            "n_converged_first_crossing": int(g["converged_first_crossing"].sum()),
            "n_converged_this_detector": int(g["converged"].sum()),
            "n_outcome_differs": int(g["outcome_differs"].sum()),
            "n_converged_becomes_failed": int(lost.sum()),
            "n_failed_becomes_converged": int((~g["converged_first_crossing"]
                                               & g["converged"]).sum()),
            "n_later_crossing": int(later.sum()),
            "max_rel_J_change_converged": float(g.loc[g["converged"], "rel_J_change"].max()),
            "max_t_change_s": float(g["t_change_s"].max()),
            "median_first_dip_duration_s": float(g["dip_duration_s"].median()),
            "median_first_dip_depth": float(g["dip_depth"].median()),
        })
    return pd.DataFrame(summary)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="results.parquet of companion diagonal runs")
    ap.add_argument("--out", default="studies/fidelity_gap")
    ap.add_argument("--n-perturb", type=int, default=6)
    ap.add_argument("--rel", type=float, default=0.05)
    ap.add_argument("--scipy-max", type=int, default=60,
                    help="scipy detectors on the first this many candidates (slow)")
    ap.add_argument("--seed", type=int, default=20250422)
    ap.add_argument("--from-csv", action="store_true",
                    help="only rebuild the summary from OUT/event_detectors_candidates.csv")
    args = ap.parse_args()
    out = Path(args.out)
    if args.from_csv:
        table = pd.read_csv(out / "event_detectors_candidates.csv")
        summarize(table).to_csv(out / "event_detectors_summary.csv", index=False)
        return
    cand = candidates(args.runs, args.n_perturb, args.rel, args.seed)
    gains = np.stack(cand["gains"].to_numpy())
    detectors = {
        "first_crossing": lambda g: kernel_eval(g, {}),
        "kernel_stepend_35s": lambda g: kernel_eval(g, {"max_step": 35.0,
                                                        "n_event_samples": 1,
                                                        "event_spacing": np.inf}),
        "lsoda_stepend": lambda g: scipy_eval(g[:args.scipy_max], "LSODA"),
        "dop853_stepend": lambda g: scipy_eval(g[:args.scipy_max], "DOP853"),
    }
    frames = []
    ref = None
    for name, run in detectors.items():
        c0 = time.process_time()
        res = run(gains)
        cpu = time.process_time() - c0
        print(f"{name}: {len(res)} candidates, {cpu:.1f} s CPU")
        res.insert(0, "detector", name)
        res.insert(1, "candidate", cand["job_id"].to_numpy()[:len(res)])
        res.insert(2, "source", cand["source"].to_numpy()[:len(res)])
        if ref is None:
            ref = res
        res["J_first_crossing"] = ref["J"].to_numpy()[:len(res)]
        res["t_first_crossing"] = ref["t_event"].to_numpy()[:len(res)]
        res["converged_first_crossing"] = ref["converged"].to_numpy()[:len(res)]
        frames.append(res)
    table = pd.concat(frames, ignore_index=True)
    table["rel_J_change"] = (table["J"] - table["J_first_crossing"]) / table["J_first_crossing"]
    table["t_change_s"] = table["t_event"] - table["t_first_crossing"]
    table["outcome_differs"] = ((table["converged"] != table["converged_first_crossing"])
                                | (table["rel_J_change"].abs() > REL_J)
                                | (table["t_change_s"].abs() > DT))
    best = cand["source"].str.endswith(":best").to_numpy()
    dips = first_dip(gains[best])
    dips.insert(0, "candidate", cand["job_id"].to_numpy()[best])
    table = table.merge(dips, on="candidate", how="left")
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / "event_detectors_candidates.csv", index=False)
    summary = summarize(table)
    summary.to_csv(out / "event_detectors_summary.csv", index=False)
    print(summary.to_string(index=False))


if __name__ == "__main__":
    main()
