"""The report's cliff probe: is a case's best point next to a jump of the criterion?

Each case's best diagonal and best full start (over every optimizer) is probed with
:func:`penaltyrun.optim.probe.probe`: every decision variable moved alone, up and down, by
1e-6 to 1e-3 of its range. The section tabulates the largest relative cost change at each
step and draws it against the step on log-log axes beside the slopes of a smooth cost (∝ h
where the gradient is not zero, ∝ h² at an interior minimum): a curve that stays flat as the
step shrinks is a jump of the criterion within that distance. The problem is rebuilt from
the stored results (nothing named in them is imported); a case whose problem cannot be
rebuilt gets no section.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.io import decode_json, storedprobe
from penaltyrun.optim.probe import CLIFF, STEPS, CliffProbe, probe
from penaltyrun.report import protocol
from penaltyrun.report.bestknown import best_rows
from penaltyrun.report.tables import fmt, markdown, save_figure

logger = logging.getLogger(__name__)

#: Columns of a probe's summary row (:func:`summary`) before the per-step ones.
KEYS = ["problem", "case", "map", "optimizer", "param", "start", "job_id", "record_cost",
        "cost", "converged", "smallest_cliff_step", "lowest_change_pct",
        "lowest_change_step", "cpu_s"]
#: Column of the rendered table (:func:`summary_table`) with the smallest cliff step.
CLIFF_COLUMN = f"smallest step with a change ≥ {100 * CLIFF:g} %"
#: Column of the report's table with the distance to a jump of the map (:func:`skip_margin`).
MARGIN_COLUMN = "jump of the map within"


def step_columns(step: float) -> list[str]:
    """The three summary columns of one step of the ladder: largest |Δ| (in %), its
    variable, and the number of steps whose run changed its convergence."""
    return [f"change_pct@{step:g}", f"variable@{step:g}", f"status_changes@{step:g}"]


def rebuilt_layout(row: pd.Series | dict[str, Any]) -> tuple[Any, Any] | None:
    """The problem and decision layout of a stored start (its ``problem``, ``case``,
    ``problem_params``, ``param`` and ``param_options``), or None when the problem cannot
    be rebuilt."""
    from penaltyrun.runner.setup import build_layout

    prob = protocol.rebuild(row["problem"], row["case"], row.get("problem_params"))
    if prob is None:
        return None
    return prob, build_layout(prob, str(row["param"]),
                              decode_json(row.get("param_options")) or {})


def probe_row(row: pd.Series | dict[str, Any], steps: tuple[float, ...] = STEPS,
              stored: pd.DataFrame | None = None) -> tuple[CliffProbe, list[str]] | None:
    """Probe one stored start's best point (``best_z`` in the layout of its ``param`` and
    ``param_options``); the probe and the variables' names, or None when the problem
    cannot be rebuilt or the start stored no decision vector.

    ``stored``: probes stored beside the results (:mod:`penaltyrun.io.storedprobe`); the
    start's stored probe of exactly this point and ladder is used instead of evaluating.
    """
    probed = _probed(row, steps, stored)
    return None if probed is None else probed[:2]


def _probed(row: pd.Series | dict[str, Any], steps: tuple[float, ...],
            stored: pd.DataFrame | None) -> tuple[CliffProbe, list[str], bool] | None:
    """:func:`probe_row` and whether the probe was read from ``stored``."""
    z = row.get("best_z")
    if z is None or not len(z):
        return None
    rebuilt = rebuilt_layout(row)
    if rebuilt is None:
        return None
    prob, layout = rebuilt
    kept = storedprobe.lookup(stored, row["job_id"], row.get("config_hash"), z, steps)
    if kept is not None:
        return kept, layout.names(), True
    lb, ub = layout.bounds()

    def cost_batch(batch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mats, scalars = layout.split(batch)
        out = prob.evaluate_batch(mats, scalars or None)
        return out.cost, out.converged

    return probe(cost_batch, np.asarray(z, float), lb, ub, steps), layout.names(), False


def skip_margin(row: pd.Series | dict[str, Any]) -> float | None:
    """How far a stored start's best point is from a jump of its map: the smallest
    Gram–Schmidt skip margin of its GEAGSP blocks
    (:meth:`~penaltyrun.penalty.layout.DecisionLayout.skip_margin`), inf for maps that are
    continuous on the whole box, None when the problem cannot be rebuilt or the start
    stored no decision vector."""
    z = row.get("best_z")
    rebuilt = None if z is None or not len(z) else rebuilt_layout(row)
    if rebuilt is None:
        return None
    return float(rebuilt[1].skip_margin(np.asarray(z, float)[None])[0])


def margin_text(margin: float | None) -> str:
    """A skip margin as table text: the margin (rad, about the angle step to the nearest
    jump of a GEAGSP map), "continuous map" where there is none, "" where unknown."""
    if margin is None:
        return ""
    return "continuous map" if np.isinf(margin) else f"{margin:.2g} rad"


def summary(row: pd.Series | dict[str, Any], result: CliffProbe, names: list[str],
            cpu_s: float = float("nan")) -> dict[str, Any]:
    """One probed point as a plain row (:data:`KEYS` and :func:`step_columns` of each step):
    where it comes from (``row``, a stored start; ``map``: its ``family`` or, without one,
    its ``param``), the cost recomputed and recorded, the smallest step reaching
    :data:`CLIFF`, the most negative change (%) and its step, and per step the largest
    change (%), the variable that gave it and how many moves changed convergence."""
    lowest, lowest_step = result.lowest()
    out = {"problem": row["problem"], "case": row["case"],
           "map": row.get("family", row["param"]), "optimizer": row["optimizer"],
           "param": row["param"], "start": int(row["start"]), "job_id": row["job_id"],
           "record_cost": float(row["best_cost"]), "cost": result.cost,
           "converged": result.converged,
           "smallest_cliff_step": result.smallest_cliff_step(CLIFF),
           "lowest_change_pct": 100.0 * lowest, "lowest_change_step": lowest_step,
           "cpu_s": cpu_s}
    steps = tuple(result.steps)
    changes = result.status_change.reshape(len(steps), -1).sum(axis=1)
    for k, (step, largest, worst) in enumerate(zip(steps, result.largest(),
                                                   result.worst_variable())):
        pct, var, flips = step_columns(step)
        out.update({pct: 100.0 * float(largest), var: names[worst] if worst >= 0 else "",
                    flips: int(changes[k])})
    return out


def summary_table(frame: pd.DataFrame, spec: str = ".3g",
                  with_case: bool = True) -> pd.DataFrame:
    """The table shown for summary rows (:func:`summary`, or a committed ``probe.csv``):
    per point its origin, cost, the largest relative change (%) at each step, the smallest
    step reaching :data:`CLIFF` and the most negative change found (text formatted with
    ``spec``); ``with_case`` adds a leading "problem / case" column."""
    steps = [float(c.split("@", 1)[1]) for c in frame.columns if c.startswith("change_pct@")]
    out = pd.DataFrame(index=frame.index)
    if with_case:
        out["problem / case"] = frame["problem"] + " / " + frame["case"]
    out["map"] = frame["map"]
    out["by"] = frame["optimizer"] + "/" + frame["param"]
    out["cost"] = frame["cost"]
    for step in steps:
        out[f"largest change (%) at {step:g}"] = frame[step_columns(step)[0]]
    out[CLIFF_COLUMN] = [f"{v:g}" if v == v else f"none up to {steps[-1]:g}"
                         for v in frame["smallest_cliff_step"]]
    out["lowest change found (%)"] = [
        f"{v:{spec}} at {s:g}" if v < 0 else "none"
        for v, s in zip(frame["lowest_change_pct"], frame["lowest_change_step"])]
    return out.reset_index(drop=True)


def table(probes: dict[str, tuple[pd.Series, CliffProbe, list[str]]]) -> pd.DataFrame:
    """The report's table: :func:`summary_table` of one case's probed maps, with the
    distance of each point from a jump of its map (:data:`MARGIN_COLUMN`,
    :func:`skip_margin`)."""
    rows = [summary({**row, "family": fam}, result, names)
            for fam, (row, result, names) in probes.items()]
    out = summary_table(pd.DataFrame(rows), with_case=False)
    out["cost"] = [fmt(c, 5) for c in out["cost"]]  # the other columns to 3 digits
    out[MARGIN_COLUMN] = [margin_text(skip_margin(row)) for row, _, _ in probes.values()]
    return out


def figure(probes: dict[str, tuple[pd.Series, CliffProbe, list[str]]], title: str,
           path: Path) -> Path:
    """Largest relative change against the step, log-log, one line per map, with the
    slopes h and h² of a smooth cost drawn through each line's first point."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    for fam, (_, result, _) in probes.items():
        steps, largest = np.asarray(result.steps), 100.0 * result.largest()
        shown = np.isfinite(largest) & (largest > 0)
        if not shown.any():
            continue
        line, = ax.loglog(steps[shown], largest[shown], "o-", label=fam)
        h0, c0 = steps[shown][0], largest[shown][0]
        for power, style in ((1, ":"), (2, "--")):
            ax.loglog(steps, c0 * (steps / h0) ** power, style, color=line.get_color(),
                      alpha=0.5, lw=1)
    ax.axhline(100.0 * CLIFF, color="grey", lw=0.8, label=f"{100 * CLIFF:g} %")
    ax.set_xlabel("step (fraction of the variable's range)")
    ax.set_ylabel("largest relative cost change (%)")
    ax.set_title(title, fontsize=9)
    ax.legend(title="dotted ∝ h, dashed ∝ h²", fontsize=8, title_fontsize=7)
    return save_figure(fig, path)


