"""Figures of the explanation page "What a full matrix does" (see
:mod:`penaltyrun.docsgen.fullmatrix`).

* :func:`ratio_figure`: per cell, the held-out cost ratios J_full / J_diag of every pairing
  (box: quartiles, whiskers: 5 and 95 %);
* :func:`mode_figure`: per cell, every converged start's training cost against its slowest
  closed-loop real part;
* :func:`trajectory_figure`: one held-out start flown by the best-known diagonal and full
  matrices side by side (distance to the target, body rates, energy).

Figures are drawn on :class:`matplotlib.figure.Figure` objects (no pyplot state, the
caller's backend untouched) and saved without a software stamp, so the same data and the same
matplotlib give the same file.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

#: Colours and markers of the maps (the diagonal first).
COLOURS = ("C0", "C1", "C2", "C3", "C4")
MARKERS = ("o", "s", "^", "D", "v")
#: Dots per inch of the saved figures.
DPI = 100


def _save(fig: Figure, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI, metadata={"Software": None})
    return path


def _grid(n: int) -> tuple[int, int]:
    cols = 1 if n == 1 else 2
    return int(np.ceil(n / cols)), cols


def _cells(frame: pd.DataFrame) -> list[tuple[str, str]]:
    return sorted({(str(p), str(c)) for p, c in zip(frame["problem"], frame["case"])})


def ratio_figure(pairs: pd.DataFrame, ratios: Mapping[str, np.ndarray], path: Path) -> Path:
    """Held-out cost ratios J_full / J_diag of every pairing, one panel per cell.

    Parameters
    ----------
    pairs : DataFrame
        ``problem``, ``case``, ``optimizer``, ``full_map``, ``label``, ``full_cheaper``,
        ``scenarios`` (the held-out table).
    ratios : mapping
        ``label`` → per-scenario ratios (ndarray).
    path : Path
        PNG written here.
    """
    cells = _cells(pairs)
    nrows, ncols = _grid(len(cells))
    fig = Figure(figsize=(6.2 * ncols, 2.6 * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    for ax, (problem, case) in zip(axes, cells):
        sel = pairs[(pairs["problem"] == problem) & (pairs["case"] == case)
                    & pairs["label"].isin(list(ratios))]
        data = [np.asarray(ratios[lab], float) for lab in sel["label"]]
        names = [f"{o.split(' (')[0]} / {f}  ({int(k)}/{int(n)} cheaper)"
                 for o, f, k, n in zip(sel["optimizer"], sel["full_map"], sel["full_cheaper"],
                                       sel["scenarios"])]
        if data:
            ax.boxplot(data, orientation="horizontal", whis=(5, 95), showfliers=False,
                       tick_labels=names)
        ax.axvline(1.0, color="k", lw=1, ls="--")
        ax.set_xscale("log")
        ax.set_title(f"{problem} / {case}", fontsize=10)
        ax.tick_params(axis="y", labelsize=8)
        ax.grid(alpha=0.3, axis="x")
        ax.set_xlabel("held-out J_full / J_diag (log; left of 1: full cheaper)", fontsize=8)
    for ax in axes[len(cells):]:
        ax.set_visible(False)
    return _save(fig, path)


def mode_figure(modes: pd.DataFrame, path: Path, best: pd.DataFrame | None = None) -> Path:
    """Training cost against the slowest closed-loop real part, every converged start, one
    panel per cell (the best-known diagonal and full starts ringed when ``best`` is given).

    Parameters
    ----------
    modes : DataFrame
        ``problem``, ``case``, ``param``, ``cost`` (training J), ``slowest`` (max Re s, 1/s).
    path : Path
    best : DataFrame, optional
        ``problem``, ``case``, ``diag_cost``, ``full_cost``, ``diag_slowest``,
        ``full_slowest`` (the page's cells).
    """
    finite = modes[np.isfinite(modes["slowest"].to_numpy(float))]
    cells = _cells(finite)
    nrows, ncols = _grid(len(cells))
    fig = Figure(figsize=(5.2 * ncols, 3.4 * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False)).ravel()
    params = sorted(set(finite["param"]), key=lambda p: (p != "diagonal", p))
    for ax, (problem, case) in zip(axes, cells):
        cell = finite[(finite["problem"] == problem) & (finite["case"] == case)]
        for k, param in enumerate(params):
            m = cell[cell["param"] == param]
            ax.scatter(m["slowest"], m["cost"], s=22, color=COLOURS[k % 5],
                       marker=MARKERS[k % 5], alpha=0.75, label=f"{param} ({len(m)})")
        if best is not None:
            b = best[(best["problem"] == problem) & (best["case"] == case)]
            for key in ("diag", "full"):
                ax.scatter(b[f"{key}_slowest"], b[f"{key}_cost"], s=140, facecolors="none",
                           edgecolors="k", linewidths=1.2)
        ax.set_yscale("log")
        ax.set_title(f"{problem} / {case}", fontsize=10)
        ax.set_xlabel("slowest closed-loop real part max Re s (1/s)", fontsize=8)
        ax.set_ylabel("training J (N²·m²·s)", fontsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, title="map (starts); ringed: best", title_fontsize=7)
    for ax in axes[len(cells):]:
        ax.set_visible(False)
    return _save(fig, path)


def trajectory_figure(sims: Mapping[str, Mapping[str, np.ndarray]], path: Path,
                      title: str = "", deadline: float | None = None) -> Path:
    """One held-out start flown by each matrix, side by side on a common time axis: the
    distance to the target (log), the body rates and the energy J(t) (log, from 10⁻⁶).

    Parameters
    ----------
    sims : mapping
        Matrix label → ``t`` (s), ``w`` (n, 3) rad/s, ``J`` (n,), ``dist`` (n,).
    path : Path
    title : str
        Figure title.
    deadline : float, optional
        The training deadline (s), drawn as a dashed line.
    """
    labels = list(sims)
    fig = Figure(figsize=(5.0 * len(labels), 7.0))
    axes = fig.subplots(3, len(labels), squeeze=False, sharex=True, sharey="row")
    for col, label in enumerate(labels):
        s = sims[label]
        t = np.asarray(s["t"], float)
        top, mid, low = axes[0, col], axes[1, col], axes[2, col]
        top.semilogy(t, np.maximum(np.asarray(s["dist"], float), 1e-12), color="k")
        top.set_title(f"{label}: arrives at {t[-1]:.0f} s", fontsize=10)
        w = np.asarray(s["w"], float)
        for k in range(w.shape[1]):
            mid.plot(t, w[:, k], lw=1, label=f"ω{k + 1}")
        low.semilogy(t, np.maximum(np.asarray(s["J"], float), 1e-6), color="C3")
        for ax in (top, mid, low):
            ax.grid(alpha=0.3)
            if deadline is not None:
                ax.axvline(deadline, color="grey", ls="--", lw=1)
        low.set_xlabel("time (s)")
    axes[0, 0].set_ylabel("distance to the target")
    axes[1, 0].set_ylabel("body rates ω (rad/s)")
    axes[2, 0].set_ylabel("energy J(t) (N²·m²·s)")
    axes[1, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    return _save(fig, path)


def write_all(df: pd.DataFrame, m: Any, ex: Mapping[str, Any], folder: Path,
              files: Mapping[str, str]) -> list[Path]:
    """Draw the three figures of one study into ``folder``.

    Parameters
    ----------
    df : DataFrame
        The study's records.
    m : Mechanism
        :func:`penaltyrun.docsgen.fullmatrix.mechanism` of ``df``.
    ex : mapping
        :func:`penaltyrun.docsgen.fullmatrix.example_scenario` (the trajectory figure's scenario).
    folder : Path
        Where the PNG files go.
    files : mapping
        Some of ``ratios``, ``modes``, ``trajectory`` → file name: the figures drawn.
    """
    from penaltyrun.docsgen.fullmatrix import simulate_example

    out = []
    if "ratios" in files:
        out.append(ratio_figure(m.pairs, m.ratios, folder / files["ratios"]))
    if "modes" in files:
        out.append(mode_figure(m.modes, folder / files["modes"], m.cells))
    if "trajectory" in files:
        sims = simulate_example(df, ex)
        cell = m.cells[(m.cells["problem"] == ex["problem"])
                       & (m.cells["case"] == ex["case"])]
        full_map = str(cell["full_map"].iloc[0])
        sims = {"best diagonal": sims["diagonal"], f"best full ({full_map})": sims["full"]}
        title = (f"{ex['problem']} / {ex['case']}, held-out start {ex['scenario']} "
                 f"(J_full / J_diag = {ex['ratio']:.3g}, the pair's median scenario)")
        out.append(trajectory_figure(sims, folder / files["trajectory"], title,
                                     ex["training_horizon"]))
    return out


__all__ = ["mode_figure", "ratio_figure", "trajectory_figure", "write_all"]
