"""Plots of rendezvous MPC runs (dictionaries from :meth:`RendezvousMPC.simulate`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def plot_trajectory(paths: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Approach paths in the orbital plane: along-track y (horizontal) vs radial x, m.

    Parameters
    ----------
    paths : mapping label → dict from ``simulate``
    ax : matplotlib Axes, optional
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    for label, path in paths.items():
        ax.plot(path["r"][:, 1], path["r"][:, 0], lw=2, label=label)
        ax.plot(path["r"][0, 1], path["r"][0, 0], "ko")
    ax.plot(0.0, 0.0, "k*", ms=12, label="target")
    ax.set_xlabel("along-track y (m)")
    ax.set_ylabel("radial x (m)")
    ax.legend(loc="best", fontsize=8)
    return ax


def plot_inputs(paths: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Commanded acceleration magnitude ‖u‖ (m/s²) and cumulative Δv (m/s) over time.

    Parameters
    ----------
    paths : mapping label → dict from ``simulate``
    ax : matplotlib Axes, optional (the Δv curves go on a twin axis)
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 4))
    twin = ax.twinx()
    for label, path in paths.items():
        line, = ax.step(path["t"], np.linalg.norm(path["u"], axis=1), where="post",
                        label=f"{label} ‖u‖")
        twin.plot(path["t"], path["delta_v"], "--", color=line.get_color(),
                  label=f"{label} Δv")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("‖u‖ (m/s²)")
    twin.set_ylabel("cumulative Δv (m/s)")
    ax.legend(loc="upper right", fontsize=8)
    return ax


__all__ = ["plot_inputs", "plot_trajectory"]
