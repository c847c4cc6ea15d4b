"""Trade-off fronts: non-dominated sets and hypervolumes against brute-force references, and
the fronts, tests and held-out fronts the report builds from a sweep of ρ."""

import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.io import read_results
from penaltyrun.io.schema import RESULTS_FILE, to_table
from penaltyrun.report import build, fronts, fronts_section
from penaltyrun.report.stats import add_variant

points_2d = st.lists(st.tuples(st.floats(0.0, 10.0), st.floats(0.0, 10.0)), min_size=0,
                     max_size=12).map(lambda p: np.asarray(p, float).reshape(-1, 2))


def brute_nondominated(p):
    keep = [i for i, a in enumerate(p)
            if not any(np.all(b <= a) and np.any(b < a) for b in p)]
    return np.unique(p[keep], axis=0) if keep else p[:0]


def brute_hypervolume(p, ref):
    """Area of the union of the boxes [p_i, ref] by inclusion–exclusion over the grid of
    every coordinate (each grid cell counted once if some box covers it)."""
    p = p[np.all(p < ref, axis=1)]
    if not len(p):
        return 0.0
    xs = np.unique(np.concatenate([p[:, 0], [ref[0]]]))
    ys = np.unique(np.concatenate([p[:, 1], [ref[1]]]))
    area = 0.0
    for x0, x1 in zip(xs[:-1], xs[1:]):
        for y0, y1 in zip(ys[:-1], ys[1:]):
            if np.any((p[:, 0] <= x0) & (p[:, 1] <= y0)):
                area += (x1 - x0) * (y1 - y0)
    return area


@settings(max_examples=50, deadline=None)
@given(points_2d)
def test_nondominated_matches_the_definition(p):
    got = fronts.nondominated(p)
    assert np.array_equal(np.unique(got, axis=0), brute_nondominated(p))
    assert np.all(np.diff(got[:, 0]) > 0)  # sorted by the first coordinate, no duplicates


@settings(max_examples=50, deadline=None)
@given(points_2d, st.tuples(st.floats(5.0, 12.0), st.floats(5.0, 12.0)))
def test_hypervolume_matches_a_brute_force_union_of_boxes(p, ref):
    ref = np.asarray(ref)
    want = brute_hypervolume(p, ref)
    assert fronts.hypervolume(p, ref) == pytest.approx(want, rel=1e-12, abs=1e-12)
    assert fronts.hypervolume(fronts.nondominated(p), ref) == pytest.approx(want, abs=1e-12)


def test_a_staircase_by_hand():
    front = np.array([[1.0, 3.0], [2.0, 2.0], [3.0, 1.0]])
    assert fronts.hypervolume(front, [4.0, 4.0]) == pytest.approx(6.0)
    assert fronts.hypervolume(front, [1.0, 1.0]) == 0.0
    assert fronts.dominated_share(front, np.array([[0.5, 2.5]])).tolist() == [True, False,
                                                                           False]


def test_the_reference_point_lies_beyond_every_point():
    logs = np.array([[0.0, 1.0], [2.0, 1.0]])
    ref = fronts.reference_point(logs)
    assert ref == pytest.approx([2.0 + fronts.REF_MARGIN * 2.0, 1.0 + fronts.REF_FLAT])


RHOS = (1e-4, 1e-3, 1e-2)


def _holdout(scale):
    return {"cost": [scale, 2 * scale, 3 * scale], "converged": [True] * 3,
            "scenario": ["a", "b", "c"], "horizon": 100.0, "training_horizon": 100.0}


def _rows(n=3):
    """Two maps × n starts × three ρ: E = c t⁻³ on both, the full map's c half the
    diagonal's (its front dominates everywhere), start k a little worse than start k − 1."""
    out = []
    for param, c in (("diagonal", 2e4), ("full", 1e4)):
        for k in range(n):
            for rho in RHOS:
                t = (3 * c / rho) ** 0.25 * (1 + 0.01 * k)
                e = c * (1 + 0.05 * k) / t ** 3
                out.append({
                    "job_id": f"{param}-{rho}-{k}", "problem": "zermelo", "case": "default",
                    "param": param, "optimizer": "cmaes", "start": k, "seed": k,
                    "status": "ok", "best_cost": e + rho * t, "best_converged": True,
                    "n_evals": 100, "max_evals": 100, "config_hash": f"h{rho}",
                    "metrics": {"criterion": "time_energy", "rho": rho, "energy": e,
                                "arrival_time": t},
                    "holdout": _holdout(e + rho * t), "matrices": {}, "scalars": {},
                    "problem_params": {"criterion": "time_energy", "rho": rho},
                    "optimizer_settings": {},
                    "config": "", "git_commit": "test"})
    return out


