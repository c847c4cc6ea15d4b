"""Report figures, one panel per optimizer (optimizers are never pooled): anytime curves,
fixed-target ECDFs and cost distributions of one problem × case × variant."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from penaltyrun.report.anytime import (  # noqa: E402
    EPSILONS,
    anytime_band,
    cell_traces,
    ecdf,
    hitting_evals,
)
from penaltyrun.report.bestknown import family, reference, with_problem_variant  # noqa: E402
from penaltyrun.report.compare import (
    MAP_ORDER,  # noqa: E402
    map_order,  # noqa: E402
)
from penaltyrun.report.rows import TRACE_COLUMNS, narrow  # noqa: E402
from penaltyrun.report.stats import converged, paper_value  # noqa: E402
from penaltyrun.report.tables import dot_sample, save_figure  # noqa: E402

#: Font sizes of the report figures (points).
plt.rcParams.update({"font.size": 11, "axes.titlesize": 12, "axes.labelsize": 11,
                     "legend.fontsize": 10, "xtick.labelsize": 10, "ytick.labelsize": 10,
                     "axes.formatter.useoffset": False})
#: One colour per map in every figure of every report; other maps get the next ones.
MAP_COLORS = {m: f"C{i}" for i, m in enumerate(MAP_ORDER)}
#: Columns the anytime and ECDF figures use (a cell's traces read with them).
TRACED = ("problem", "case", "problem_variant", "optimizer", "param", "status", "n_evals",
          *TRACE_COLUMNS)
#: What the report says instead of a fixed-target ECDF figure whose curves would all be 0.
ECDF_NONE_REACHED = ("Fixed-target ECDF: no start of any optimizer and map here reached "
                     "its family's best-known cost f* within "
                     + " or ".join(f"{100 * e:g} %" for e in EPSILONS)
                     + " (f* is the best over every run of this problem variant, runs with "
                     "other settings among them), so every curve would be 0: no figure.")
#: Colour of each published value (dashed lines).
PAPER_COLORS = {"mean_cost": "k", "median_cost": "0.45"}


def _optimizers(df: pd.DataFrame) -> list[str]:
    return sorted(o for o in df["optimizer"].unique() if o != "baseline")


def _colors(df: pd.DataFrame) -> dict[str, str]:
    extra = [m for m in map_order(df["param"].unique()) if m not in MAP_COLORS]
    return {**MAP_COLORS, **{m: f"C{len(MAP_COLORS) + i}" for i, m in enumerate(extra)}}


def _no_offset(ax: plt.Axes) -> None:
    """Plain cost tick labels (no ``+1.066e1`` offset text)."""
    fmt = ax.yaxis.get_major_formatter()
    if isinstance(fmt, matplotlib.ticker.ScalarFormatter):
        fmt.set_useOffset(False)


def _save(fig: plt.Figure, path: Path) -> Path:
    return save_figure(fig, path)


def _log_x(ax: plt.Axes) -> None:
    """Log evaluation axis with plain major labels and no minor labels."""
    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def _grid(traces: list) -> np.ndarray:
    first = min(float(e[0]) for e, _, _ in traces)
    last = max(max(float(e[-1]), s) for e, _, s in traces)
    return np.unique(np.geomspace(max(first, 1.0), max(last, first, 1.0), 200).round())


def anytime(df: pd.DataFrame, bk: pd.DataFrame, label: str, title: str,
            path: Path) -> Path | None:
    """Median and IQR band of best-so-far vs evaluations, per optimizer (panel) × map.

    The y axis is the gap to the lowest best-known cost of the problem (any map family),
    plus δ = 1e-6·|f*| so that the best-known itself stays on the log scale (a dotted line
    marks the best-known diagonal when it is higher); x is log evaluations. None if no
    start has a trace (results before anytime traces).
    """
    df = narrow(with_problem_variant(df), TRACED)
    bands = {}  # one cell's traces at a time: (optimizer, map) → grid, band, starts
    for opt in _optimizers(df):
        g = df[df["optimizer"] == opt]
        for param in map_order(g["param"].unique()):
            traces = cell_traces(g[g["param"] == param])
            if traces:
                grid = _grid(traces)
                bands[opt, param] = (grid, *anytime_band(traces, grid), len(traces))
    opts = [o for o in _optimizers(df) if any(key[0] == o for key in bands)]
    if not opts:
        return None
    first = df.iloc[0]
    refs = [reference(bk, first["problem"], first["case"], first["problem_variant"], f)
            for f in ("diagonal", "full")]
    f_ref = np.nanmin(refs) if np.isfinite(refs).any() else 0.0
    delta = 1e-6 * abs(f_ref) or 1e-12
    colors = _colors(df)
    fig, axes = plt.subplots(1, len(opts), figsize=(5.5 * len(opts), 4.6), squeeze=False,
                             sharey=True)
    for ax, opt in zip(axes[0], opts):
        g = df[df["optimizer"] == opt]
        for param in map_order(g["param"].unique()):
            if (opt, param) not in bands:
                continue
            grid, med, q25, q75, n = bands[opt, param]
            c = colors[param]
            ax.plot(grid, med - f_ref + delta, color=c, lw=2,
                    label=f"{param} (median of {n})")
            ax.fill_between(grid, q25 - f_ref + delta, q75 - f_ref + delta, color=c,
                            alpha=0.2, lw=0)
        if np.isfinite(refs[0]) and refs[0] > f_ref:
            ax.axhline(refs[0] - f_ref + delta, color="k", ls=":", lw=1,
                       label="best-known diagonal")
        _log_x(ax)
        ax.set_yscale("log")
        ax.set_xlabel("objective evaluations")
        ax.set_title(opt)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    axes[0, 0].set_ylabel(f"best-so-far − f* + δ\n{label}")
    fig.suptitle(f"{title}: anytime (median, IQR band)\nf* = {f_ref:.6g} (lowest best-known, "
                 f"any map), δ = {delta:.2g} = 1e-6·|f*| keeps f* on the log axis")
    return _save(fig, path)


def ecdf_figure(df: pd.DataFrame, bk: pd.DataFrame, title: str, path: Path
                ) -> Path | str | None:
    """Share of starts whose trace reached f* (1 + ε) by n evaluations, per optimizer × map.

    f* is the best-known cost of the map's family. Rows: ε; columns: optimizers.

    Returns
    -------
    Path, str or None
        The figure's path; :data:`ECDF_NONE_REACHED` (a sentence, no figure) when no start
        reached either target, every curve of the figure then being 0 throughout; None
        without traces.
    """
    df = narrow(with_problem_variant(df), TRACED)
    curves, traced = {}, set()  # one cell's traces at a time: (optimizer, map) → curves
    for opt in _optimizers(df):
        g = df[df["optimizer"] == opt]
        for param in map_order(g["param"].unique()):
            cell = g[g["param"] == param]
            traces = cell_traces(cell)
            traced |= {opt} if traces else set()
            ref = reference(bk, cell["problem"].iloc[0], cell["case"].iloc[0],
                            cell["problem_variant"].iloc[0], family(param))
            if not traces or not np.isfinite(ref):
                continue
            grid = _grid(traces)
            curves[opt, param] = (grid, [ecdf(np.array([hitting_evals(
                e, b, ref + eps * abs(ref)) for e, b, _ in traces]), grid)
                for eps in EPSILONS], len(traces))
    opts = [o for o in _optimizers(df) if o in traced]
    if not opts:
        return None
    if not any(share.any() for _, shares, _ in curves.values() for share in shares):
        return ECDF_NONE_REACHED
    colors = _colors(df)
    fig, axes = plt.subplots(len(EPSILONS), len(opts), figsize=(5.5 * len(opts), 3.8 *
                             len(EPSILONS)), squeeze=False, sharey=True)
    for j, opt in enumerate(opts):
        g = df[df["optimizer"] == opt]
        for param in map_order(g["param"].unique()):
            if (opt, param) not in curves:
                continue
            grid, shares, n = curves[opt, param]
            for i, share in enumerate(shares):
                axes[i, j].step(grid, share, where="post",
                                color=colors[param], label=f"{param} (n = {n})")
        for i, eps in enumerate(EPSILONS):
            ax = axes[i, j]
            _log_x(ax)
            ax.set_ylim(-0.02, 1.02)
            ax.set_title(f"{opt}, target f*·(1 + {eps:g})")
            ax.set_xlabel("objective evaluations")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        axes[0, j].set_ylabel("share of starts at target")
    fig.suptitle(f"{title}: fixed-target ECDF\nf* = best-known of each map's own family "
                 "(diagonal or full): a map that reaches its own, higher f* sooner is not "
                 "better")
    return _save(fig, path)


def cost_distribution(df: pd.DataFrame, label: str, title: str, path: Path,
                      paper: Any = None) -> Path:
    """Box plot and points of converged costs per optimizer (panel) × map.

    Diverged and failed starts are not plotted (a penalty is not a cost): the tick label
    gives converged / all starts. Published means / medians (a problem's
    :class:`~penaltyrun.problems.base.PaperValues`) are dashed lines of fixed colours. A log
    axis when the costs span more than two decades. A box of more than
    :data:`~penaltyrun.report.tables.MAX_DOTS` converged starts shows that many of them as
    dots, drawn at random (its tick label says so); the box is computed from every start.
    """
    opts = sorted(df["optimizer"].unique())
    df = narrow(df, ("optimizer", "param", "best_cost", "status", "best_converged"))
    ok = df[converged(df)]
    fig, axes = plt.subplots(1, len(opts), figsize=(max(4.0, 1.1 * df["param"].nunique() + 1.6)
                                                    * len(opts), 4.8), squeeze=False,
                             sharey=True)
    colors = _colors(df)
    costs = ok["best_cost"].astype(float).to_numpy()
    log = costs.size and costs.min() > 0 and costs.max() / costs.min() > 100
    rng = np.random.default_rng(0)
    for ax, opt in zip(axes[0], opts):
        g, gok = df[df["optimizer"] == opt], ok[ok["optimizer"] == opt]
        params = map_order(g["param"].unique())
        data = [gok.loc[gok["param"] == p, "best_cost"].astype(float).to_numpy()
                for p in params]
        if any(d.size for d in data):
            ax.boxplot([d if d.size else [np.nan] for d in data], showfliers=False)
        drawn = [dot_sample(d.size, rng) for d in data]
        ticks = [f"{p}\n{d.size}/{int((g['param'] == p).sum())}"
                 + (f"\n({len(k)} dots)" if len(k) < d.size else "")
                 for p, d, k in zip(params, data, drawn)]
        ax.set_xticks(range(1, len(params) + 1), ticks)
        shown: set[str] = set()
        for i, (p, values, k) in enumerate(zip(params, data, drawn), start=1):
            values = values[k]
            ax.scatter(i + rng.uniform(-0.12, 0.12, values.size), values, s=16,
                       color=colors[p], zorder=3)
            for kind, color in PAPER_COLORS.items():
                ref = paper_value(paper, p, kind) if paper is not None else np.nan
                if np.isfinite(ref):
                    name = f"paper {kind.split('_')[0]}"
                    ax.hlines(ref, i - 0.3, i + 0.3, colors=color, linestyles="--",
                              label=None if name in shown else name)
                    shown.add(name)
        ax.set_title(f"{opt} (converged/all under each map)")
        ax.grid(True, axis="y", alpha=0.3)
        if log:
            ax.set_yscale("log")
        _no_offset(ax)
        if ax.get_legend_handles_labels()[0]:
            ax.legend()
    axes[0, 0].set_ylabel(f"best cost per converged start\n{label}")
    fig.suptitle(title)
    return _save(fig, path)
