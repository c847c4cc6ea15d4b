"""The authors' companion attitude study beside ours (spec attitude.md, last section).

Cases ``schaub_detumble`` (unconstrained) and ``schaub_detumble_sat`` (|u_i| ≤ 1 N·m) of
``attitude_lyapunov``: best / median / mean / worst J over the successful starts of each
cell (optimizer × map), with their PSO numbers (20 runs, MATLAB ``particleswarm``) beside.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.report.tables import markdown

#: Their PSO results (best, median, mean, worst over 20 runs) by (case, our map name).
THEIRS: dict[tuple[str, str], tuple[float, float, float, float]] = {
    ("schaub_detumble", "diagonal"): (86.53, 95.23, 96.69, 110.96),
    ("schaub_detumble", "givens"): (55.75, 73.34, 77.14, 113.39),
    ("schaub_detumble", "cayley"): (55.15, 76.62, 75.69, 102.25),
    ("schaub_detumble_sat", "diagonal"): (49.96, 51.20, 51.25, 52.28),
    ("schaub_detumble_sat", "givens"): (48.89, 50.42, 50.55, 53.08),
    ("schaub_detumble_sat", "cayley"): (48.67, 49.94, 50.30, 54.09),
}
CASES = ("schaub_detumble", "schaub_detumble_sat")


def _fmt4(values: tuple[float, ...]) -> str:
    return " / ".join("—" if not np.isfinite(v) else f"{v:.2f}" for v in values)


def companion_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per (case, variant, optimizer, map): ours and theirs (best/median/mean/worst)."""
    sel = df[(df["problem"] == "attitude_lyapunov") & df["case"].isin(CASES)
             & (df["status"] != "failed")]
    rows = []
    for (case, variant, optimizer, param), g in sel.groupby(
            ["case", "variant", "optimizer", "param"], sort=True):
        ok = g.loc[g["best_converged"].astype(bool), "best_cost"].to_numpy(float)
        ours = (ok.min(), np.median(ok), ok.mean(), ok.max()) if ok.size else (np.nan,) * 4
        theirs = THEIRS.get((case, param))
        rows.append({"case": case, "variant": variant, "optimizer": optimizer, "map": param,
                     "starts": len(g), "converged": int(ok.size),
                     "ours best / median / mean / worst": _fmt4(ours),
                     "theirs (PSO, 20 runs)": _fmt4(theirs) if theirs else "—"})
    return pd.DataFrame(rows)


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
            "rule); GEAGSP was not in their study, their Cayley-tan map is not in ours. "
            "Optimizer implementation and budget differ: compare with care.", "",
            markdown(table), ""]


__all__ = ["THEIRS", "companion_table", "study_sections"]
