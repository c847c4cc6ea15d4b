"""Report hooks of the low-thrust problems (see :mod:`penaltyrun.problems.report_hooks`).

Each law describes its cost (time of flight in days, or propellant in kg for min-fuel), its
held-out set (perturbed departures; the same transfer at other control steps and RK4
substeps, which give the discretization check), the paper's claims, plots the best
transfers (3-D path, elements, thrust pattern) and adds the paper-layout tables (Table 3
case definitions, time of flight and final mass per cell) and the Case E / E* note. Plain
Python / numpy only (no pandas).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.problems.base import PaperValues, ReportInfo, ReportSection
from penaltyrun.problems.lowthrust.params import build_params
from penaltyrun.problems.lowthrust.plots import plot_elements, plot_thrust, plot_trajectory

#: The paper's statements (arXiv 2504.16328) per law, and its numbers per case.
CLAIMS = {"lyapunov_transfer": "full better in all five cases A–E; largest mean ToF savings "
                               "≈ 3.2 d (B) and ≈ 2.2 d (E)",
          "qlaw": "full better in every case; E*: ≈ 10.5 d ToF (min time) or ≈ 90 kg final "
                  "mass (min fuel)"}
SAVINGS = {("lyapunov_transfer", "B"): "mean ToF saving ≈ 3.2 d",
           ("lyapunov_transfer", "E"): "mean ToF saving ≈ 2.2 d",
           ("qlaw", "Estar"): "≈ 10.5 d ToF or ≈ 90 kg final mass"}
DISCRETIZATION_KINDS = ("control_step", "substeps")


def holdout_description(p: Any) -> str:
    """What the held-out set of these parameters is, in one sentence."""
    parts = []
    if p.holdout_n_perturbed > 0:
        parts.append(f"{p.holdout_n_perturbed} seeded perturbations of the departure orbit "
                     f"(a ± {100 * p.holdout_da_rel:g} %, e ± {p.holdout_de:g}, i ± "
                     f"{p.holdout_di_deg:g}°, Ω ± {p.holdout_draan_deg:g}°, ω ± "
                     f"{p.holdout_domega_deg:g}°, ν0 ± {p.holdout_dnu_deg:g}°)")
    redo = [f"control steps {', '.join(f'{s:g}' for s in p.holdout_control_steps)} s"
            if p.holdout_control_steps else "",
            f"RK4 substeps {', '.join(str(s) for s in p.holdout_substeps)}"
            if p.holdout_substeps else ""]
    redo = [r for r in redo if r]
    if redo:
        parts.append("the training transfer re-run at " + " and ".join(redo) +
                     " (discretization check, not counted as held-out scenarios)")
    return "; ".join(parts)


def hooks(law: str, params_cls: type) -> tuple[Callable[..., ReportInfo],
                                               Callable[..., dict[str, Any]],
                                               Callable[..., list[ReportSection]]]:
    """``(report_info, report_plots, report_sections)`` of one low-thrust law module."""

    def report_info(case: str, params: Mapping[str, Any]) -> ReportInfo:
        p = build_params(params_cls, case, params)
        fuel = getattr(p, "objective", "min_time") == "min_fuel"
        claim = CLAIMS.get(law, "")
        if (law, case) in SAVINGS:
            claim += f"; this case: {SAVINGS[(law, case)]}"
        return ReportInfo(cost_name="propellant used" if fuel else "time of flight",
                          cost_unit="kg" if fuel else "days",
                          holdout_description=holdout_description(p),
                          discretization_kinds=DISCRETIZATION_KINDS,
                          paper=PaperValues(source="paper", claim=claim))

    def report_plots(sims: Mapping[str, Mapping[str, np.ndarray]], case: str,
                     params: Mapping[str, Any]) -> dict[str, Any]:
        import matplotlib.pyplot as plt

        sims = {k: v for k, v in sims.items() if not k.startswith("paper")}
        fig = plt.figure(figsize=(6.5 * len(sims), 6.0))
        for i, (label, sim) in enumerate(sims.items(), start=1):
            plot_trajectory(sim, ax=fig.add_subplot(1, len(sims), i, projection="3d"),
                            title=label)
        fig.suptitle(f"{law} / {case}: transfers of the best starts")
        thrust, axes = plt.subplots(len(sims), 1, figsize=(9, 2.8 * len(sims)),
                                    squeeze=False)
        for ax, (label, sim) in zip(axes[:, 0], sims.items()):
            plot_thrust(sim, ax=ax, title=label)
        return {"trajectory": fig, "elements": plot_elements(sims), "thrust": thrust}

    def report_sections(jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
        return [case_definitions(law, params_cls, jobs), transfer_table(law, jobs),
                *case_e_note(law, jobs)]

    return report_info, report_plots, report_sections


def case_definitions(law: str, params_cls: type,
                     jobs: Sequence[Mapping[str, Any]]) -> ReportSection:
    """Table 3 layout: the case definitions actually used (orbits; spacecraft)."""
    orbits, craft = [], []
    seen = set()
    for j in jobs:
        if j["case"] in seen:
            continue
        seen.add(j["case"])
        p = build_params(params_cls, j["case"], j["problem_params"] or {})
        orbits.append({"case": j["case"], "a0 km": p.a0_km, "e0": p.e0, "i0 °": p.i0_deg,
                       "aT km": p.a_target_km, "eT": p.e_target, "iT °": p.i_target_deg,
                       "ΩT °": p.Omega_target_deg, "ωT °": p.omega_target_deg,
                       "targeted": ", ".join(p.targeted)})
        craft.append({"case": j["case"], "thrust N": p.thrust_newton, "m0 kg": p.m0_kg,
                      "Isp s": p.isp_s, "ToF cap d": p.tof_cap_days,
                      "control step s": p.control_step_s})
    return ReportSection(title=f"{law}: Table 3 layout (case definitions used)",
                         tables=[("Departure and target orbits:", orbits),
                                 ("Spacecraft and discretization:", craft)])


def _num(metrics: Mapping[str, Any], key: str) -> float:
    value = (metrics or {}).get(key)
    return float(value) if isinstance(value, (int, float)) else float("nan")


def _finite(statistic: Any, values: np.ndarray) -> float:
    """``statistic`` of the finite values (NaN when there are none, e.g. a metric the
    records do not carry)."""
    finite = values[np.isfinite(values)]
    return float(statistic(finite)) if finite.size else float("nan")


def transfer_table(law: str, jobs: Sequence[Mapping[str, Any]]) -> ReportSection:
    """Tables 4 / 5 layout: time of flight and final mass of the converged starts per case,
    variant, optimizer and map (K = I baseline included), with the end statuses."""
    cells: dict[tuple[str, str, str, str], list[Mapping[str, Any]]] = {}
    for j in jobs:
        if j["status"] not in NO_RESULT_STATUSES:
            cells.setdefault((j["case"], j["variant"], j["optimizer"], j["param"]), []).append(j)
    rows = []
    for (case, variant, optimizer, param), group in sorted(cells.items()):
        ok = [j for j in group if j["converged"]]
        tof = np.array([_num(j["metrics"], "tof_days") for j in ok])
        mass = np.array([_num(j["metrics"], "final_mass_kg") for j in ok])
        ends = Counter(str((j["metrics"] or {}).get("status", "?")) for j in group)
        rows.append({"case": case + (f" [{variant}]" if variant else ""),
                     "optimizer": optimizer, "map": param,
                     "converged": f"{len(ok)}/{len(group)}",
                     "best ToF d": _finite(np.min, tof), "mean ToF d": _finite(np.mean, tof),
                     "best m_f kg": _finite(np.max, mass),
                     "mean m_f kg": _finite(np.mean, mass),
                     "end statuses": ", ".join(f"{k}×{v}" for k, v in sorted(ends.items()))})
    name = "Table 4 — generic Lyapunov law" if law == "lyapunov_transfer" else "Table 5 — Q-law"
    return ReportSection(
        title=f"{law}: {name} layout (time of flight and final mass)",
        text="Converged starts only; `baseline` is K = I. The full-vs-diagonal comparison "
             "with its tests, held-out result and discretization check is in the verdict "
             f"and the case sections. Paper: {CLAIMS.get(law, '—')}.", tables=[("", rows)])


def case_e_note(law: str, jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
    """Original Case E vs E*: how the first start of each cell ended."""
    lines = []
    firsts: dict[tuple[str, str, str, str], Mapping[str, Any]] = {}
    counts: Counter = Counter()
    conv: Counter = Counter()
    for j in sorted(jobs, key=lambda j: j["start"] or 0):
        if j["case"] not in ("E", "Estar"):
            continue
        key = (j["case"], j["variant"], j["optimizer"], j["param"])
        firsts.setdefault(key, j)
        counts[key] += 1
        conv[key] += bool(j["converged"])
    for key, j in sorted(firsts.items()):
        m = j["metrics"] or {}
        cap = (j["problem_params"] or {}).get("a_cap_km") or "none"
        errors = ", ".join(f"{k} {v:.3g}" for k, v in (m.get("final_errors") or {}).items())
        label = f"{law} / {key[0]}" + (f" [{key[1]}]" if key[1] else "")
        lines.append(f"- **{label}**, {key[2]} / {key[3]}: {conv[key]}/{counts[key]} starts "
                     f"converged; a-cap {cap}; first start ended `{m.get('status', '?')}` "
                     f"after {_num(m, 'tof_days'):.1f} d"
                     + (f"; final errors: {errors}" if errors else "") + ".")
    if not lines:
        return []
    return [ReportSection(
        title=f"{law}: original Case E and the rotated Case E*",
        text="Original Case E (i 0.06° → 116°) is reported separately from E* (30.06° → "
             "86°).\n\n" + "\n".join(lines))]


__all__ = ["CLAIMS", "DISCRETIZATION_KINDS", "case_definitions", "case_e_note",
           "holdout_description", "hooks", "transfer_table"]