def section(g: pd.DataFrame, out: Path, stem: str,
            stored: pd.DataFrame | None = None) -> list[str]:
    """Markdown lines of one problem × case × variant's probe (figure ``cliffs_<stem>.png``
    in ``out``); none when its problem cannot be rebuilt. ``stored``: probes stored
    beside the results, used where one is of exactly the probed point
    (:func:`probe_row`)."""
    probes: dict[str, tuple[pd.Series, CliffProbe, list[str]]] = {}
    read = []
    for fam, row in best_rows(g).items():
        probed = _probed(row, STEPS, stored)
        if probed is None:
            return []
        probes[fam] = (row, *probed[:2])
        read += [fam] if probed[2] else []
    if not probes:
        return []
    first = g.iloc[0]
    path = figure(probes, f"{first['problem']} / {first['case']}: cost change near the best "
                  "points", out / f"cliffs_{stem}.png")
    source = ([f"The probe of the best {' and '.join(read)} point was read from "
               f"`{storedprobe.PROBE_FILE}` beside the results (the same evaluations, "
               "stored with them), not evaluated again.", ""] if read else [])
    return ["### Cliffs next to the best points", "",
            "Each variable of the best diagonal and full point moved alone, up and down, by "
            "the step (a fraction of its range); the largest relative change of the cost. A "
            "smooth cost changes about 10 to 100 times less per tenfold smaller step; a "
            "change that stays large as the step shrinks is a jump of the criterion within "
            "that distance, where no gradient describes the cost and a search creeps along "
            "the edge. A step that lowers the cost shows the point is not a local minimum "
            "along that variable. The last column is how far the point is from a jump of "
            "the map itself: GEAGSP is discontinuous where its Gram–Schmidt step skips a "
            "basis vector, and a margin of m means such a jump about m radians of an angle "
            "away.", "",
            *source, markdown(table(probes), digits=3), "",
            f"![cliffs next to the best points]({path.name})", ""]


__all__ = ["CLIFF_COLUMN", "KEYS", "MARGIN_COLUMN", "figure", "margin_text", "probe_row",
           "rebuilt_layout", "section", "skip_margin", "step_columns", "summary",
           "summary_table", "table"]
