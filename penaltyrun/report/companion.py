"""The authors' companion attitude study beside ours.

Cases ``schaub_detumble`` (unconstrained) and ``schaub_detumble_sat`` (|u_i| ≤ 1 N·m) of
``attitude_lyapunov``: best / median / mean / worst J over the successful starts of each
cell (optimizer × map), with their PSO numbers (20 runs, MATLAB ``particleswarm``) beside.

Only their summaries are published (the repository's ``.mat`` files hold the runs but not in
a form read here), so the two-sample test is Mood's median test with their median as the
split: their 20 runs are 10 above and 10 below it by definition, ours are counted, and the
2 × 2 table goes to Fisher's exact test (two-sided), Holm-corrected over the section.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from penaltyrun.report.stats import holm
from penaltyrun.report.tables import markdown

#: Their PSO results (best, median, mean, worst over 20 runs) by (case, our map name).
THEIRS: dict[tuple[str, str], tuple[float, float, float, float]] = {
    ("schaub_detumble", "diagonal"): (86.53, 95.23, 96.69, 110.96),
    ("schaub_detumble", "givens"): (55.75, 73.34, 77.14, 113.39),
    ("schaub_detumble", "cayley"): (55.15, 76.62, 75.69, 102.25),
    ("schaub_detumble", "cayley_tan"): (60.89, 71.51, 80.05, 116.38),
    ("schaub_detumble_sat", "diagonal"): (49.96, 51.20, 51.25, 52.28),
    ("schaub_detumble_sat", "givens"): (48.89, 50.42, 50.55, 53.08),
    ("schaub_detumble_sat", "cayley"): (48.67, 49.94, 50.30, 54.09),
    ("schaub_detumble_sat", "cayley_tan"): (48.60, 50.26, 50.23, 52.07),
}
#: Runs per cell in their study.
THEIR_RUNS = 20
CASES = ("schaub_detumble", "schaub_detumble_sat")


def _fmt4(values: tuple[float, ...]) -> str:
    return " / ".join("—" if not np.isfinite(v) else f"{v:.2f}" for v in values)


def median_test(ours: np.ndarray, their_median: float, their_runs: int = THEIR_RUNS) -> float:
    """Two-sided p-value of Mood's median test of our costs against their published median.

    Parameters
    ----------
    ours : ndarray, shape (n,)
        Our costs (successful starts). Values equal to their median are left out.
    their_median : float
        Their median over ``their_runs`` runs (half of their runs lie on each side).
    their_runs : int
        Their number of runs.

    Returns
    -------
    float
        Fisher's exact test of [[ours above, ours below], [their_runs/2, their_runs/2]];
        NaN without our costs.
    """
    ours = np.asarray(ours, float)
    above, below = int((ours > their_median).sum()), int((ours < their_median).sum())
    if above + below == 0:
        return float("nan")
    half = their_runs // 2
    return float(stats.fisher_exact([[above, below], [half, their_runs - half]]).pvalue)


def companion_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per (case, variant, optimizer, map): ours and theirs (best/median/mean/worst),
    our evaluations per start and the median test against theirs (Holm-corrected)."""
    sel = df[(df["problem"] == "attitude_lyapunov") & df["case"].isin(CASES)
             & (df["status"] != "failed")]
    rows = []
    for (case, variant, optimizer, param), g in sel.groupby(
            ["case", "variant", "optimizer", "param"], sort=True):
        ok = g.loc[g["best_converged"].astype(bool), "best_cost"].to_numpy(float)
        ours = (ok.min(), np.median(ok), ok.mean(), ok.max()) if ok.size else (np.nan,) * 4
        theirs = THEIRS.get((case, param))
        evals = g["n_evals"].to_numpy(float) if "n_evals" in g else np.array([])
        rows.append({"case": case, "variant": variant, "optimizer": optimizer, "map": param,
                     "starts": len(g), "converged": int(ok.size),
                     "ours best / median / mean / worst": _fmt4(ours),
                     "theirs (PSO, 20 runs)": _fmt4(theirs) if theirs else "—",
                     "evaluations per start, median (min–max)": _fmt_evals(evals),
                     "p": median_test(ok, theirs[1]) if theirs else float("nan")})
    table = pd.DataFrame(rows)
    if not table.empty:
        table["p (Holm)"] = holm(table.pop("p").to_numpy(float))
    return table


def _fmt_evals(evals: np.ndarray) -> str:
    evals = evals[np.isfinite(evals)]
    if not evals.size:
        return "—"
    return f"{np.median(evals):.0f} ({evals.min():.0f}–{evals.max():.0f})"


def study_sections(df: pd.DataFrame, out: Path, paper: bool) -> list[str]:
    """Markdown lines of the companion-study section (empty without its cases)."""
    table = companion_table(df)
    if table.empty:
        return []
    table.to_csv(out / "companion_attitude.csv", index=False)
    return ["## Attitude: the authors' companion study (Schaub & Junkins detumble)", "",
            "Lyapunov PD law, I = diag(140, 100, 80) kg·m², MRP σ0 = (0.6, −0.4, 0.2), "
            "ω0 = (0.70, 0.20, −0.15) rad/s, t_f = 350 s, event ‖(10·q_v, ω)‖ ≤ 1e-3; "
            "`schaub_detumble_sat`: |u_i| ≤ 1 N·m. Ours: J over the converged starts of each "
            "cell. Theirs: MATLAB particleswarm (swarm min(100, 10·nvars), default stall "
            "rule; about 5 000–85 000 evaluations per run over the whole study, per cell not "
            "published); GEAGSP was not in their study. "
            "p: Mood's median test of our converged starts against their median (their 20 "
            "runs split 10/10 by definition, Fisher's exact test, two-sided), Holm-corrected "
            "over this table. Optimizer implementation and budget differ unless the optimizer "
            "is `pso_matlab` (MATLAB's particleswarm re-implemented; a variant "
            "`neighbourhood=others,stall_test=page` is the algorithm page's reading instead "
            "of the shipped code's).", "",
            markdown(table), ""]


__all__ = ["THEIRS", "THEIR_RUNS", "companion_table", "median_test", "study_sections"]
