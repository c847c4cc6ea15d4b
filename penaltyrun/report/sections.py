"""Problem-specific report sections (paper comparisons and problem figures)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from penaltyrun import problems  # noqa: E402
from penaltyrun.io import decode_json  # noqa: E402
from penaltyrun.report import attitude, companion, holdout, lowthrust, tuning  # noqa: E402
from penaltyrun.report.paper import BEST_MATRICES  # noqa: E402
from penaltyrun.report.tables import markdown  # noqa: E402

#: Share of the largest entry within which a matrix "matches" a published one.
MATCH_TOL = 0.005


def best_rows(df: pd.DataFrame) -> dict[tuple[str, str], pd.Series]:
    """Best non-failed job per (parameterization, optimizer)."""
    ok = df[df["status"] != "failed"]
    return {key: g.loc[g["best_cost"].idxmin()]
            for key, g in ok.groupby(["param", "optimizer"], sort=True)}


def matrices_of(row: pd.Series) -> dict[str, np.ndarray]:
    """Decoded best matrices of a job row."""
    return {k: np.asarray(v, float) for k, v in decode_json(row["matrices"]).items()}


def problem_of(row: pd.Series) -> Any:
    """The problem instance a job row was run with."""
    return problems.make(row["problem"], row["case"], decode_json(row["problem_params"]) or {})


def relative_deviation(K: np.ndarray, ref: np.ndarray) -> float:
    """max |K − ref| / max |ref| (entrywise, relative to the largest entry)."""
    return float(np.max(np.abs(K - ref)) / np.max(np.abs(ref)))


def zermelo_section(df: pd.DataFrame, out: Path, paper: bool, stem: str) -> list[str]:
    """Best K vs the paper's K1/K2, match counts, and the phase-plane figure."""
    mod = problems.module("zermelo")
    best = best_rows(df)
    if not best:
        return []
    prob = problem_of(next(iter(best.values())))
    rows, paths = [], {}
    ref_mats = BEST_MATRICES[("zermelo", "default")]
    for (param, optimizer), row in best.items():
        K = matrices_of(row)["K"]
        if param in ("diagonal", "full", "geagsp") and optimizer == "pso":
            paths[f"best {param} (J = {row['best_cost']:.4f})"] = prob.simulate({"K": K})
        entry = {"param": param, "optimizer": optimizer,
                 "best K": json.dumps(np.round(K, 4).tolist()), "best J": float(row["best_cost"])}
        ref = ref_mats.get("full" if param != "diagonal" else "diagonal")
        if paper and ref is not None:
            cell = df[(df["param"] == param) & (df["optimizer"] == optimizer)
                      & (df["status"] != "failed")]
            devs = [relative_deviation(matrices_of(r)["K"], ref["K"]) for _, r in cell.iterrows()]
            entry.update({
                "paper K": json.dumps(ref["K"].round(4).tolist()),
                "J(paper K), ours": prob.evaluate(ref)["cost"],
                "deviation of best K": f"{100 * relative_deviation(K, ref['K']):.3f} %",
                "starts within 0.5 %": f"{sum(d <= MATCH_TOL for d in devs)}/{len(devs)}",
            })
        rows.append(entry)
    if paper:
        for param, ref in ref_mats.items():
            paths[f"paper {param} K"] = prob.simulate(ref)
    if not any(label.startswith("best") for label in paths):
        paths.update({f"best {p} / {o}": prob.simulate(matrices_of(r))
                      for (p, o), r in best.items()})
    fig, ax = plt.subplots(figsize=(6.5, 6.5))
    mod.plot_phase_plane(paths, ax=ax)
    ax.set_title("Zermelo: closed-loop paths over the current")
    fig.tight_layout()
    fig.savefig(out / f"{stem}_phase_plane.png", dpi=120)
    plt.close(fig)
    table = pd.DataFrame(rows)
    return ["### Best matrices vs the paper's K1 (diagonal) and K2 (full)", "",
            markdown(table), "", f"![phase plane]({stem}_phase_plane.png)", ""]


#: problem name → section builder(df of one case and variant, out dir, paper flag, file stem)
#: → Markdown lines.
SECTIONS: dict[str, Callable[[pd.DataFrame, Path, bool, str], list[str]]] = {
    "zermelo": zermelo_section,
    "attitude_lyapunov": attitude.case_section,
    "attitude_lqr": attitude.case_section,
    "lyapunov_transfer": lowthrust.case_section,
    "qlaw": lowthrust.case_section,
}


def problem_section(problem: str, case: str, df: pd.DataFrame, out: Path, paper: bool,
                    stem: str) -> list[str]:
    """Markdown lines of the problem-specific section (empty if none is registered)."""
    builder = SECTIONS.get(problem)
    return builder(df, out, paper, stem) if builder else []


#: Cross-case sections (paper-layout tables spanning several cases), by problem family.
STUDIES: dict[str, Callable[[pd.DataFrame, Path, bool], list[str]]] = {
    "attitude": attitude.study_sections,
    "low thrust": lowthrust.study_sections,
    "attitude companion": companion.study_sections,
    "held-out": holdout.study_sections,
    "tuning modes": tuning.study_sections,
}
