"""Figures of the tuned controllers: the closed-loop pole map (every map of a cell overlaid)
and per-channel time histories with the limits the problem declares (``simulate``'s
optional ``channels`` and ``limits`` keys, see :mod:`penaltyrun.problems.base`)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from penaltyrun.report.tables import dot_sample, save_figure

#: Most panels of the channel figure (one per history key).
MAX_PANELS = 6
#: Most channels drawn per panel (the first ones; the rest are named in the caption).
MAX_CHANNELS = 6
STYLES = ("-", "--", ":", "-.")
MARKERS = ("x", "o", "s", "^", "D", "v")


def pole_map(poles: Mapping[str, np.ndarray], title: str, path: Path) -> Path | None:
    """Continuous-time closed-loop poles s of each map, overlaid (the first map, the
    diagonal where present, as crosses; the others as hollow markers).

    Both axes are symmetric-logarithmic (linear within 1e-3 of the largest |s|), so slow
    modes near the imaginary axis stay visible beside fast ones.

    Parameters
    ----------
    poles : mapping label → complex ndarray
        Continuous-time poles (1 / time unit) per map label.
    title : str
    path : Path
        PNG written here.

    Returns
    -------
    Path or None
        ``path``, or None when no map has a finite pole.
    """
    finite = {k: np.asarray(v, complex)[np.isfinite(np.asarray(v, complex))]
              for k, v in poles.items()}
    finite = {k: v for k, v in finite.items() if v.size}
    if not finite:
        return None
    scale = max(float(np.max(np.abs(v))) for v in finite.values()) or 1.0
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, (label, s) in enumerate(finite.items()):
        style = {"color": f"C{k}"} if k == 0 else {"facecolors": "none",
                                                   "edgecolors": f"C{k}"}
        ax.scatter(s.real, s.imag, marker=MARKERS[k % len(MARKERS)], s=70, linewidths=1.5,
                   label=label, **style)
    ax.axvline(0.0, color="0.3", lw=0.8)
    ax.axhline(0.0, color="0.8", lw=0.6)
    lin = 1e-3 * scale
    real = np.concatenate([v.real for v in finite.values()])
    imag = np.concatenate([np.abs(v.imag) for v in finite.values()])
    ax.set_xscale("symlog", linthresh=lin)
    ax.set_yscale("symlog", linthresh=lin)
    ax.set_xlim(min(-lin, 2.0 * float(real.min())), max(lin, 2.0 * float(real.max())))
    top = max(lin, 2.0 * float(imag.max()))
    ax.set_ylim(-top, top)
    ax.set_xlabel("Re s (1 / time unit)")
    ax.set_ylabel("Im s (1 / time unit)")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=9)
    return save_figure(fig, path)


def _panels(sim: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """History arrays of one ``simulate`` dict as (n_t, channels); a per-start array
    (starts, n_t, channels) gives its first start."""
    t = np.asarray(sim.get("t", ()), float)
    out = {}
    for key, value in sim.items():
        if key in ("t", "channels", "limits") or isinstance(value, Mapping):
            continue
        arr = np.asarray(value)
        if arr.dtype.kind not in "fiub" or t.size < 2:
            continue
        if arr.ndim == 3 and arr.shape[1] == t.size:
            arr = arr[0]
        if arr.ndim in (1, 2) and arr.shape[0] == t.size:
            out[key] = arr.reshape(t.size, -1).astype(float)
    return out


def _limit_values(limit: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(lower, upper) of one ``limits`` entry as (n,) arrays."""
    lo, hi = limit
    return (np.broadcast_to(np.asarray(lo, float), (n,)),
            np.broadcast_to(np.asarray(hi, float), (n,)))


