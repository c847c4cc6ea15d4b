"""A user problem describes itself to the report through the protocol hooks; the report
works without its module too; the HTML page is self-contained."""

from __future__ import annotations

import re
import textwrap

import pytest

from penaltyrun import io, problems, runner
from penaltyrun.problems.attitude.report import paper_tables
from penaltyrun.report import build_report

MODULE = '''
import numpy as np
from penaltyrun.problems.base import (BatchEvaluation, MatrixSpec, ParamsMixin, ReportInfo,
                                      check_spd)
from dataclasses import dataclass

CASES = ("only",)
DEFAULT_CASE = "only"
TARGET = np.array([[2.0, 0.5], [0.5, 1.0]])


@dataclass(frozen=True)
class Params(ParamsMixin):
    scale: float = 1.0


class Toy:
    name = "toy_user_report"
    scalars = ()

    def __init__(self, case, params):
        self.case, self.params = case, params
        self.matrices = (MatrixSpec("K", 2, (0.1, 5.0)),)

    def evaluate_batch(self, mats, scalars=None):
        K = np.asarray(mats["K"], float)
        cost = 1.0 + ((K - TARGET) ** 2).sum(axis=(1, 2))
        n = len(cost)
        return BatchEvaluation(cost, np.ones(n, bool), np.array(["converged"] * n, object))

    def evaluate(self, mats, scalars=None):
        b = self.evaluate_batch({"K": np.asarray(mats["K"])[None]})
        return {"cost": float(b.cost[0]), "converged": True, "status": "converged",
                "t_final": 1.0}

    def simulate(self, mats, scalars=None):
        K = check_spd("K", mats["K"], 2)
        t = np.linspace(0.0, 3.0, 50)
        x = np.exp(-np.trace(K) * t)
        return {"t": t, "x": x}


def make_problem(case, params):
    return Toy(case, Params.from_mapping(params))


def report_info(case, params):
    return ReportInfo(cost_name="energy drawn", cost_unit="W·h")


def report_plots(sims, case, params):
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    for label, sim in sims.items():
        ax.plot(sim["t"], sim["x"], label=label)
    ax.legend()
    return {"toy decay plot": fig}
'''


@pytest.fixture(scope="module")
def user_run(tmp_path_factory):
    root = tmp_path_factory.mktemp("user")
    (root / "toy_user_report_mod.py").write_text(textwrap.dedent(MODULE), encoding="utf-8")
    mp = pytest.MonkeyPatch()
    mp.syspath_prepend(str(root))
    problems.register("toy_user_report", "toy_user_report_mod")
    jobs = []
    for param in ("diagonal", "full"):
        jobs += runner.plan_jobs("toy_user_report", "only", param, "pso", n_starts=3, root_seed=7,
                                 optimizer_options={"n_particles": 6, "iters": 5},
                                 problem_module="toy_user_report_mod")
    runner.execute(jobs, root / "run")
    io.collect(root / "run")
    yield root
    mp.undo()


def test_user_problem_unit_plot_and_html(user_run, tmp_path):
    problems.register("toy_user_report", "toy_user_report_mod")
    out = build_report(user_run / "run", tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    assert text.index("## Verdict") < text.index("## toy_user_report / only")
    assert "energy drawn (W·h)" in text
    figure = re.search(r"!\[toy decay plot\]\((toy_user_report_only_toy_decay_plot_"
                       r"[0-9a-f]{10}\.png)\)", text)
    assert figure and (out / figure.group(1)).stat().st_size > 0
    for line in text.splitlines():  # no table wider than 10 columns
        if line.startswith("|"):
            assert line.count("|") - 1 <= 10, line
    page = (out / "report.html").read_text(encoding="utf-8")
    assert "data:image/png;base64," in page
    assert not re.search(r"(src|href)=\"(https?:)?//", page)  # nothing fetched
    assert not re.search(r"<img[^>]+src=\"(?!data:)", page)  # every figure embedded
    assert page.index("Verdict") < page.index("Methods and conventions")


def test_report_without_the_user_module(user_run, tmp_path):
    problems.register("toy_user_report", "no_such_module_for_this_report")
    try:
        out = build_report(user_run / "run", tmp_path / "report")
    finally:
        problems.register("toy_user_report", "toy_user_report_mod")
    text = (out / "report.md").read_text(encoding="utf-8")
    warnings = [line for line in text.splitlines() if "cannot be imported" in line]
    assert len(warnings) == 1
    assert "unresolved" not in text and "ConfigError" not in "".join(
        p.name for p in out.iterdir())
    assert "## toy_user_report / only" in text  # cells come from the Parquet alone


def test_paper_tables_list_every_optimizer():
    """pso_matlab (and any future optimizer) gets its own Table 1–2 layout."""
    jobs = [{"case": case, "variant": "", "optimizer": opt, "status": "ok", "converged": True,
             "family": fam, "param": fam, "start": k, "best_cost": 0.1 + k}
            for opt in ("pso", "pso_matlab") for case in ("detumble", "rest_to_rest")
            for fam in ("diagonal", "full") for k in range(2)]
    titles = [s.title for s in paper_tables("attitude_lqr", jobs)]
    assert titles == ["Table 1 — attitude LQR layout (pso)",
                      "Table 1 — attitude LQR layout (pso_matlab)"]


def test_cost_constants_are_enough_to_declare_a_unit():
    import types

    from penaltyrun.problems.report_hooks import info

    mod = types.SimpleNamespace(COST_LABEL="Δv = Σ Tₛ‖u_k‖₂ (m/s)", COST_UNIT="m/s")
    assert info(mod, "c", {}).cost_label == "Δv = Σ Tₛ‖u_k‖₂ (m/s)"
    assert info(mod, "c", {}).cost_unit == "m/s"
    assert info(types.SimpleNamespace(), "c", {}).cost_label == "cost (unit not declared)"
