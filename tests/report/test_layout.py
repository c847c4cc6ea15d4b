"""The report's tight layout: matplotlib's margins and spacing, each panel measured once."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.layout_engine import TightLayoutEngine  # noqa: E402

from penaltyrun.report.layout import tight_layout  # noqa: E402


def _grid() -> plt.Figure:
    fig, axes = plt.subplots(2, 3, figsize=(9, 5))
    for k, ax in enumerate(axes.flat):
        ax.plot(np.arange(10) * 10.0 ** k, label=f"line {k}")
        ax.set_title(f"panel {k} with a longer title")
        ax.set_ylabel("energy (N·m·s)" if k % 3 == 0 else "")
        if k == 4:
            ax.set_yscale("log")
            ax.legend()
    fig.suptitle("a grid of panels")
    return fig


def _shared_column() -> plt.Figure:
    fig, axes = plt.subplots(4, 1, figsize=(8, 9), sharex=True)
    for k, ax in enumerate(axes):
        ax.plot(np.linspace(0, 100, 50), np.sin(np.linspace(0, 10, 50)) * 10.0 ** (3 * k))
        ax.set_ylabel(f"channel {k}")
    axes[-1].set_xlabel("time (s)")
    return fig


def _colorbar() -> plt.Figure:
    fig, axes = plt.subplots(1, 3, figsize=(10, 4), gridspec_kw={"width_ratios": [1, 1, 0.05]})
    mesh = None
    for ax in axes[:2]:
        mesh = ax.pcolormesh(np.arange(5), np.arange(4), np.arange(12.0).reshape(3, 4) + 1)
        ax.set_xlabel("roll (deg)")
    fig.colorbar(mesh, cax=axes[2], label="arrival time (s)")
    fig.suptitle("maps")
    return fig


@pytest.mark.parametrize("build", [_grid, _shared_column, _colorbar])
def test_same_layout_as_matplotlib(build):
    reference, ours = build(), build()
    TightLayoutEngine().execute(reference)
    tight_layout(ours)
    try:
        for name in ("left", "right", "top", "bottom", "wspace", "hspace"):
            assert getattr(ours.subplotpars, name) == getattr(reference.subplotpars, name)
        for a, b in zip(ours.axes, reference.axes):
            np.testing.assert_array_equal(a.get_position().bounds, b.get_position().bounds)
        assert ours.get_layout_engine() is None
        assert all("get_tightbbox" not in vars(ax) for ax in ours.axes)
    finally:
        plt.close(reference)
        plt.close(ours)


def test_each_panel_measured_once(monkeypatch):
    calls: list[int] = []
    measure = Axes.get_tightbbox

    def counted(self, *args, **kwargs):
        if kwargs.get("for_layout_only"):
            calls.append(id(self))
        return measure(self, *args, **kwargs)

    monkeypatch.setattr(Axes, "get_tightbbox", counted)
    fig = _grid()
    try:
        TightLayoutEngine().execute(fig)
        assert len(calls) == 2 * len(fig.axes)  # matplotlib's two passes
        calls.clear()
        tight_layout(fig)
        assert sorted(calls) == sorted(id(ax) for ax in fig.axes)
    finally:
        plt.close(fig)


def test_measurement_restored_after_a_failure(monkeypatch):
    fig = _grid()

    def refuse(self, fig):
        raise RuntimeError("layout refused")

    monkeypatch.setattr(TightLayoutEngine, "execute", refuse)
    try:
        with pytest.raises(RuntimeError):
            tight_layout(fig)
        assert all("get_tightbbox" not in vars(ax) for ax in fig.axes)
    finally:
        plt.close(fig)


def test_save_figure_draws_once_after_a_hooks_tight_layout(monkeypatch, tmp_path):
    """A problem's plotting code that called ``fig.tight_layout()`` left a placeholder
    layout engine, with which ``savefig`` draws the figure twice; the report removes it."""
    from matplotlib.figure import Figure

    from penaltyrun.report.tables import save_figure

    draws: list[int] = []
    draw = Figure.draw

    def counted(self, renderer):
        draws.append(1)
        return draw(self, renderer)

    monkeypatch.setattr(Figure, "draw", counted)
    fig = _shared_column()
    fig.tight_layout()
    assert fig.get_layout_engine() is not None
    save_figure(fig, tmp_path / "f.png")
    assert len(draws) == 1
    constrained = _grid()
    constrained.set_layout_engine("constrained")
    save_figure(constrained, tmp_path / "c.png")
    assert (tmp_path / "c.png").stat().st_size > 0


def test_save_figure_writes_other_formats_with_matplotlibs_defaults(tmp_path):
    """The PNG compression setting is Pillow's; an SVG (or PDF) is saved as matplotlib
    saves it."""
    from penaltyrun.report.tables import save_figure

    for name in ("f.svg", "f.pdf", "f.png"):
        assert save_figure(_grid(), tmp_path / name).stat().st_size > 0
    assert (tmp_path / "f.svg").read_text().lstrip().startswith("<?xml")
