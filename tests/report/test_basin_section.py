"""The report's basin-of-attraction section: the best diagonal and full starts side by
side, for problems that name a plane of initial conditions, and nothing for the others."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from penaltyrun.io import read_results
from penaltyrun.io.schema import RESULTS_FILE, to_table
from penaltyrun.report import basins, build_report
from penaltyrun.report.stats import add_variant

K_DIAG = [[0.85, 0.0], [0.0, 0.19]]
K_FULL = [[1.7421, 0.9560], [0.9560, 1.1414]]


def _rows(problem="zermelo", case="default"):
    out = []
    for param, K in (("diagonal", K_DIAG), ("full", K_FULL)):
        for k in range(3):
            scale = 1.0 + 0.1 * k
            out.append({"job_id": f"{param}-{k}", "problem": problem, "case": case,
                        "param": param, "optimizer": "cmaes", "start": k, "seed": k,
                        "status": "ok", "best_cost": 20.0 + k + (param == "full"),
                        "best_converged": True, "n_evals": 10, "config_hash": "h",
                        "matrices": {"K": (np.asarray(K) * scale).tolist()}, "scalars": {},
                        "metrics": {}, "problem_params": {}, "optimizer_settings": {},
                        "config": "", "git_commit": "test"})
    return out


@pytest.mark.slow  # about 10 s: a whole report with its figures
def test_zermelo_report_shows_the_basins_of_both_maps(tmp_path):
    folder = tmp_path / "received"
    folder.mkdir()
    pq.write_table(to_table(_rows(), "run"), folder / RESULTS_FILE)
    out = build_report(folder, tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    section = text.split("### Basins of attraction", 1)[1].split("\n### ", 1)[0]
    n = basins.REPORT_POINTS ** 2
    assert f"| diagonal | cmaes/diagonal | {n}/{n} |" in section
    assert f"| full | cmaes/full | {n}/{n} |" in section
    assert "![basins of attraction](basins_zermelo_default.png)" in section
    assert (out / "basins_zermelo_default.png").stat().st_size > 10_000


def _frame(tmp_path, rows):
    pq.write_table(to_table(rows, "run"), tmp_path / RESULTS_FILE)
    return add_variant(read_results(tmp_path / RESULTS_FILE))


def test_the_table_uses_the_best_start_and_counts_grid_points(tmp_path):
    maps = basins.maps_of(_frame(tmp_path, _rows()), n=3)
    assert list(maps) == ["diagonal", "full"]
    row, _ = maps["full"]
    assert row["job_id"] == "full-0"  # the lowest cost of the map
    assert np.allclose(json.loads(row["matrices"])["K"], K_FULL)
    tab = basins.table(maps)
    assert tab["starts converged"].tolist() == ["9/9", "9/9"]
    assert tab.columns.tolist() == basins.COLUMNS


def test_a_problem_without_a_plane_has_no_section(tmp_path):
    frame = _frame(tmp_path, _rows(problem="no_such_problem"))
    assert basins.section(frame, tmp_path, "x") == []


def test_basin_points_on_the_command_line(tmp_path, capsys):
    """``--basin-points 0`` leaves the maps out; a bad value is one line, exit 2; the help
    states the default of the code."""
    from penaltyrun.cli import report_main

    folder = tmp_path / "received"
    folder.mkdir()
    pq.write_table(to_table(_rows(), "run"), folder / RESULTS_FILE)
    with pytest.raises(SystemExit) as exc:
        report_main([str(folder), "--basin-points", "1"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--basin-points" in err[0] and "2 to 200" in err[0]
    for bad in (["--basin-points", "1.5"], ["--progress", "maybe"], ["--bogus"]):
        with pytest.raises(SystemExit) as exc:  # argparse's own refusals: one line too
            report_main([str(folder), *bad])
        assert exc.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("penaltyrun-report: error: ")
    report_main([str(folder), "-o", str(tmp_path / "rep"), "--basin-points", "0"])
    assert "Basins of attraction" not in (tmp_path / "rep" / "report.md").read_text()
    with pytest.raises(SystemExit):
        report_main(["--help"])
    assert f"(default {basins.REPORT_POINTS};" in " ".join(capsys.readouterr().out.split())


def test_a_region_estimate_adds_its_column_and_its_contour(tmp_path):
    """A problem's region estimate (e.g. a Lyapunov sub-level set): the table counts the grid
    points inside it that converged, the text names it, the figure draws it."""
    from penaltyrun.problems.basins import BasinAxes, BasinMap

    axes = BasinAxes(("a", "b"), (-1.0, -1.0), (1.0, 1.0))
    x = y = np.linspace(-1.0, 1.0, 4)
    conv = np.ones((4, 4), bool)
    conv[0, 0] = False
    inside = np.zeros((4, 4), bool)
    inside[1:3, 1:3] = True
    inside[0, 0] = True
    region = {"inside": inside, "level": 2.5, "certified": 1e-6, "label": "set {V ≤ c}"}
    bm = BasinMap(axes, x, y, conv, np.ones((4, 4)), np.ones((4, 4)), 10.0, region)
    assert bm.region_check() == (4, 5)
    row = {"optimizer": "cmaes", "param": "diagonal"}
    maps = {"diagonal": (row, bm)}
    tab = basins.table(maps)
    assert tab.columns.tolist() == [*basins.COLUMNS, basins.REGION_COLUMN]
    assert tab[basins.REGION_COLUMN].tolist() == ["4/5"]
    assert "set {V ≤ c}" in "\n".join(basins._region_lines(maps))
    assert basins.figure(maps, "t", tmp_path / "b.png").stat().st_size > 5_000
