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

from penaltyrun.io import decode_json
from penaltyrun.optim.probe import CLIFF, STEPS, CliffProbe, probe
from penaltyrun.report import protocol
from penaltyrun.report.bestknown import best_rows
from penaltyrun.report.tables import fmt, markdown, save_figure

logger = logging.getLogger(__name__)

COLUMNS = ["map", "by", "cost", *(f"largest change at {s:g}" for s in STEPS),
           f"smallest step with a change ≥ {100 * CLIFF:g} %", "lowest change found",
           "jump of the map within"]


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


def probe_row(row: pd.Series | dict[str, Any],
              steps: tuple[float, ...] = STEPS) -> tuple[CliffProbe, list[str]] | None:
    """Probe one stored start's best point (``best_z`` in the layout of its ``param`` and
    ``param_options``); the probe and the variables' names, or None when the problem
    cannot be rebuilt or the start stored no decision vector."""
    z = row.get("best_z")
    if z is None or not len(z):
        return None
    rebuilt = rebuilt_layout(row)
    if rebuilt is None:
        return None
    prob, layout = rebuilt
    lb, ub = layout.bounds()

    def cost_batch(batch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mats, scalars = layout.split(batch)
        out = prob.evaluate_batch(mats, scalars or None)
        return out.cost, out.converged

    return probe(cost_batch, np.asarray(z, float), lb, ub, steps), layout.names()


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


def table(probes: dict[str, tuple[pd.Series, CliffProbe]]) -> pd.DataFrame:
    """One row per probed map: where it comes from, its cost, the largest relative change
    (%) per step, the smallest step reaching :data:`CLIFF`, the most negative change and
    the distance to the nearest jump of the map (:func:`skip_margin`)."""
    rows = []
    for fam, (row, result) in probes.items():
        low, at = result.lowest()
        cliff = result.smallest_cliff_step()
        rows.append({"map": fam, "by": f"{row['optimizer']}/{row['param']}",
                     "cost": fmt(result.cost, 5),
                     **{c: fmt(100.0 * v, 3) + " %" for c, v in
                        zip(COLUMNS[3:3 + len(STEPS)], result.largest())},
                     COLUMNS[-3]: f"{cliff:g}" if cliff == cliff else f"none up to {STEPS[-1]:g}",
                     COLUMNS[-2]: f"{fmt(100.0 * low, 3)} % at {at:g}" if low < 0 else "none",
                     COLUMNS[-1]: margin_text(skip_margin(row))})
    return pd.DataFrame(rows, columns=COLUMNS)


def figure(probes: dict[str, tuple[pd.Series, CliffProbe]], title: str, path: Path) -> Path:
    """Largest relative change against the step, log-log, one line per map, with the
    slopes h and h² of a smooth cost drawn through each line's first point."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4.0))
    for fam, (_, result) in probes.items():
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


def section(g: pd.DataFrame, out: Path, stem: str) -> list[str]:
    """Markdown lines of one problem × case × variant's probe (figure ``cliffs_<stem>.png``
    in ``out``); none when its problem cannot be rebuilt."""
    probes: dict[str, tuple[pd.Series, CliffProbe]] = {}
    for fam, row in best_rows(g).items():
        result = probe_row(row)
        if result is None:
            return []
        probes[fam] = (row, result[0])
    if not probes:
        return []
    first = g.iloc[0]
    path = figure(probes, f"{first['problem']} / {first['case']}: cost change near the best "
                  "points", out / f"cliffs_{stem}.png")
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
            markdown(table(probes)), "", f"![cliffs next to the best points]({path.name})", ""]


__all__ = ["COLUMNS", "figure", "margin_text", "probe_row", "rebuilt_layout", "section",
           "skip_margin", "table"]
