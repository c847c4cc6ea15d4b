"""Generic report figures: PSO convergence curves and cost distributions per cell."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402


def convergence(df: pd.DataFrame, title: str, path: Path) -> Path:
    """Best cost vs iteration, one thin line per start and the median bold, per param."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for i, (param, g) in enumerate(df.groupby("param", sort=True)):
        color = f"C{i}"
        curves = [np.asarray(h, float) for h in g["history"] if h is not None and len(h)]
        for h in curves:
            ax.plot(np.arange(1, h.size + 1), h, color=color, alpha=0.3, lw=0.8)
        if curves:
            n = max(h.size for h in curves)
            padded = np.array([np.pad(h, (0, n - h.size), mode="edge") for h in curves])
            ax.plot(np.arange(1, n + 1), np.median(padded, axis=0), color=color, lw=2.2,
                    label=f"{param} (median of {len(curves)})")
    ax.set_xlabel("iteration")
    ax.set_ylabel("best cost")
    ax.set_yscale("log")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def cost_distribution(df: pd.DataFrame, title: str, path: Path,
                      paper: dict[str, float] | None = None) -> Path:
    """Box plot plus every start's best cost per parameterization (paper means marked)."""
    ok = df[df["status"] != "failed"]
    params = sorted(ok["param"].unique())
    fig, ax = plt.subplots(figsize=(1.6 * max(len(params), 2) + 2, 4.5))
    data = [ok.loc[ok["param"] == p, "best_cost"].astype(float).to_numpy() for p in params]
    if params:
        ax.boxplot(data, showfliers=False)
        ax.set_xticks(range(1, len(params) + 1), params)
    rng = np.random.default_rng(0)
    for i, (p, values) in enumerate(zip(params, data), start=1):
        converged = ok.loc[ok["param"] == p, "best_converged"].fillna(False).to_numpy(bool)
        x = i + rng.uniform(-0.12, 0.12, values.size)
        ax.scatter(x[converged], values[converged], s=18, color="C0", zorder=3,
                   label="converged" if i == 1 else None)
        ax.scatter(x[~converged], values[~converged], s=22, marker="x", color="C3", zorder=3,
                   label="not converged" if i == 1 else None)
        ref = (paper or {}).get("full" if p in ("full", "geagsp") else p)
        if ref is not None and np.isfinite(ref):
            ax.hlines(ref, i - 0.3, i + 0.3, colors="k", linestyles="--",
                      label="paper mean" if p == "diagonal" else None)
    ax.set_ylabel("best cost per start")
    ax.set_title(title)
    ax.legend(fontsize=8)
    ax.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
