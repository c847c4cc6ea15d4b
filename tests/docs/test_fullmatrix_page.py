"""The explanation page "What a full matrix does" against its committed data.

The page's numbers are recomputed here without the docs machinery: the Parquet files read
with pandas, the best starts picked by hand, the closed loops built from the stored matrices
(LQR gain from ``scipy.linalg.solve_continuous_are``, not penaltyrun's Riccati solver), the
poles by ``numpy.linalg.eigvals``, the held-out ratios from the stored per-scenario costs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.linalg
from scipy.stats import spearmanr

ROOT = Path(__file__).resolve().parents[2]
STUDY = ROOT / "studies" / "attitude_convergence"
PAGE = ROOT / "docs" / "explanation" / "full-matrix.md"
INERTIA = np.diag([10.0, 15.0, 20.0])  # kg·m², the paper's spacecraft (docs: attitude.md)


def g3(x: float) -> str:
    return format(x, ".3g")


def records() -> pd.DataFrame:
    """Every record with its re-judged held-out JSON (None where not re-judged)."""
    df = pd.read_parquet(STUDY / "results.parquet")
    long = pd.read_parquet(STUDY / "holdout_long.parquet")
    held = {(j, h): v for j, h, v in zip(long["job_id"], long["config_hash"], long["holdout"])}
    df["held"] = [held.get((j, h)) for j, h in zip(df["job_id"], df["config_hash"])]
    return df


def closed_loop(row: pd.Series) -> np.ndarray:
    """Poles of the loop linearized at the target, x = (q_v, ω), built here."""
    mats = {k: np.asarray(v, float) for k, v in json.loads(row["matrices"]).items()}
    A = np.zeros((6, 6))
    A[:3, 3:] = 0.5 * np.eye(3)
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(INERTIA)])
    if row["problem"] == "attitude_lqr":
        P = scipy.linalg.solve_continuous_are(A, B, mats["Q"], mats["R"])
        K = np.linalg.solve(mats["R"], B.T @ P)
    else:
        K = np.hstack([mats["Kp"], mats["Kd"]])
    return np.linalg.eigvals(A - B @ K)


def cell_numbers(df: pd.DataFrame, problem: str, case: str) -> dict:
    g = df[(df["problem"] == problem) & (df["case"] == case)]
    ok = g[(g["status"] == "ok") & g["best_converged"].astype(bool)
           & (g["optimizer"] != "baseline")]
    held = ok[ok["held"].notna()]
    diag = held.loc[held[held["param"] == "diagonal"]["best_cost"].idxmin()]
    full = held.loc[held[held["param"] != "diagonal"]["best_cost"].idxmin()]
    out = {"diag": diag, "full": full}
    for key, row in (("diag", diag), ("full", full)):
        s = closed_loop(row)
        out[f"{key}_slowest"] = float(s.real.max())
        out[f"{key}_damping"] = float(np.min(-s.real / np.abs(s)))
    tables = {}
    for key, row in (("diag", diag), ("full", full)):
        h = json.loads(row["held"])
        tables[key] = pd.DataFrame({"cost": h["cost"], "arrival": h["arrival_time"]},
                                   index=h["scenario"], dtype=float)
    common = tables["diag"].index.intersection(tables["full"].index)
    jd, jf = tables["diag"].loc[common, "cost"], tables["full"].loc[common, "cost"]
    ratio = (jf / jd).to_numpy()
    out.update(ratio=ratio, median=float(np.median(ratio)), n=len(common),
               cheaper=int(np.sum(jf.to_numpy() < jd.to_numpy())), tables=tables,
               common=common)
    fulls = ok[ok["param"] != "diagonal"]
    slow = [float(closed_loop(r).real.max()) for _, r in fulls.iterrows()]
    out["rho"] = float(spearmanr(fulls["best_cost"], -np.asarray(slow)).statistic)
    out["n_full"] = len(fulls)
    return out


@pytest.fixture(scope="module")
def direct() -> dict:
    df = records()
    cells = sorted(set(zip(df["problem"], df["case"])))
    return {cell: cell_numbers(df, *cell) for cell in cells}


def test_table_rows_equal_a_direct_computation(direct):
    page = PAGE.read_text()
    for (problem, case), c in direct.items():
        d, f = c["diag"], c["full"]
        saving = 100.0 * (1.0 - f["best_cost"] / d["best_cost"])
        row = (f"| {problem} / {case} | {f['param']} | {g3(d['best_cost'])} → "
               f"{g3(f['best_cost'])} | {saving:.0f} % | {c['diag_slowest']:.2g} / "
               f"{c['full_slowest']:.2g} | {c['diag_damping']:.2f} / {c['full_damping']:.2f}"
               f" | {c['rho']:.2f} (n = {c['n_full']}) | {g3(c['median'])} "
               f"({np.quantile(c['ratio'], 0.05):.2g}–{g3(np.quantile(c['ratio'], 0.95))}) | "
               f"{c['cheaper']}/{c['n']} |")
        assert row in page, row


def test_prose_numbers_equal_a_direct_computation(direct):
    page = " ".join(PAGE.read_text().split())  # the prose wraps anywhere

    def span(values, spec):
        lo, hi = format(min(values), spec), format(max(values), spec)
        return lo if lo == hi else f"{lo} to {hi}"

    cells = list(direct.values())
    tau_full = [-1.0 / c["full_slowest"] for c in cells]
    tau_diag = [-1.0 / c["diag_slowest"] for c in cells]
    assert f"time constant 1/|σ| of {span(tau_full, '.0f')} s, against " \
           f"{span(tau_diag, '.0f')} s" in page
    assert f"ρ is {span([c['rho'] for c in cells], '.2f')}:" in page
    assert f"has a median of {span([c['median'] for c in cells], '.3g')} across" in page
    assert f"cheaper on at most {max(c['cheaper'] for c in cells)} of the" in page
    savings = [100.0 * (1 - c["full"]["best_cost"] / c["diag"]["best_cost"]) for c in cells]
    assert f"training energy by {span(savings, '.0f')} % in all {len(cells)}" in page


def test_example_start_is_the_median_scenario(direct):
    c = direct[("attitude_lyapunov", "detumble")]
    labels = sorted(str(s) for s in c["common"])
    d, f = c["tables"]["diag"].loc[labels], c["tables"]["full"].loc[labels]
    ratio = (f["cost"] / d["cost"]).to_numpy()
    # closest to the median ratio in log scale; the first such label in sorted order
    label = labels[int(np.argmin(np.abs(np.log(ratio) - np.log(np.median(ratio)))))]
    diag, full = d.loc[label], f.loc[label]
    page = " ".join(PAGE.read_text().split())
    assert f"held-out start `{label}`" in page
    assert f"arrives after {diag['arrival']:.0f} s having spent J = {g3(diag['cost'])}" in page
    assert f"arrives after {full['arrival']:.0f} s having spent J = {g3(full['cost'])}" in page
