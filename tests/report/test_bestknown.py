"""Best-known optima: converged starts only, certification rules, shortfall."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from penaltyrun.report.bestknown import (
    best_known,
    family,
    reference,
    shortfall,
    within,
)


def job(param, optimizer, cost, status="ok", variant="", job_id=None, pv=""):
    return {"problem": "toy", "case": "c1", "problem_variant": pv, "variant": variant,
            "param": param, "optimizer": optimizer, "best_cost": cost, "status": status,
            "best_converged": status == "ok", "job_id": job_id or f"{param}-{optimizer}-{cost}",
            "matrices": json.dumps({"K": [[cost, 0.0], [0.0, 1.0]]})}


def bk_row(bk, fam, pv=""):
    sel = bk[(bk["family"] == fam) & (bk["problem_variant"] == pv)]
    assert len(sel) == 1
    return sel.iloc[0]


def test_family_and_within():
    assert family("diagonal") == "diagonal"
    assert {family(m) for m in ("full", "geagsp", "givens", "cayley")} == {"full"}
    assert within(1.0001, 1.0) and not within(1.00011, 1.0)
    assert within(-1.0001, -1.0)  # relative to |ref|


def test_best_known_takes_converged_non_baseline_starts_of_every_full_map():
    df = pd.DataFrame([
        job("diagonal", "pso", 5.0), job("diagonal", "de", 4.0),
        job("diagonal", "pso", 0.1, status="diverged"),  # not a cost
        job("diagonal", "baseline", 3.0),  # K = I is not a search
        job("geagsp", "pso", 2.0), job("givens", "de", 1.5, job_id="the-best"),
        job("cayley", "cmaes", 1.6),
    ])
    bk = best_known(df)
    d, f = bk_row(bk, "diagonal"), bk_row(bk, "full")
    assert (d["best_known"], d["optimizer"], d["n_converged"]) == (4.0, "de", 2)
    assert (f["best_known"], f["param"], f["job_id"]) == (1.5, "givens", "the-best")
    assert json.loads(f["matrices"]) == {"K": [[1.5, 0.0], [0.0, 1.0]]}
    assert (d["best_pso"], d["best_de"]) == (5.0, 4.0)
    assert not d["certified"] and not f["certified"]  # 4.0 vs 5.0, 1.5 vs 1.6: no agreement
    assert reference(bk, "toy", "c1", "", "full") == 1.5


@pytest.mark.parametrize("costs, level, by, evidence", [
    ({"grid": 4.0}, "certified", "grid", "certified (grid + local search)"),
    ({"pso": 4.0, "grid": 4.0003}, "certified", "pso",  # the grid is 7.5e-5 above: reached
     "certified (grid + local search)"),
    ({"pso": 4.0, "de": 4.0 * (1 + 0.9e-4)}, "agreement", "pso, de",  # two optimizers agree
     "agreement (2 optimizers; reached by 3 of 3 starts)"),
    ({"pso": 4.0, "de": 4.0 * (1 + 2e-4)}, "single optimizer", "—",  # too far apart
     "single optimizer (pso; reached by 2 of 3 starts)"),
    ({"pso": 4.0}, "single optimizer", "—",  # one optimizer, however many starts
     "single optimizer (pso; reached by 2 of 2 starts)"),
    ({"grid": 4.002, "pso": 4.0}, "single optimizer", "—",  # the grid did not reach it
     "single optimizer (pso; reached by 2 of 3 starts)"),
])
def test_evidence_levels(costs, level, by, evidence):
    """Certified only by the grid; two optimizers that agree are *agreement*, not
    certified."""
    data = [job("diagonal", o, c) for o, c in costs.items()]
    data += [job("diagonal", "pso", 4.0, job_id="second-pso-start")]
    row = bk_row(best_known(pd.DataFrame(data)), "diagonal")
    assert row["level"] == level and row["evidence"] == evidence
    assert row["certified"] == (level == "certified")
    if level != "single optimizer":
        assert set(row["certified_by"].split(" (")[0].split(", ")) >= set(by.split(", "))
    else:
        assert row["certified_by"] == "—"


def test_problem_variants_have_their_own_best_known_but_budgets_do_not():
    df = pd.DataFrame([job("diagonal", "pso", 4.0, variant="max_evals=300"),
                       job("diagonal", "pso", 5.0),
                       job("diagonal", "pso", 9.0, pv="t_max=500", variant="t_max=500")])
    bk = best_known(df)
    assert bk_row(bk, "diagonal")["best_known"] == 4.0
    assert bk_row(bk, "diagonal", "t_max=500")["best_known"] == 9.0


def test_shortfall_is_the_gap_to_the_family_best_known():
    df = pd.DataFrame([job("diagonal", "grid", 4.0), job("diagonal", "pso", 5.0),
                       job("diagonal", "pso", 6.0), job("diagonal", "pso", 1.0, "diverged"),
                       job("geagsp", "pso", 3.0)])
    gaps = shortfall(df, best_known(df)).set_index(["optimizer", "param"])
    pso = gaps.loc[("pso", "diagonal")]
    assert (pso["n_jobs"], pso["n_converged"]) == (3, 2)
    assert pso["gap_best_pct"] == pytest.approx(25.0)
    assert pso["gap_median_pct"] == pytest.approx(37.5)
    assert not pso["reached_best_known"]
    assert gaps.loc[("grid", "diagonal"), "gap_best_pct"] == 0.0
    assert gaps.loc[("pso", "geagsp"), "best_known"] == 3.0  # the full family's value


@pytest.mark.parametrize(("grad_norm", "level", "words"), [
    (1e-9, "first-order certified local optimum", "first-order certified local optimum (lbfgs"),
    (1e-3, "single optimizer", "single optimizer (lbfgs"),
    (float("nan"), "single optimizer", "single optimizer (lbfgs"),
    (None, "single optimizer", "single optimizer (lbfgs"),
])
def test_first_order_certificate_from_the_projected_gradient(grad_norm, level, words):
    rows = [{**job("givens", "lbfgs", 2.0), "grad_norm": grad_norm},
            {**job("givens", "cmaes", 2.5), "grad_norm": 1e-12}]  # not the best: no say
    f = bk_row(best_known(pd.DataFrame(rows)), "full")
    assert f["level"] == level and f["evidence"].startswith(words)


def test_agreement_notes_a_first_order_certificate():
    rows = [{**job("givens", "lbfgs", 2.0), "grad_norm": 1e-10},
            {**job("givens", "cmaes", 2.00001), "grad_norm": None}]
    f = bk_row(best_known(pd.DataFrame(rows)), "full")
    assert f["level"] == "agreement" and "first-order certified" in f["evidence"]


def _best_rows_by_copy(df: pd.DataFrame) -> dict[str, pd.Series]:
    """The former best_rows: a copy of the converged rows grouped by family (reference)."""
    from penaltyrun.report.stats import converged

    ok = df[converged(df) & (df["optimizer"] != "baseline")]
    return {str(fam): g.loc[g["best_cost"].astype(float).idxmin()]
            for fam, g in ok.groupby(ok["param"].map(family))}


PARAMS = ["diagonal", "full", "geagsp", "givens"]


@given(st.lists(st.tuples(st.sampled_from(PARAMS), st.sampled_from(["pso", "baseline"]),
                          st.sampled_from([1.0, 2.0, 3.0]), st.sampled_from(["ok", "failed"]),
                          st.sampled_from(["", "v2"])), max_size=25),
       st.booleans())
def test_best_rows_and_best_labels_equal_the_copying_reference(rows, categorical):
    from penaltyrun.report.bestknown import best_labels, best_rows

    df = pd.DataFrame([job(p, o, c, s, job_id=f"j{k}", pv=pv)
                       for k, (p, o, c, s, pv) in enumerate(rows)],
                      columns=list(job("diagonal", "pso", 1.0)))
    df.index = df.index * 3 + 5  # labels that are not positions
    if categorical:
        df["param"] = df["param"].astype("category")
    got, want = best_rows(df), _best_rows_by_copy(df)
    assert list(got) == list(want)
    for fam in want:
        pd.testing.assert_series_equal(got[fam], want[fam])
    by_group = best_labels(df, ("problem", "case", "problem_variant"))
    for (_, _, pv), labels in by_group.items():
        ref = _best_rows_by_copy(df[df["problem_variant"] == pv])
        assert labels == {fam: row.name for fam, row in ref.items()}
    assert len(by_group) == sum(bool(_best_rows_by_copy(df[df["problem_variant"] == pv]))
                                for pv in df["problem_variant"].unique())