def channel_figure(sims: Mapping[str, Mapping[str, Any]], title: str,
                   path: Path) -> Path | None:
    """Every channel of the ``simulate`` dicts against time, one panel per history key
    (the keys named in ``channels`` first): channels by colour (legend per panel), maps by
    line style (legend on top), limits as dotted lines.

    Parameters
    ----------
    sims : mapping label → simulate dict
    title : str
    path : Path

    Returns
    -------
    Path or None
        ``path``, or None when no dict has a time grid.
    """
    series = {label: _panels(sim) for label, sim in sims.items()}
    named = [k for sim in sims.values() for k in (sim.get("channels") or {})]
    keys = list(dict.fromkeys(named + sorted({k for h in series.values() for k in h})))
    keys = [k for k in keys if any(k in h for h in series.values())][:MAX_PANELS]
    if not keys:
        return None
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(len(keys), 1, figsize=(8, 2.1 * len(keys) + 1.0), sharex=True,
                             squeeze=False)
    for ax, key in zip(axes[:, 0], keys):
        channels: dict[str, str] = {}
        drawn_limit = False
        for k, (label, hist) in enumerate(series.items()):
            if key not in hist:
                continue
            sim = sims[label]
            data = hist[key][:, :MAX_CHANNELS]
            names = list((sim.get("channels") or {}).get(key, []))
            for j in range(data.shape[1]):
                name = names[j] if j < len(names) else (f"{key}[{j}]" if data.shape[1] > 1
                                                        else key)
                channels.setdefault(name, f"C{j % 10}")
                ax.plot(np.asarray(sim["t"], float), data[:, j], STYLES[k % len(STYLES)],
                        color=f"C{j % 10}")
            limit = (sim.get("limits") or {}).get(key)
            if limit is not None and not drawn_limit:
                lo, hi = _limit_values(limit, hist[key].shape[1])
                for v in sorted({float(x) for x in np.concatenate([lo, hi])
                                 if np.isfinite(x)}):
                    ax.axhline(v, color="k", ls=":", lw=1.2)
                    drawn_limit = True
        ax.set_ylabel(key + (" (limits dotted)" if drawn_limit else ""))
        ax.grid(alpha=0.3)
        ax.add_artist(ax.legend([Line2D([], [], color=c) for c in channels.values()],
                                list(channels), fontsize=8, ncol=min(len(channels), 6),
                                loc="best"))
    axes[-1, 0].set_xlabel("t (time unit of the problem)")
    maps = [Line2D([], [], color="k", ls=STYLES[k % len(STYLES)]) for k in range(len(series))]
    axes[0, 0].legend(maps, list(series), loc="lower center", bbox_to_anchor=(0.5, 1.0),
                      ncol=min(len(series), 4), fontsize=9, frameon=False)
    fig.suptitle(title)
    return save_figure(fig, path)


def cost_mode_scatter(modes: Any, title: str, path: Path, cost_label: str = "cost"
                      ) -> Path | None:
    """Every start's cost against its slowest closed-loop real part, one colour per map
    (the diagonal first, as in :func:`pole_map`); a map of more than
    :data:`~penaltyrun.report.tables.MAX_DOTS` starts draws that many of them, at random
    (its legend entry says so).

    Parameters
    ----------
    modes : DataFrame
        Columns ``param``, ``cost``, ``slowest`` (max Re s, 1 / time unit).
    title : str
    path : Path
    cost_label : str
        Label of the cost axis (name and unit).

    Returns
    -------
    Path or None
        ``path``, or None when no start has a finite slowest mode.
    """
    finite = modes[np.isfinite(modes["slowest"].to_numpy(float))]
    if finite.empty:
        return None
    fig, ax = plt.subplots(figsize=(7, 4.2))
    params = sorted(set(finite["param"]), key=lambda p: (p != "diagonal", p))
    rng = np.random.default_rng(0)
    for k, param in enumerate(params):
        m = finite[finite["param"] == param]
        drawn = m.iloc[dot_sample(len(m), rng)]
        shown = f"; {len(drawn)} drawn" if len(drawn) < len(m) else ""
        ax.scatter(drawn["slowest"], drawn["cost"], s=24, color=f"C{k}",
                   marker=MARKERS[k % 6], alpha=0.8, label=f"{param} ({len(m)}{shown})")
    ax.set_xlabel("slowest closed-loop real part max Re s (1 / time unit)")
    ax.set_ylabel(cost_label)
    if (finite["cost"] > 0).all() and finite["cost"].max() > 10 * finite["cost"].min():
        ax.set_yscale("log")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, title="map (converged starts)", title_fontsize=8)
    return save_figure(fig, path)


__all__ = ["channel_figure", "cost_mode_scatter", "pole_map"]
