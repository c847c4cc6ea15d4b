"""The report's basin-of-attraction maps: the best diagonal and the best full start of a
problem × case × variant run from a grid of initial conditions, side by side.

The problem names the plane and runs the gain (:mod:`penaltyrun.problems.basins`); this
module draws the maps and writes the table. A problem without the two members of
:class:`~penaltyrun.problems.basins.BasinProblem`, or one that cannot be rebuilt from the
stored results, gets no section.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.io import decode_json
from penaltyrun.problems.basins import DEFAULT_POINTS, BasinMap, basin_map
from penaltyrun.report import protocol
from penaltyrun.report.bestknown import best_rows
from penaltyrun.report.sections import matrices_of
from penaltyrun.report.tables import fmt, markdown, md_text, save_figure

COLUMNS = ["map", "by", "starts converged", "median arrival", "median cost"]
#: Column added when a problem gives an estimate of the region of attraction.
REGION_COLUMN = "inside region estimate: converged"
#: Grid points per axis of a report's maps (``penaltyrun-report --basin-points``).
REPORT_POINTS = 16


def maps_of(g: pd.DataFrame, n: int = DEFAULT_POINTS) -> dict[str, tuple[pd.Series, BasinMap]]:
    """Basin maps of the best start of each map family of ``g`` (one problem × case ×
    variant), keyed ``diagonal`` / ``full``; empty when the problem offers none."""
    out: dict[str, tuple[pd.Series, BasinMap]] = {}
    for fam, row in best_rows(g).items():
        prob = protocol.rebuild(row["problem"], row["case"], row.get("problem_params"))
        if prob is None:
            return {}
        bm = basin_map(prob, matrices_of(row), decode_json(row.get("scalars")) or None, n)
        if bm is None:
            return {}
        out[fam] = (row, bm)
    return out


def table(maps: dict[str, tuple[pd.Series, BasinMap]]) -> pd.DataFrame:
    """One row per map: the start it comes from, the converged grid points (k/n) and the
    median arrival time and cost over them; with a region estimate (:data:`REGION_COLUMN`)
    also the grid points inside it that converged (k/n)."""
    rows = []
    for fam, (row, bm) in maps.items():
        ok = bm.converged
        unit = f" {bm.axes.time_unit}" if bm.axes.time_unit else ""
        arrival = bm.arrival_time[ok]
        rows.append({"map": fam, "by": f"{row['optimizer']}/{row['param']}",
                     "starts converged": f"{int(ok.sum())}/{ok.size}",
                     "median arrival": (fmt(float(np.median(arrival)), 4) + unit
                                        if arrival.size and np.isfinite(arrival).all()
                                        else "—"),
                     "median cost": fmt(float(np.median(bm.cost[ok])), 4)
                     if ok.any() else "—",
                     REGION_COLUMN: _region_text(bm)})
    regions = any(bm.region is not None for _, bm in maps.values())
    return pd.DataFrame(rows, columns=[*COLUMNS, REGION_COLUMN]
                        )[[*COLUMNS, REGION_COLUMN] if regions else COLUMNS]


def _region_text(bm: BasinMap) -> str:
    """``k/n`` grid points inside the problem's region estimate that converged, "—" without
    an estimate."""
    if bm.region is None:
        return "—"
    hit, inside = bm.region_check()
    return f"{hit}/{inside}"


def figure(maps: dict[str, tuple[pd.Series, BasinMap]], title: str, path: Path) -> Path:
    """Panels of the maps side by side: arrival time (or, for a cost without a target
    event, the cost) of each converged grid point on one shared log colour scale; grid
    points that did not converge by the horizon in grey; the training start as a star."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    by_time = all(np.isfinite(bm.arrival_time[bm.converged]).all() and bm.converged.any()
                  for _, bm in maps.values())
    values = {fam: np.where(bm.converged, bm.arrival_time if by_time else bm.cost, np.nan)
              for fam, (_, bm) in maps.items()}
    finite = np.concatenate([v[np.isfinite(v) & (v > 0)] for v in values.values()])
    norm = LogNorm(finite.min(), finite.max()) if finite.size and finite.max() > finite.min() \
        else None
    fig, axes = plt.subplots(1, len(maps) + 1, figsize=(4.6 * len(maps) + 0.6, 4.0),
                             squeeze=False, gridspec_kw={"width_ratios": [1] * len(maps)
                                                         + [0.05]})
    bar_ax = axes[0][-1]
    axes = axes[:, :-1]
    mesh = None
    for ax, (fam, (_, bm)) in zip(axes[0], maps.items()):
        ax.pcolormesh(bm.x, bm.y, np.where(bm.converged, np.nan, 1.0), cmap="Greys",
                      vmin=0.0, vmax=4.0, shading="nearest")
        mesh = ax.pcolormesh(bm.x, bm.y, values[fam], cmap="viridis", norm=norm,
                             shading="nearest")
        if bm.region is not None and bm.region["inside"].any():
            ax.contour(bm.x, bm.y, bm.region["inside"].astype(float), levels=[0.5],
                       colors="red", linewidths=1.5)
        if bm.axes.marker is not None:
            ax.plot(*bm.axes.marker, marker="*", color="red", markersize=12, linestyle="",
                    label="training start")
            ax.legend(loc="upper right", fontsize=8)
        ax.set_title(f"{fam}: {100 * bm.share_converged:.3g} % of starts converge",
                     fontsize=10)
        ax.set_xlabel(bm.axes.labels[0])
        if ax is not axes[0][0]:
            ax.tick_params(labelleft=False)
    first = next(iter(maps.values()))[1]
    axes[0][0].set_ylabel(first.axes.labels[1])
    if mesh is not None and finite.size:
        unit = f" ({first.axes.time_unit})" if by_time and first.axes.time_unit else ""
        fig.colorbar(mesh, cax=bar_ax, label=("arrival time" + unit) if by_time else "cost")
    else:
        bar_ax.set_axis_off()
    fig.suptitle(f"{title} (grey: not converged by {fmt(first.horizon, 4)})",
                 fontsize=10)
    return save_figure(fig, path)


