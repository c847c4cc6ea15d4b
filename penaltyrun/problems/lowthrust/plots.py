"""Plots of low-thrust transfers (matplotlib, Agg-safe; they take the dicts returned by
``LowThrustProblem.simulate``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.problems.lowthrust.params import DEG


def _figure_axes(ax: Any, projection: str | None = None, nrows: int = 1) -> tuple[Any, Any]:
    import matplotlib.pyplot as plt

    if ax is not None:
        return ax.figure, ax
    if nrows == 1:
        fig = plt.figure(figsize=(6, 5))
        return fig, fig.add_subplot(111, projection=projection)
    fig, axes = plt.subplots(nrows, 1, figsize=(7, 2.0 * nrows), sharex=True)
    return fig, axes


def _finish(fig: Any, out: Any) -> Any:
    if out is not None:
        import matplotlib.pyplot as plt

        fig.savefig(out, dpi=120, bbox_inches="tight")
        plt.close(fig)
    return fig


def plot_trajectory(sim: Mapping[str, np.ndarray], out: Any = None, ax: Any = None,
                    title: str = "") -> Any:
    """3-D trajectory (km) with Earth's radius marked; thrust arcs solid, coast arcs grey.

    Parameters
    ----------
    sim : mapping
        Output of ``simulate`` (``x``, ``y``, ``z``, ``thrust_on``).
    out : path-like, optional
        Save the figure there and close it.
    ax : matplotlib 3-D Axes, optional
        Draw into this Axes instead of a new figure.
    """
    fig, ax = _figure_axes(ax, projection="3d")
    x, y, z = sim["x"], sim["y"], sim["z"]
    on = np.asarray(sim["thrust_on"]) > 0.5
    ax.plot(x, y, z, color="0.7", lw=0.4, label="coast arcs")
    ax.plot(np.where(on, x, np.nan), np.where(on, y, np.nan), np.where(on, z, np.nan),
            color="C3", lw=0.5, label="thrust arcs")
    u = np.linspace(0.0, 2.0 * np.pi, 60)
    ax.plot(lt.R_E * np.cos(u), lt.R_E * np.sin(u), 0.0 * u, color="C0",
            label="Earth radius (equator)")
    if len(x):
        ax.scatter([x[0]], [y[0]], [z[0]], color="C2", marker="o", s=30,
                   label="departure (on the departure orbit)")
        ax.scatter([x[-1]], [y[-1]], [z[-1]], color="k", marker="*", s=60,
                   label="arrival (on the target orbit)")
    if "t" in sim and len(sim["t"]):
        title = f"{title}\nToF {float(sim['t'][-1]) / 86400.0:.3f} days" if title else \
            f"ToF {float(sim['t'][-1]) / 86400.0:.3f} days"
    lim = float(np.nanmax(np.abs(np.concatenate([x, y, z])))) if len(x) else lt.R_E
    for setter in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        setter(-lim, lim)
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.set_zlabel("z [km]")
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize=9)
    return _finish(fig, out)


#: Histories plotted unwrapped (rad in ``simulate`` output).
ANGLE_KEYS = ("Omega", "omega")


def plot_elements(sims: Mapping[str, Mapping[str, np.ndarray]], out: Any = None,
                  axes: Any = None) -> Any:
    """Element histories (a, e, i, Ω, ω, mass vs days) of labelled runs, e.g. diagonal vs full.

    Ω and ω are unwrapped (continuous through ±180°), so an angle settling at 180° does not
    draw a wall of jumps between −180° and 180°.

    Parameters
    ----------
    sims : mapping of label → simulate dict
        For example ``{"diagonal": sim_d, "full": sim_f}``.
    out : path-like, optional
        Save the figure there and close it.
    axes : sequence of 6 Axes, optional
    """
    fig, axes = _figure_axes(axes, nrows=6)
    rows = (("a", "a [km]", 1.0), ("e", "e [-]", 1.0), ("i", "i [deg]", 1.0 / DEG),
            ("Omega", "Ω [deg, unwrapped]", 1.0 / DEG), ("omega", "ω [deg, unwrapped]", 1.0 / DEG),
            ("mass", "m [kg]", 1.0))
    for label, sim in sims.items():
        days = np.asarray(sim["t"]) / 86400.0
        for ax, (key, _, fac) in zip(axes, rows, strict=True):
            values = np.asarray(sim[key], float)
            if key in ANGLE_KEYS:
                values = np.unwrap(values)
            ax.plot(days, values * fac, lw=0.8, label=label)
    for ax, (_, ylabel, _) in zip(axes, rows, strict=True):
        ax.set_ylabel(ylabel)
    axes[0].legend(loc="best", fontsize="small")
    axes[-1].set_xlabel("time [days]")
    return _finish(fig, out)


def plot_thrust(sim: Mapping[str, np.ndarray], out: Any = None, ax: Any = None,
                title: str = "") -> Any:
    """Thrust/coast pattern (on = 1) versus time in days, with the mass on a twin axis."""
    fig, ax = _figure_axes(ax)
    days = np.asarray(sim["t"]) / 86400.0
    ax.fill_between(days, 0.0, np.asarray(sim["thrust_on"]), step="post", color="C3",
                    alpha=0.5, lw=0.0)
    ax.set_ylim(-0.05, 1.05)
    ax.set_ylabel("thrust on")
    ax.set_xlabel("time [days]")
    twin = ax.twinx()
    twin.plot(days, sim["mass"], color="C0", lw=1.0)
    twin.set_ylabel("mass [kg]")
    ax.set_title(title)
    return _finish(fig, out)


__all__ = ["ANGLE_KEYS", "plot_elements", "plot_thrust", "plot_trajectory"]
