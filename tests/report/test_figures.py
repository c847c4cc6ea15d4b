"""Report figures: one panel per optimizer (never pooled), converged costs only, units."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from penaltyrun.report import figures, protocol
from penaltyrun.report.bestknown import best_known

PENALTY = 1000.0


def job(param, optimizer, cost, status="ok", trace=True):
    return {"problem": "toy", "case": "c1", "problem_variant": "", "variant": "",
            "param": param, "optimizer": optimizer, "status": status,
            "best_converged": status == "ok", "best_cost": cost,
            "trace_evals": [5, 50] if trace else None,
            "trace_best": [cost * 3, cost] if trace else None, "n_evals": 50,
            "job_id": f"{param}-{optimizer}-{cost}", "matrices": "{}"}


@pytest.fixture
def frame():
    return pd.DataFrame([job("diagonal", "pso", c) for c in (4.0, 5.0, 6.0)]
                        + [job("diagonal", "pso", PENALTY, "diverged")]
                        + [job("geagsp", "pso", c) for c in (3.0, 3.5)]
                        + [job("diagonal", "de", c) for c in (4.0, 4.1)]
                        + [job("geagsp", "de", c) for c in (2.0, 2.5, 2.6, 2.7)])


@pytest.fixture
def kept(monkeypatch):
    """Keep the figures open so that their panels can be inspected."""
    plt.close("all")
    monkeypatch.setattr(figures.plt, "close", lambda fig=None: None)
    yield lambda: [plt.figure(n) for n in plt.get_fignums()]
    plt.close("all")


def legends(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_anytime_has_one_panel_per_optimizer(frame, kept, tmp_path):
    path = figures.anytime(frame, best_known(frame), "J (unit)", "toy", tmp_path / "a.png")
    assert path.stat().st_size > 0
    (fig,) = kept()
    axes = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in axes] == ["de", "pso"]
    assert legends(axes[0]) == ["diagonal (median of 2)", "geagsp (median of 4)",
                                "best-known diagonal"]
    assert legends(axes[1]) == ["diagonal (median of 4)", "geagsp (median of 2)",
                                "best-known diagonal"]
    assert axes[0].get_xscale() == "log" and axes[0].get_yscale() == "log"
    assert "J (unit)" in axes[0].get_ylabel()


def test_ecdf_has_one_panel_per_optimizer_and_target(frame, kept, tmp_path):
    figures.ecdf_figure(frame, best_known(frame), "toy", tmp_path / "e.png")
    (fig,) = kept()
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == ["de, target f*·(1 + 0.01)", "pso, target f*·(1 + 0.01)",
                      "de, target f*·(1 + 0.001)", "pso, target f*·(1 + 0.001)"]
    assert legends(fig.axes[1]) == ["diagonal (n = 4)", "geagsp (n = 2)"]


def test_cost_distribution_per_optimizer_without_penalties(frame, kept, tmp_path):
    figures.cost_distribution(frame, "J (unit)", "toy", tmp_path / "c.png")
    (fig,) = kept()
    axes = fig.axes
    assert [ax.get_title().split(" ")[0] for ax in axes] == ["de", "pso"]
    assert [t.get_text() for t in axes[1].get_xticklabels()] == ["diagonal\n3/4",
                                                                 "geagsp\n2/2"]
    points = np.concatenate([c.get_offsets()[:, 1] for ax in axes for c in ax.collections])
    assert sorted(points) == sorted([4.0, 5.0, 6.0, 3.0, 3.5, 4.0, 4.1, 2.0, 2.5, 2.6, 2.7])
    assert PENALTY not in points


def test_anytime_and_ecdf_skip_results_without_traces(frame, tmp_path):
    old = frame.assign(trace_evals=None, trace_best=None)
    assert figures.anytime(old, best_known(old), "J", "toy", tmp_path / "a.png") is None
    assert figures.ecdf_figure(old, best_known(old), "toy", tmp_path / "e.png") is None


@pytest.mark.parametrize("problem, params, case, label", [
    ("zermelo", None, "default", "J = ∫½‖u‖² dt (nondimensional)"),
    ("attitude_lqr", "{}", "detumble", "J = ∫½‖u‖² dt (N²·m²·s)"),
    ("attitude_lyapunov", None, "rest_to_rest", "J = ∫½‖u‖² dt (N²·m²·s)"),
    ("qlaw", "{}", "C", "time of flight (days)"),
    ("qlaw", '{"objective": "min_fuel"}', "Estar", "propellant used (kg)"),
    ("lyapunov_transfer", None, "B", "time of flight (days)"),
    ("no_such_problem_here", None, "x", "cost (unit not declared)"),
])
def test_cost_labels_come_from_the_problems(problem, params, case, label):
    protocol.reset()
    assert protocol.info(problem, case, params).cost_label == label


def test_saved_figures_are_not_clipped(frame, kept, tmp_path):
    """bbox_inches="tight": the saved image holds every title and label (its extent grows
    past the figure size when a long title would otherwise be cut)."""
    import matplotlib.pyplot as plt
    from PIL import Image

    from penaltyrun.report.tables import save_figure

    fig, ax = plt.subplots(figsize=(3, 2))
    ax.set_title("a title far too long for a three-inch figure " * 3)
    path = save_figure(fig, tmp_path / "long.png", dpi=100)
    width, _ = Image.open(path).size
    assert width > 3 * 100  # tight bbox widened the image to hold the title
    out = figures.ecdf_figure(frame, best_known(frame), "toy", tmp_path / "ecdf.png")
    fig_w = 5.5 * frame["optimizer"].nunique() * 110
    assert Image.open(out).size[0] >= 0.9 * fig_w


def test_ecdf_without_any_start_at_a_target_is_a_sentence(frame, tmp_path):
    """When no start reached f*·(1 + ε) (f* from runs not in the section), every curve
    would be 0: the report says so instead of drawing the figure."""
    bk = best_known(frame)
    bk["best_known"] = bk["best_known"] / 10.0
    out = figures.ecdf_figure(frame, bk, "toy", tmp_path / "e.png")
    assert out == figures.ECDF_NONE_REACHED
    assert "1 % or 0.1 %" in out
    assert not (tmp_path / "e.png").exists()
    assert isinstance(figures.ecdf_figure(frame, best_known(frame), "toy",
                                          tmp_path / "e.png"), type(tmp_path))


def test_a_box_of_many_starts_draws_a_random_sample_of_dots_over_every_start(
        kept, tmp_path, monkeypatch):
    """Above MAX_DOTS converged starts a box draws that many of them as dots (distinct
    starts, said in the tick label); the box itself is of every start."""
    from penaltyrun.report import tables

    monkeypatch.setattr(tables, "MAX_DOTS", 5)
    costs = [1.0 + k for k in range(12)]
    frame = pd.DataFrame([job("diagonal", "pso", c) for c in costs]
                         + [job("full", "pso", c) for c in (2.0, 3.0)])
    figures.cost_distribution(frame, "J", "toy", tmp_path / "c.png")
    (fig,) = kept()
    (ax,) = fig.axes
    assert [t.get_text() for t in ax.get_xticklabels()] == ["diagonal\n12/12\n(5 dots)",
                                                            "full\n2/2"]
    dots = [c.get_offsets()[:, 1] for c in ax.collections]
    assert len(dots[0]) == 5 and len(set(dots[0])) == 5 and set(dots[0]) <= set(costs)
    assert sorted(dots[1]) == [2.0, 3.0]
    whiskers = sorted(y for line in ax.lines for y in line.get_ydata())
    assert whiskers[0] == 1.0 and whiskers[-1] == 12.0  # the box's whiskers span all 12


@pytest.mark.parametrize("n", [0, 1, 5, 6, 40])
def test_dot_sample_keeps_every_point_up_to_the_limit_and_distinct_ones_above(
        monkeypatch, n):
    from penaltyrun.report import tables

    monkeypatch.setattr(tables, "MAX_DOTS", 5)
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    k = tables.dot_sample(n, rng)
    if n <= 5:
        assert list(k) == list(range(n))
        assert rng.bit_generator.state == state  # small groups draw nothing: same pixels
    else:
        assert len(k) == 5 and len(set(k)) == 5 and list(k) == sorted(k) and k.max() < n


def test_cost_against_mode_draws_a_sample_of_a_large_map_and_says_so(
        kept, tmp_path, monkeypatch):
    from penaltyrun.report import controller_plots, tables

    monkeypatch.setattr(tables, "MAX_DOTS", 5)
    modes = pd.DataFrame({"param": ["diagonal"] * 9 + ["full"] * 3,
                          "cost": np.arange(1.0, 13.0), "slowest": -np.arange(1.0, 13.0)})
    controller_plots.cost_mode_scatter(modes, "toy", tmp_path / "m.png")
    (fig,) = kept()
    (ax,) = fig.axes
    assert legends(ax) == ["diagonal (9; 5 drawn)", "full (3)"]
    assert [len(c.get_offsets()) for c in ax.collections] == [5, 3]
