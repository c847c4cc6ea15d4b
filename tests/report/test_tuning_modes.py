"""Multi- vs single-scenario tuning in the report, on a synthetic Parquet file."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from penaltyrun import io
from penaltyrun.io.schema import write_table_atomic
from penaltyrun.report import tuning

LABELS = [f"s{k}" for k in range(12)]
DIAG = np.linspace(10.0, 21.0, 12)
#: single-scenario full: better on 9 of 12 (by 10 %), worse on 3 (by 5 %)
FULL_SINGLE = np.where(np.arange(12) < 9, 0.9 * DIAG, 1.05 * DIAG)
#: multi-scenario full: better on 4 of 12 (by 2 %), worse on 8 (by 1 %)
FULL_MULTI = np.where(np.arange(12) < 4, 0.98 * DIAG, 1.01 * DIAG)
MULTI = {"train_scenarios": [{"attitude": [30.0, 20.0, 40.0]},
                             {"attitude": [-45.0, 35.0, 120.0]}], "train_aggregate": "mean"}
BUDGET = {"max_evals": 3000, "sigma0": 0.3}


def job(param, cost, held, params, start=0, optimizer="cmaes", settings=BUDGET):
    return {"job_id": f"j-{param}-{optimizer}-{len(params)}-{start}",
            "problem": "attitude_lyapunov", "case": "rest_to_rest", "param": param,
            "optimizer": optimizer, "start": start, "status": "ok", "best_cost": cost,
            "best_converged": True, "problem_params": params,
            "optimizer_settings": settings, "max_evals": settings["max_evals"],
            "holdout": {"scenario": LABELS, "cost": list(held),
                        "converged": [True] * 12}}


def synthetic(tmp_path):
    records = [job("diagonal", 1.0, DIAG, {}), job("geagsp", 0.9, FULL_SINGLE, {}),
               # a worse diagonal start: the best start (cost 1.0) is the one paired
               job("diagonal", 2.0, DIAG * 0.5, {}, start=1),
               job("diagonal", 1.2, DIAG, MULTI), job("geagsp", 1.1, FULL_MULTI, MULTI),
               # another budget: single-scenario only, so no comparison row
               job("diagonal", 1.0, DIAG, {}, settings={"max_evals": 100, "sigma0": 0.3}),
               job("geagsp", 1.0, DIAG, {}, settings={"max_evals": 100, "sigma0": 0.3}),
               # multi-scenario only (other optimizer): no comparison row either
               job("diagonal", 1.0, DIAG, MULTI, optimizer="pso_budget"),
               job("geagsp", 1.0, DIAG, MULTI, optimizer="pso_budget")]
    path = tmp_path / "results.parquet"
    write_table_atomic(io.to_table(records, run_id="synthetic"), path)
    return io.read_results(path)


def test_mode_labels():
    assert tuning.mode_label(tuning.training_of('{"t_max": 80}')) == "single"
    assert tuning.mode_label(tuning.training_of(MULTI)) == "multi (mean of 2)"
    assert tuning.mode_label(tuning.training_of(
        {"train_sample": 3, "train_aggregate": "max"})) == "multi (max of 3)"
    assert tuning.mode_label(tuning.training_of(
        {"train_scenarios": [{}], "train_sample": 2})) == "multi (mean of 3)"
    assert tuning.training_of(None) == {}


def test_side_by_side_matches_hand_computation(tmp_path):
    table = tuning.comparison(synthetic(tmp_path))
    assert len(table) == 1
    row = table.iloc[0]
    assert (row["optimizer"], row["full_map"], row["max_evals"]) == ("cmaes", "geagsp", 3000)
    assert row["single: pairs"] == 12 and row["multi (mean of 2): pairs"] == 12
    assert row["single: full better"] == pytest.approx(9 / 12)
    assert row["single: median impr. %"] == pytest.approx(10.0)
    assert row["single: Wilcoxon p"] == pytest.approx(stats.wilcoxon(DIAG, FULL_SINGLE).pvalue)
    assert row["multi (mean of 2): full better"] == pytest.approx(4 / 12)
    assert row["multi (mean of 2): median impr. %"] == pytest.approx(-1.0)
    assert row["multi (mean of 2): Wilcoxon p"] == pytest.approx(
        stats.wilcoxon(DIAG, FULL_MULTI).pvalue)
    columns = list(table.columns)
    assert columns.index("single: median impr. %") < columns.index(
        "multi (mean of 2): median impr. %")


def test_section_and_csv(tmp_path):
    df = synthetic(tmp_path)
    out = tmp_path / "report"
    out.mkdir()
    lines = tuning.study_sections(df, out, paper=False)
    assert lines[0] == "## Held-out scenarios: multi-scenario vs single-scenario tuning"
    saved = pd.read_csv(out / "holdout_tuning_modes.csv")
    assert len(saved) == 1 and "multi (mean of 2): Wilcoxon p" in saved


def test_no_section_with_one_mode_only(tmp_path):
    df = synthetic(tmp_path)
    single = df[df["problem_params"].map(lambda p: "train" not in (p or ""))]
    assert tuning.comparison(single).empty
    assert tuning.study_sections(single, tmp_path, paper=False) == []


def test_two_training_sets_with_one_label_stay_apart(tmp_path):
    other = {**MULTI, "train_scenarios": [{"attitude": [1.0, 2.0, 3.0]},
                                          {"attitude": [4.0, 5.0, 6.0]}]}
    df = pd.DataFrame([job("diagonal", 1.0, DIAG, {}), job("diagonal", 1.0, DIAG, MULTI),
                       job("diagonal", 1.0, DIAG, other)])
    labels = set(tuning.with_modes(df)["tuning"])
    assert "single" in labels and len(labels) == 3
    assert all(lab.startswith("multi (mean of 2) #") for lab in labels - {"single"})


def test_setting_shows_the_variant_label_when_known(tmp_path):
    df = synthetic(tmp_path)
    assert tuning.comparison(df).iloc[0]["setting"] == "—"  # no variant column: params, none
    labelled = df.assign(variant="")
    assert tuning.comparison(labelled).iloc[0]["setting"] == "—"
    labelled = df.assign(variant="t_max=80.0")
    assert tuning.comparison(labelled).iloc[0]["setting"] == "t_max=80.0"
