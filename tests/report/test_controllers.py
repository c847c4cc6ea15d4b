"""The tuned-controller section of the report (penaltyrun/report/controllers.py) on a tiny
real Zermelo run whose box is forced so that the best matrices sit at a bound, the stored
closed-loop columns against the closed loop built here, older results without them, and
the warnings and figures on hand-made input."""

import numpy as np
import pandas as pd
import pytest

from penaltyrun import io, problems, runner
from penaltyrun.io import decode_json, read_results
from penaltyrun.report import build_report, controllers
from penaltyrun.report.controller_plots import channel_figure, pole_map
from penaltyrun.report.stats import add_variant

#: The Zermelo optimum has eigenvalues below 2 (the paper's: 0.16–2.3), so a box [2, 10]
#: forces the best diagonal entries onto the lower bound.
FORCED = {"eig_bounds": [2.0, 10.0]}
SMALL_HOLDOUT = {"holdout_radii": [2.0], "holdout_n_angles": 2}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("controllers")
    jobs = []
    for param in ("diagonal", "full"):
        jobs += runner.plan_jobs("zermelo", "default", param, "pso", n_starts=2, root_seed=7,
                                 problem_params=SMALL_HOLDOUT, param_options=FORCED,
                                 optimizer_options={"n_particles": 6, "iters": 5, "max_evals": 30})
    runner.execute(jobs, root / "run")
    return io.collect(root / "run")


@pytest.fixture(scope="module")
def report(run, tmp_path_factory):
    return build_report(run, tmp_path_factory.mktemp("report") / "report")


def test_stored_diagnostics_equal_numpy_eig_of_the_closed_loop(run):
    df = read_results(run)
    assert len(df) == 4 and (df["status"] == "ok").all()
    for _, row in df.iterrows():
        K = np.asarray(decode_json(row["matrices"])["K"])
        eig = np.linalg.eig(-K.T)[0]
        np.testing.assert_allclose(np.sort(row["cl_eig_real"]), np.sort(eig.real), rtol=1e-12)
        np.testing.assert_allclose(row["cl_eig_imag"], 0.0, atol=1e-12)
        assert row["cl_slowest_real"] == pytest.approx(eig.real.max(), rel=1e-12)
        assert row["cl_min_damping"] == pytest.approx(1.0)
        assert row["cl_gain_norm"] == pytest.approx(np.linalg.norm(K, 2), rel=1e-12)
        assert row["cl_gain_cond"] == pytest.approx(np.linalg.cond(K), rel=1e-10)
        loop = decode_json(row["closed_loop"])
        assert loop["time"] == "continuous" and loop["state_names"] == ["x", "y"]


def test_report_section_shows_matrices_gain_poles_channels_and_bound_warning(report):
    text = (report / "report.md").read_text(encoding="utf-8")
    section = text[text.index("### Tuned controllers"):]
    section = section[:section.index("\n## ")]
    for needle in ("| map | by | cost | time | slowest Re s | min damping | ‖K‖₂ | cond K |",
                   "<details><summary>best diagonal (pso s", "K =\n```", "gain =\n```",
                   "<details><summary>best full (pso s", "matrices and gain</summary>",
                   "Closed-loop poles s (1 / time unit, slowest first): -",
                   "![closed-loop poles](controller_zermelo_default_poles.png)",
                   "![channels](controller_zermelo_default_channels.png)",
                   "at its lower bound 2 (box [2, 10])",
                   "within 1 % of the box width (and in log scale for a box spanning 10× or "
                   "more); the box may be too small."):
        assert needle in section, needle
    assert "K.lam1 = 2" in section  # the forced diagonal entry, named as the layout names it
    assert "![cost against the slowest mode](controller_zermelo_default_cost_vs_mode.png)" \
        in section
    for name in ("controller_zermelo_default_poles.png", "controller_zermelo_default_channels.png",
                 "controller_zermelo_default_cost_vs_mode.png"):
        assert (report / name).stat().st_size > 0
    page = (report / "report.html").read_text(encoding="utf-8")
    assert "<details><summary>best full (pso s" in page and "</details>" in page
    assert page.count("<pre>") == section.count("```") // 2
    table = pd.read_csv(report / "controllers.csv")
    assert list(table["map"]) == ["diagonal", "full"]
    # the lower eigenvalue bound 2, to the round-off of K = Q diag(λ) Qᵀ
    assert (table["poles_from"] == "stored").all()
    assert (table["slowest_real"] <= -2.0 * (1 - 1e-12)).all()
    for line in text.splitlines():  # every table of the report stays readable
        if line.startswith("|---"):
            assert line.count("|") - 1 <= 10


