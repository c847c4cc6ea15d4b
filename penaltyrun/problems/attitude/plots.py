"""Plots of attitude closed-loop histories (matplotlib, imported lazily).

Each helper takes ``sims``: a mapping label (e.g. "best diagonal") → the dict returned by
``AttitudeProblem.simulate``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

_STYLES = ("-", "--", ":", "-.")
_COLORS = ("C0", "C1", "C2", "C3")


def _plot_components(sims: Mapping[str, Mapping[str, np.ndarray]], key: str,
                     names: tuple[str, ...], ylabel: str, ax: Any) -> Any:
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(7, 3.5))
    for k, (label, sim) in enumerate(sims.items()):
        style = _STYLES[k % len(_STYLES)]
        data = np.asarray(sim[key])
        for i, comp in enumerate(names):
            ax.plot(sim["t"], data[:, i], style, color=_COLORS[i % len(_COLORS)],
                    label=f"{label}: {comp}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    return ax


def plot_quaternions(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Quaternion histories; ``sims`` maps a label (e.g. "best diagonal") to a
    :meth:`AttitudeProblem.simulate` dict. Components by colour, candidates by line style."""
    return _plot_components(sims, "q", ("q0", "q1", "q2", "q3"), "quaternion", ax)


def plot_rates(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Body-rate histories (rad/s); see :func:`plot_quaternions`."""
    return _plot_components(sims, "w", ("ω1", "ω2", "ω3"), "body rate (rad/s)", ax)


def plot_torques(sims: Mapping[str, Mapping[str, np.ndarray]], ax: Any = None) -> Any:
    """Control torque histories (N·m); see :func:`plot_quaternions`."""
    return _plot_components(sims, "u", ("u1", "u2", "u3"), "torque (N·m)", ax)


def plot_histories(sims: Mapping[str, Mapping[str, np.ndarray]], layout: bool = True) -> Any:
    """Figure with quaternion, rate and torque histories stacked (shared time axis).

    Parameters
    ----------
    sims : mapping label → dict
        ``simulate`` dicts (``t`` s, ``q``, ``w`` rad/s, ``u`` N·m).
    layout : bool, optional
        Apply ``fig.tight_layout()`` (default); False leaves the layout to the caller (the
        report lays out every figure it saves).

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    plot_quaternions(sims, axes[0])
    plot_rates(sims, axes[1])
    plot_torques(sims, axes[2])
    for ax in axes[:2]:
        ax.set_xlabel("")
    if layout:
        fig.tight_layout()
    return fig


__all__ = ["plot_histories", "plot_quaternions", "plot_rates", "plot_torques"]
