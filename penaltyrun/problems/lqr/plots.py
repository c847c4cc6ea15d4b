"""Plots of ``problem=lqr`` closed loops (dictionaries from :meth:`LQRProblem.simulate`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np


def plot_histories(paths: Mapping[str, Mapping[str, np.ndarray]], out: Any = None) -> Any:
    """State norm ‖x(t)‖ and input norm ‖u(t)‖ of every training start, one colour per
    candidate (e.g. best diagonal vs best full).

    Parameters
    ----------
    paths : mapping label → dict from :meth:`~penaltyrun.problems.lqr.problem.LQRProblem.simulate`
        ``t`` (n,), ``x`` (k, n, n_states), ``u`` (k, n, m).
    out : path, optional
        Save the figure there (PNG) and close it.

    Returns
    -------
    matplotlib Figure
    """
    import matplotlib.pyplot as plt

    fig, (ax_x, ax_u) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for i, (label, path) in enumerate(paths.items()):
        colour = f"C{i % 10}"
        for k in range(path["x"].shape[0]):
            name = label if k == 0 else None
            ax_x.semilogy(path["t"], np.linalg.norm(path["x"][k], axis=1), color=colour,
                          label=name, lw=1.2)
            ax_u.plot(path["t"], np.linalg.norm(path["u"][k], axis=1), color=colour, lw=1.2)
    ax_x.set_ylabel("‖x‖ (state units)")
    ax_u.set_ylabel("‖u‖ (input units)")
    ax_u.set_xlabel("t (time units)")
    ax_x.legend(fontsize=8)
    fig.tight_layout()
    if out is not None:
        fig.savefig(out, dpi=120)
        plt.close(fig)
    return fig


__all__ = ["plot_histories"]
