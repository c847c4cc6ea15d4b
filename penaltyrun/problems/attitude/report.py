"""Report hooks of the attitude problems (see :mod:`penaltyrun.problems.report_hooks`).

Both laws (``attitude_lqr``, ``attitude_lyapunov``) describe their cost (J = ∫½‖u‖² dt in
N²·m²·s), their held-out set, the paper's means (Tables 1–2 of arXiv 2504.16328) and the
authors' companion study (Schaub & Junkins detumble, 20 MATLAB ``particleswarm`` runs per
map), plot the best starts' histories and add the paper-layout tables and the horizon
study. Plain Python / numpy only (no pandas).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.problems import criteria
from penaltyrun.problems.attitude.params import CASE_PARAMS, Params
from penaltyrun.problems.attitude.plots import plot_histories
from penaltyrun.problems.base import PaperValues, ReportInfo, ReportSection

MANOEUVRES = ("detumble", "rest_to_rest")
TABLE_NAMES = {"attitude_lqr": "Table 1 — attitude LQR",
               "attitude_lyapunov": "Table 2 — attitude Lyapunov PD"}
#: The paper's mean J per (law, manoeuvre) and map family (5–10 PSO runs each).
PAPER_MEANS: dict[tuple[str, str], dict[str, float]] = {
    ("attitude_lqr", "detumble"): {"diagonal": 0.423, "full": 0.146},
    ("attitude_lqr", "rest_to_rest"): {"diagonal": 0.400, "full": 0.152},
    ("attitude_lyapunov", "detumble"): {"diagonal": 0.107, "full": 0.076},
    ("attitude_lyapunov", "rest_to_rest"): {"diagonal": 0.091, "full": 0.068},
}
#: The companion study's (best, median, mean, worst) J over 20 runs, by case and map.
COMPANION: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "schaub_detumble": {"diagonal": (86.53, 95.23, 96.69, 110.96),
                        "givens": (55.75, 73.34, 77.14, 113.39),
                        "cayley": (55.15, 76.62, 75.69, 102.25),
                        "cayley_tan": (60.89, 71.51, 80.05, 116.38)},
    "schaub_detumble_sat": {"diagonal": (49.96, 51.20, 51.25, 52.28),
                            "givens": (48.89, 50.42, 50.55, 53.08),
                            "cayley": (48.67, 49.94, 50.30, 54.09),
                            "cayley_tan": (48.60, 50.26, 50.23, 52.07)},
}
COMPANION_RUNS = 20
#: The companion study's function evaluations per run (min, median, max) by case and map,
#: where the authors published them (their unconstrained diagonal PSO cell).
COMPANION_EVALS: dict[str, dict[str, tuple[float, float, float]]] = {
    "schaub_detumble": {"diagonal": (4560, 12450, 35160)},
}


def _params(case: str, params: Mapping[str, Any]) -> Params:
    return Params.from_mapping({**CASE_PARAMS.get(case, {}), **dict(params)})


def holdout_description(p: Params) -> str:
    """What the held-out set of these parameters is, in one sentence."""
    parts = []
    if p.holdout_n > 0:
        parts.append(f"{p.holdout_n ** 3} rest-to-rest starts from the attitudes of a grid "
                     f"(yaw, pitch, roll each in linspace({p.holdout_lo_deg:g}°, "
                     f"{p.holdout_hi_deg:g}°, {p.holdout_n}))")
    if p.holdout_n_perturbed > 0:
        parts.append(f"{p.holdout_n_perturbed} seeded perturbations of the training state "
                     f"(attitude rotated by up to {p.holdout_perturb_deg:g}°, each rate scaled "
                     f"by 1 ± up to {p.holdout_rate_rel:g})")
    return "; ".join(parts) + (f", same horizon t_f = {p.t_max:g} s" if parts else "")


def hooks(law: str) -> tuple[Callable[..., ReportInfo], Callable[..., dict[str, Any]],
                             Callable[..., list[ReportSection]]]:
    """``(report_info, report_plots, report_sections)`` of one attitude law module."""

    def report_info(case: str, params: Mapping[str, Any]) -> ReportInfo:
        p = _params(case, params)
        paper = None
        if (law, case) in PAPER_MEANS:
            paper = PaperValues(source="paper, Tables 1–2 (means of 5–10 PSO runs)",
                                mean_cost=PAPER_MEANS[(law, case)])
        elif law == "attitude_lyapunov" and case in COMPANION:
            paper = PaperValues(source="authors' companion study (MATLAB particleswarm)",
                                summaries=COMPANION[case], runs=COMPANION_RUNS,
                                evaluations=COMPANION_EVALS.get(case, {}))
        if p.criterion != criteria.DEADLINE:
            paper = None   # the published values are of the deadline criterion
        return ReportInfo(cost_name=criteria.report_name(p, "J = ∫½‖u‖² dt", "∫₀^t_f ½‖u‖² dt",
                                                         "∫₀ᵀ ½‖u‖² dt"),
                          cost_unit="N²·m²·s", holdout_description=holdout_description(p),
                          paper=paper)

    def report_plots(sims: Mapping[str, Mapping[str, np.ndarray]], case: str,
                     params: Mapping[str, Any]) -> dict[str, Any]:
        own = {k: v for k, v in sims.items() if not k.startswith("paper")}
        short = {" ".join(k.split()[:2]): v for k, v in own.items()}  # "best diagonal"
        fig = plot_histories(short, layout=False)  # the report lays out what it saves
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is not None:
                for text in legend.get_texts():
                    text.set_fontsize(9)
        fig.suptitle(f"{law} / {case}: quaternion, rate and torque histories\n"
                     + "; ".join(own))
        return {"histories": fig}

    def report_sections(jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
        return paper_tables(law, jobs) + horizon_study(jobs)

    return report_info, report_plots, report_sections


def _cost(job: Mapping[str, Any]) -> float:
    return float(job["best_cost"]) if job["converged"] else float("nan")


def paper_tables(law: str, jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
    """The paper's Table 1 / 2 layout per optimizer (every optimizer that ran both maps of
    the default set-up): J per start, then mean / best / worst over converged starts."""
    main = [j for j in jobs if j["case"] in MANOEUVRES and not j["variant"]
            and j["optimizer"] != "baseline" and j["status"] not in NO_RESULT_STATUSES]
    out = []
    for optimizer in sorted({j["optimizer"] for j in main}):
        mine = [j for j in main if j["optimizer"] == optimizer]
        if not any(j["family"] == "full" for j in mine):
            continue
        cols = {f"{c} {f}": sorted((j for j in mine if j["case"] == c and j["family"] == f),
                                   key=lambda j: j["start"] or 0)
                for c in MANOEUVRES for f in ("diagonal", "full")}
        n = max(len(v) for v in cols.values())
        rows = [{"start": str(k + 1), **{c: _cost(v[k]) if k < len(v) else float("nan")
                                        for c, v in cols.items()}} for k in range(n)]
        values = {c: np.array([_cost(j) for j in v]) for c, v in cols.items()}
        for name, func in (("mean", np.nanmean), ("best", np.nanmin), ("worst", np.nanmax)):
            rows.append({"start": name, **{c: float(func(x)) if np.isfinite(x).any()
                                           else float("nan") for c, x in values.items()}})
        rows.append({"start": "converged", **{c: f"{int(np.isfinite(x).sum())}/{x.size}"
                                              for c, x in values.items()}})
        paper = {"start": "paper mean"}
        for c in MANOEUVRES:
            ref = PAPER_MEANS.get((law, c), {})
            paper[f"{c} diagonal"] = ref.get("diagonal", float("nan"))
            paper[f"{c} full"] = ref.get("full", float("nan"))
        rows.append(paper)
        out.append(ReportSection(
            title=f"{TABLE_NAMES.get(law, law)} layout ({optimizer})",
            text="J (N²·m²·s) per start; mean, best, worst over converged starts (a start "
                 "that did not converge is empty: its graded penalty is not a cost). The "
                 "paper's t_f is not published, so compare improvements as well as J.",
            tables=[("", rows)]))
    return out


def horizon_study(jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
    """Best J vs the horizon t_f per manoeuvre, map family and optimizer budget, for the
    budgets run at two or more horizons (a point from another budget would bend a curve)."""
    import matplotlib.pyplot as plt

    points: dict[tuple[str, str, str], dict[float, float]] = {}
    for j in jobs:
        if j["optimizer"] == "baseline" or not j["converged"]:
            continue
        t_f = float((j["metrics"] or {}).get("t_max", np.nan))
        budget = f"{j['optimizer']} " + ",".join(
            f"{k}={v}" for k, v in sorted((j["optimizer_settings"] or {}).items())
            if k in ("n_particles", "iters", "popsize", "max_iterations", "max_evals"))
        key = (j["case"], j["family"], budget)
        cur = points.setdefault(key, {})
        cur[t_f] = min(cur.get(t_f, np.inf), float(j["best_cost"]))
    points = {k: v for k, v in points.items() if len(v) >= 2}
    if not points:
        return []
    fig, ax = plt.subplots(figsize=(8, 5))
    rows = []
    for (case, fam, budget), curve in sorted(points.items()):
        t = sorted(curve)
        ax.plot(t, [curve[x] for x in t], "o-" if fam == "diagonal" else "s--",
                color="C0" if fam == "diagonal" else "C1", label=f"{case} / {fam} ({budget})")
        rows += [{"case": case, "map family": fam, "budget": budget, "t_f s": x,
                  "best J": curve[x]} for x in t]
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("horizon t_f (s)")
    ax.set_ylabel("best J over converged starts (N²·m²·s)")
    ax.set_title("Attitude: best cost vs horizon t_f")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return [ReportSection(
        title="Attitude: horizon study (best J vs t_f)",
        text="The paper does not publish t_f; with a hard cap the minimum-energy optimum "
             "converges just before t_f, so t_f sets the scale of J. Each curve is one "
             "optimizer budget run at every t_f.", tables=[("", rows)],
        figures=[("horizon study", fig)])]


__all__ = ["COMPANION", "COMPANION_EVALS", "PAPER_MEANS", "holdout_description", "hooks",
           "horizon_study", "paper_tables"]