def _frame(tmp_path, rows):
    pq.write_table(to_table(rows, "run"), tmp_path / RESULTS_FILE)
    return add_variant(read_results(tmp_path / RESULTS_FILE))


def test_a_sweep_gives_per_start_fronts_and_a_test_per_full_map(tmp_path):
    tables = fronts.fronts_of(_frame(tmp_path, _rows(n=4)))
    hv = tables["fronts"]
    assert len(hv) == 8 and set(hv["param"]) == {"diagonal", "full"}
    assert (hv["n_swept"] == 3).all() and (hv["n_front"] == 3).all()
    assert (hv["hypervolume"] > 0).all()
    one = hv.iloc[0]
    front = np.array(json.loads(one["front"]))
    ref = np.log10([one["ref_energy"], one["ref_time"]])
    assert one["hypervolume"] == pytest.approx(brute_hypervolume(np.log10(front), ref))
    diag = hv[hv["param"] == "diagonal"]["hypervolume"].to_numpy()
    full = hv[hv["param"] == "full"]["hypervolume"].to_numpy()
    assert full.min() > diag.max()  # a dominating front has the larger hypervolume
    test = tables["fronts_tests"].iloc[0]
    assert (test["map_a"], test["map_b"], test["n_a"], test["n_b"]) == ("diagonal", "full",
                                                                        4, 4)
    assert test["a12_b_beats_a"] == 1.0 and test["equal_budget"]
    assert test["dominated_a"] == 1.0 and test["dominated_b"] == 0.0
    assert "underpowered" in test["note"]
    assert test["words"] == "full front larger (hypervolume)"  # n = 4: p = 0.029, one test
    held = tables["fronts_holdout"]
    assert len(held) == 6 and set(held["rho"]) == set(RHOS)
    assert (held.loc[held["param"] == "full", "dominated"] == 0).all()


def test_a_start_without_a_converged_point_has_hypervolume_zero(tmp_path):
    rows = _rows()
    for r in rows:
        if r["param"] == "full" and r["start"] == 0:
            r["best_converged"] = False
    hv = fronts.fronts_of(_frame(tmp_path, rows))["fronts"]
    first = hv[(hv["param"] == "full") & (hv["start"] == 0)].iloc[0]
    assert first["n_converged"] == 0 and first["hypervolume"] == 0.0


def test_no_sweep_no_fronts(tmp_path):
    rows = [r for r in _rows() if r["metrics"]["rho"] == RHOS[0]]
    tables = fronts.fronts_of(_frame(tmp_path, rows))
    assert all(t.empty for t in tables.values())
    assert fronts_section.section(tables, tables["fronts"], tmp_path) == []


def test_the_section_names_the_family_and_draws_one_figure(tmp_path):
    df = _frame(tmp_path, _rows(n=3))
    from penaltyrun.report.compare import pairwise
    tables = fronts.fronts_of(df)
    lines = "\n".join(fronts_section.section(tables, pairwise(df), tmp_path))
    assert "## Trade-off fronts" in lines and fronts.FAMILY in lines
    assert "supported points" in lines  # the weighted-sum caveat
    assert "pooled full front dominates 100 % of the pooled diagonal front" in lines
    assert len(list(tmp_path.glob("fronts_*.png"))) == 1
    assert {"fronts", "fronts_tests", "fronts_holdout"} <= set(build.TABLES)


@pytest.mark.slow  # a whole report
def test_the_report_writes_the_fronts_tables_and_section(tmp_path):
    folder = tmp_path / "received"
    folder.mkdir()
    pq.write_table(to_table(_rows(n=3), "run"), folder / RESULTS_FILE)
    out = build.build_report(folder, tmp_path / "report", basin_points=0)
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "## Trade-off fronts" in text
    for stem in ("fronts", "fronts_tests", "fronts_holdout"):
        assert (out / f"{stem}.csv").is_file()
    assert len(list(out.glob("fronts_*.png"))) == 1