def test_older_results_get_the_diagnostics_from_the_stored_matrices(run):
    df = add_variant(read_results(run))
    new = controllers.controller_rows(df)
    old = df.copy()
    for name in ("closed_loop", "cl_eig_real", "cl_eig_imag", "cl_slowest_real"):
        old[name] = None
    again = controllers.controller_rows(old)
    assert set(again["poles from"]) == {"recomputed from the stored matrices"}
    np.testing.assert_allclose(again["slowest"], new["slowest"], rtol=1e-12)


def test_start_modes_from_the_stored_column_or_the_stored_matrices(run):
    df = add_variant(read_results(run))
    stored = controllers.start_modes(df)
    assert len(stored) == 4
    np.testing.assert_allclose(stored["slowest"], df["cl_slowest_real"], rtol=1e-12)
    old = df.assign(cl_slowest_real=np.nan, closed_loop=None)
    np.testing.assert_allclose(controllers.start_modes(old)["slowest"], stored["slowest"],
                               rtol=1e-12)


def test_mode_lines_give_spearman_per_map():
    modes = pd.DataFrame({"param": ["full"] * 4 + ["diagonal"] * 2,
                          "cost": [1.0, 2.0, 3.0, 4.0, 1.0, 2.0],
                          "slowest": [-0.01, -0.02, -0.03, -0.05, -0.1, -0.2]})
    (line, _) = controllers.mode_lines(modes)
    assert line.endswith(": full 1 (n = 4).")  # diagonal: fewer than 3 starts
    assert controllers.mode_lines(modes[modes["param"] == "diagonal"]) == []


def test_bound_warning_within_one_percent_of_the_box_width(run):
    df = add_variant(read_results(run))
    row = df[df["param"] == "full"].iloc[0].copy()
    z = np.array(row["best_z"], float)
    z[:2] = [2.0 + 0.005 * 8.0, 6.0]  # 0.5 % of the width above the lower bound; inside
    row["best_z"] = z.copy()
    lines = controllers.bound_warnings(row)
    assert len([w for w in lines if "K.lam1" in w and "lower bound 2" in w]) == 1
    assert not any("K.lam2" in w for w in lines)
    z[0] = 2.0 + 0.02 * 8.0  # 2 % of the width: not at the bound
    row["best_z"] = z.copy()
    assert not any("K.lam1" in w for w in controllers.bound_warnings(row))


def test_bound_warning_in_log_scale_for_an_eigenvalue_box_over_decades(run):
    df = add_variant(read_results(run))
    row = df[df["param"] == "diagonal"].iloc[0].copy()
    row["param_options"] = '{"eig_bounds": [0.001, 10.0]}'
    row["best_z"] = np.array([0.0036, 9.95])  # 3.6× the lower bound; 0.5 ‰ below the upper
    lines = controllers.bound_warnings(row)
    assert len(lines) == 1 and "K.lam2 = 9.95 at its upper bound 10" in lines[0]
    assert "K.lam1" not in lines[0]
    row["best_z"] = np.array([0.00109, 5.0])  # log distance 0.086 < 1 % of log(1e4) = 0.092
    assert "K.lam1 = 0.00109 at its lower bound 0.001" in controllers.bound_warnings(row)[0]
    row["param_options"] = '{"eig_bounds": [1e-8, 100.0]}'
    row["best_z"] = np.array([1.1e-8, 86.0])  # 86 is 14 % of the width below 100: not at it
    lines = controllers.bound_warnings(row)
    assert len(lines) == 1 and "K.lam1 = 1.1e-08 at its lower bound 1e-08" in lines[0]
    assert "K.lam2" not in lines[0]