def section(g: pd.DataFrame, out: Path, stem: str, n: int = REPORT_POINTS) -> list[str]:
    """Markdown lines of one problem × case × variant's basin maps (figure
    ``basins_<stem>.png`` in ``out``); none when the problem offers no maps."""
    maps = maps_of(g, n)
    if not maps:
        return []
    first = g.iloc[0]
    _, bm = next(iter(maps.values()))
    unit = f" {bm.axes.time_unit}" if bm.axes.time_unit else ""
    title = f"{first['problem']} / {first['case']}: basins of the best starts"
    path = figure(maps, title, out / f"basins_{stem}.png")
    return ["### Basins of attraction", "",
            f"The best converged start of each map run from a {n} × {n} grid of initial "
            f"conditions ({md_text(bm.axes.labels[0])} × {md_text(bm.axes.labels[1])}; the "
            f"other state components as in the problem's held-out set) at the held-out "
            f"horizon {fmt(bm.horizon, 4)}{unit}. A grid point counts as converged when "
            "its run reached the target by then: a sampled map, not a proof.", "",
            *_region_lines(maps),
            markdown(table(maps)), "", f"![basins of attraction]({path.name})", ""]


def _region_lines(maps: dict[str, tuple[pd.Series, BasinMap]]) -> list[str]:
    """The region estimates' description (red contour), when the problem gives one."""
    with_region = [(fam, bm) for fam, (_, bm) in maps.items() if bm.region is not None]
    if not with_region:
        return []
    levels = "; ".join(f"{fam}: c = {fmt(float(bm.region['level']), 4)} (certified "
                       f"{fmt(float(bm.region['certified']), 3)})" for fam, bm in with_region)
    return [f"Red contour: the problem's estimate of the region of attraction in this plane, "
            f"the {md_text(with_region[0][1].region['label'])} ({levels}). The last column "
            "counts the grid points inside it that converged.", ""]


__all__ = ["COLUMNS", "REGION_COLUMN", "REPORT_POINTS", "figure", "maps_of", "section", "table"]

