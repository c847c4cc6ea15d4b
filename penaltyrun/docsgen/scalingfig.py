"""Growth of the tuning cost with the plant size, from a study's ``known_optimum`` table.

One panel for the CPU seconds and one for the evaluations a start needed to reach the known
optimum J* (median over the starts that reached it), against the size of the tuned matrix,
one line per optimizer and map. A cell where no start reached J* is drawn as an open marker
at what its starts spent (the least CPU, the median evaluations), with an arrow up: its time
to reach is larger than that (a lower bound).

The numbers drawn are written beside the figure as ``docs/results/figures/<study>_scaling.csv``
and checked by ``make check-docs`` like the pages' text; the PNG is drawn from that CSV (only
when it changed or is missing) and checked for presence only.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from penaltyrun.docsgen.comparefig import FIGURES, to_csv

#: File-name suffix of this figure (``render_all`` picks the drawing by it).
SUFFIX = "_scaling"
CSV_COLUMNS = ["optimizer", "param", "size", "dim", "n_starts", "n_reached",
               "cpu_s_to_reach_median", "evals_to_reach_median", "cpu_s_spent_min",
               "evals_spent_median"]


def points(table: Any) -> Any:
    """The rows of a ``known_optimum`` table the figure draws, sorted by map, optimizer and
    size (:data:`CSV_COLUMNS`)."""
    return table[CSV_COLUMNS].sort_values(["param", "optimizer", "size"]).reset_index(drop=True)


def draw(csv_text: str, path: Path, title: str) -> Path:
    """Draw the figure of ``csv_text`` (:func:`to_csv` of :func:`points`) into ``path``."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import pandas as pd

    from penaltyrun.report.tables import save_figure

    frame = pd.read_csv(io.StringIO(csv_text))
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.6))
    panels = (("cpu_s_to_reach_median", "cpu_s_spent_min", "CPU seconds to reach J*"),
              ("evals_to_reach_median", "evals_spent_median", "evaluations to reach J*"))
    for ax, (reach, spent, label) in zip(axes, panels):
        for k, ((param, optimizer), g) in enumerate(frame.groupby(["param", "optimizer"],
                                                                  sort=True)):
            color, line = f"C{k}", "-" if param != "diagonal" else ":"
            hit = g[g["n_reached"] > 0]
            ax.plot(hit["size"], hit[reach], line, marker="o", color=color, ms=5,
                    label=f"{optimizer}, {param}")
            miss = g[g["n_reached"] == 0]
            ax.plot(miss["size"], miss[spent], "o", mfc="none", color=color, ms=7)
            for x, y in zip(miss["size"], miss[spent]):
                ax.annotate("", xy=(x, 2.2 * y), xytext=(x, y),
                            arrowprops={"arrowstyle": "->", "color": color, "lw": 1})
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        drawn = pd.concat([frame.loc[frame["n_reached"] > 0, reach],
                           frame.loc[frame["n_reached"] == 0, spent]]).dropna()
        if len(drawn) and (drawn > 0).all():  # room above for the arrows
            ax.set_ylim(0.5 * drawn.min(), 4.0 * drawn.max())
        ax.set_xticks(sorted(frame["size"].unique()), [str(v) for v in
                                                       sorted(frame["size"].unique())])
        ax.set_xlabel("plant states n")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(title + " (open marker + arrow: no start reached J*; what a start spent)",
                 fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path)


def section(name: str, table: Any, figures: dict[Path, str]) -> str:
    """The figure of study ``name`` (its CSV registered in ``figures``) and a sentence on
    how to read it."""
    csv_rel = FIGURES / f"{name}{SUFFIX}.csv"
    figures[csv_rel] = to_csv(points(table))
    return (f"![CPU seconds and evaluations to reach J* against the plant size, {name}]"
            f"(figures/{csv_rel.with_suffix('.png').name})\n\n"
            "Filled markers: median over the starts that reached J* within the tolerance; "
            "open markers with an arrow: no start reached it, drawn at the least CPU a start "
            "spent (left) and the median evaluations spent (right), so the time to reach "
            f"lies above. The numbers: `{csv_rel.as_posix()}`.")


__all__ = ["CSV_COLUMNS", "SUFFIX", "draw", "points", "section"]