def test_no_bound_warning_for_a_full_turn_angle(run):
    df = add_variant(read_results(run))
    row = df[df["param"] == "full"].iloc[0].copy()
    z = np.array(row["best_z"], float)
    z[:2] = [5.0, 6.0]
    for name, lo in (("givens", -np.pi), ("cayley_tan", -1.5608)):
        row["param"] = name
        z[2] = lo + 1e-4
        row["best_z"] = z.copy()
        lines = controllers.bound_warnings(row)
        assert bool(lines) == (name == "cayley_tan"), (name, lines)


def test_mode_warnings():
    table = pd.DataFrame({"param": ["diagonal", "geagsp", "cayley", "givens"],
                          "slowest": [-0.06, -0.0055, -0.03, 0.001]})
    lines = controllers.mode_warnings(table)
    assert len(lines) == 2
    assert "best givens: its closed loop is not asymptotically stable" in lines[0]
    assert "best geagsp" in lines[1] and "10.9× slower than the best diagonal's" in lines[1]
    assert controllers.mode_warnings(table[table["param"] != "diagonal"]) == [lines[0]]


def test_pole_line_lists_each_conjugate_pair_once():
    from penaltyrun.problems.base import ClosedLoop

    wn, zeta = 2.0, 0.3
    A = np.zeros((3, 3))
    A[:2, :2] = [[0.0, 1.0], [-wn ** 2, -2 * zeta * wn]]
    A[2, 2] = -0.05
    line = controllers.pole_line(ClosedLoop(A))
    assert line == ("Closed-loop poles s (1 / time unit, slowest first): -0.05, "
                    "-0.6 ± 1.908j.")
    line = controllers.pole_line(ClosedLoop(np.diag([0.5, 0.9]), "discrete", dt=2.0))
    assert line.endswith("As z (sample time 2): 0.9, 0.5.")
    assert "-0.05268, -0.3466" in line


def test_matrix_block_is_aligned_and_rounded():
    lines = controllers.matrix_block("gain", [[1.234567, -0.5], [1e-7, 20.0]], ("u1", "u2"),
                                     ("x", "y"))
    assert lines[:2] == ["gain =", "```"] and lines[-2:] == ["```", ""]
    body = lines[2:-2]
    assert body[1].split() == ["u1", "1.235", "-0.5"]
    assert len({len(b) for b in body}) == 1


def test_figures_on_hand_made_input(tmp_path):
    assert pole_map({"diagonal": np.array([-1.0, -2.0 + 1j, -2.0 - 1j]),
                     "full": np.array([-0.01 + 0.2j, -0.01 - 0.2j, -3.0])}, "poles",
                    tmp_path / "p.png").stat().st_size > 0
    assert pole_map({"diagonal": np.array([])}, "none", tmp_path / "q.png") is None
    t = np.linspace(0.0, 1.0, 20)
    sim = {"t": t, "u": np.column_stack([np.sin(t), np.cos(t)]), "x": np.ones((3, 20, 2)),
           "channels": {"u": ["u1", "u2"]}, "limits": {"u": (-0.8, 0.8)}}
    assert channel_figure({"diagonal": sim, "full": sim}, "channels",
                          tmp_path / "c.png").stat().st_size > 0
    assert channel_figure({"diagonal": {"t": t}}, "none", tmp_path / "d.png") is None


def test_lqr_simulate_declares_channels_and_input_limits():
    prob = problems.make("lqr", "default", {"u_max": 0.8})
    sim = prob.simulate({m.name: np.eye(m.size) for m in prob.matrices}, n_points=50)
    n, m = prob.plant.n_states, prob.plant.n_inputs
    assert sim["channels"] == {"x": [f"x{i + 1}" for i in range(n)],
                               "u": [f"u{i + 1}" for i in range(m)]}
    lo, hi = sim["limits"]["u"]
    np.testing.assert_array_equal(hi, np.full(m, 0.8))
    np.testing.assert_array_equal(lo, -hi)
    assert np.all(np.abs(sim["u"]) <= 0.8 + 1e-12)
