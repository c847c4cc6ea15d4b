"""Evaluation counts and costs of companion-cell runs beside the authors' published ones.

Each run directory's best candidates are also re-evaluated with the production kernel
(first-crossing event, the case's default step and event settings), so runs tuned under
another event detector are compared on the same J.

Usage::

    python bench/fidelity_summary.py LABEL=RUN_DIR [LABEL=RUN_DIR ...] \
        --out studies/fidelity_gap/acceptance.csv

Also writes ``<out stem>_starts.csv``: one row per start (run, start, seed, evaluations,
stop reason, J recorded and under the production kernel, event time).

Columns: ``run`` (label), ``objective_form``, ``max_step_s``, ``n_event_samples`` and
``event_spacing_s`` (the event detector the optimizer saw; ``inf`` spacing with one sample
per step: step ends only), ``starts``, evaluation counts (median, min, max and the
ratio of the median to the authors' 12 450), J as recorded (``J_recorded_*``) and J of the
same gains under the production kernel (``J_production_*``: best, median, mean, worst;
NaN for a start whose best does not converge there, counted in
``n_fail_production``), then the authors' values (companion diagonal cells only, else
NaN; no published function counts for the saturated cell).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.problems import make
from penaltyrun.problems.attitude.report import COMPANION, COMPANION_EVALS


def _authors(case: str) -> dict[str, float]:
    """The authors' diagonal PSO cell of ``case`` (20 runs): J best / median / mean / worst
    and, where published, the median and range of their function counts."""
    best, median, mean, worst = COMPANION[case]["diagonal"]
    row = {"J_best": best, "J_median": median, "J_mean": mean, "J_worst": worst}
    low, mid, high = COMPANION_EVALS.get(case, {}).get("diagonal", (np.nan,) * 3)
    return {**row, "evals_median": mid, "evals_min": low, "evals_max": high}


#: The authors' unconstrained diagonal cell, and their saturated (|u_i| <= 1 N·m) one.
AUTHORS = _authors("schaub_detumble")
AUTHORS_SAT = _authors("schaub_detumble_sat")


def production_costs(df: pd.DataFrame, case: str) -> np.ndarray:
    """J of each row's best matrices under the production kernel (NaN: not converged)."""
    prob = make("attitude_lyapunov", case, {"objective_form": "cost"})
    out = []
    for m in df["matrices"]:
        res = prob.evaluate({k: np.asarray(v) for k, v in json.loads(m).items()})
        out.append(res["energy"] if res["converged"] else np.nan)
    return np.asarray(out, dtype=float)


def summarize(label: str, run_dir: Path) -> tuple[dict, pd.DataFrame]:
    df = pd.read_parquet(run_dir / "results.parquet")
    params = [json.loads(p) for p in df["problem_params"]]
    metrics = [json.loads(m) for m in df["metrics"]]
    forms = sorted({m.get("objective_form", "cost") for m in metrics})
    case = str(df["case"].iloc[0])
    rec = df["best_cost"].where(df["best_converged"].astype(bool)).astype(float)
    prod = production_costs(df, case)
    row = {"run": label, "case": case, "objective_form": "/".join(forms),
           "max_step_s": params[0].get("max_step"),
           "n_event_samples": params[0].get("n_event_samples"),
           "event_spacing_s": params[0].get("event_spacing"),
           "starts": len(df),
           "evals_median": float(df["n_evals"].median()),
           "evals_min": int(df["n_evals"].min()), "evals_max": int(df["n_evals"].max()),
           "evals_median_over_authors": float(df["n_evals"].median())
           / AUTHORS["evals_median"] if case == "schaub_detumble" else np.nan,
           "n_stopped_by_stall": int((df["stop_reason"] == "ftol").sum())}
    for name, values in (("J_recorded", rec.to_numpy()), ("J_production", prod)):
        ok = values[np.isfinite(values)]
        row.update({f"{name}_best": ok.min() if ok.size else np.nan,
                    f"{name}_median": float(np.median(ok)) if ok.size else np.nan,
                    f"{name}_mean": ok.mean() if ok.size else np.nan,
                    f"{name}_worst": ok.max() if ok.size else np.nan})
    row["n_fail_production"] = int(np.sum(~np.isfinite(prod)))
    diagonal = set(df["param"]) == {"diagonal"}
    theirs = {"schaub_detumble": AUTHORS, "schaub_detumble_sat": AUTHORS_SAT}.get(case, {})
    row.update({f"authors_{k}": theirs.get(k, np.nan) if diagonal else np.nan
                for k in AUTHORS})
    starts = pd.DataFrame({"run": label, "start": df["start"], "seed": df["seed"],
                           "n_evals": df["n_evals"], "stop_reason": df["stop_reason"],
                           "J_recorded": rec.to_numpy(), "J_production": prod,
                           "t_event_s": df["t_final"]})
    return row, starts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="LABEL=RUN_DIR (a directory with results.parquet)")
    ap.add_argument("--out", default="studies/fidelity_gap/acceptance.csv")
    args = ap.parse_args()
    done = [summarize(label, Path(path))
            for label, path in (spec.split("=", 1) for spec in args.runs)]
    table = pd.DataFrame([row for row, _ in done])
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(out, index=False, float_format="%.6g")
    pd.concat([starts for _, starts in done], ignore_index=True).to_csv(
        out.with_name(out.stem + "_starts.csv"), index=False, float_format="%.8g")
    print(table.T.to_string())


if __name__ == "__main__":
    main()
