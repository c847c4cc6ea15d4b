"""The verdict on hand-made results with known answers."""

from __future__ import annotations

import numpy as np
import pandas as pd

from penaltyrun.report.bestknown import best_known
from penaltyrun.report.compare import pairwise
from penaltyrun.report.holdout import holdout_rows
from penaltyrun.report.verdict import COLUMNS, stop_setting, verdict_rows

SCENARIOS = [f"s{k}" for k in range(12)]


def job(param, optimizer, cost, holdout=None, n_evals=100, max_evals=None, stop="iters"):
    return {"problem": "toy_handmade", "case": "c1", "variant": "", "problem_variant": "",
            "optimizer": optimizer, "param": param, "best_cost": cost, "status": "ok",
            "best_converged": True, "n_evals": n_evals, "max_evals": max_evals,
            "stop_reason": stop, "holdout": holdout, "matrices": '{"K": [[1.0]]}',
            "optimizer_settings": '{"iters": 10}', "problem_params": "{}",
            "job_id": f"{param}-{optimizer}-{cost}"}


def held(costs):
    return {"scenario": SCENARIOS, "cost": list(costs), "converged": [True] * len(costs)}


def frame(full_evals=100, diag_second=None):
    diag_h = held(np.full(12, 10.0))
    full_h = held([8.0, 8.0] + [20.0 + k for k in range(10)])  # worse on 10 of 12
    rows = [job("diagonal", "pso", 10.0 + 0.1 * k, diag_h if k == 0 else None)
            for k in range(10)]
    rows += [job("full", "pso", 9.0 + 0.1 * k, full_h if k == 0 else None, n_evals=full_evals)
             for k in range(10)]
    if diag_second:
        rows.append(job("diagonal", diag_second, 10.0))
    return pd.DataFrame(rows)


def verdict(df):
    bk = best_known(df)
    comp = pairwise(df)
    held_table, _ = holdout_rows(df)
    return verdict_rows(df, bk, comp, held_table).iloc[0]



def test_a_gain_tuned_on_several_scenarios_says_what_it_was_measured_on():
    """The optimizers minimized an aggregate over the training scenarios, not one
    scenario's cost: the sentence names that aggregate."""
    df = frame(diag_second="de").assign(
        problem_params='{"train_sample": 8, "train_seed": 7, "train_aggregate": "max"}')
    s = verdict(df)["sentence"]
    assert "on the training scenarios (max of 8) the best-known full cost is 10 % below" in s
    assert "the gain is specific to the training scenarios (max of 8)" in s
    assert "training scenario " not in s

def test_full_better_on_training_but_worse_held_out():
    row = verdict(frame(diag_second="de"))
    assert row["gain_pct"] == np.float64(10.0)
    assert row["diag_level"] == "agreement" and "agreement (2 optimizers" in \
        row["diagonal best-known"]
    assert "full cheaper on 2/12" in row["held-out"]
    assert "judged at the training deadline (record older" in row["held-out"]
    s = row["sentence"]
    assert "on the training scenario the best-known full cost is 10 % below the diagonal's" in s
    assert "but from the held-out scenarios full costs more (full cheaper on 2/12" in s
    assert "the gain is specific to the training scenario" in s
    assert "A12 = 1" in s and "equal budget" in s  # equal budgets: tested
    assert len(COLUMNS) <= 10


def test_unequal_budgets_give_no_test():
    df = frame(full_evals=300)
    comp = pairwise(df)
    assert not comp["equal_budget"].any() and comp["p_mwu"].isna().all()
    assert comp["note"].iloc[0] == "budgets differ: no test"
    row = verdict(df)
    assert row["equal budget"] == "pso: budgets differ: no test"
    assert "no equal-budget test (budgets differ)" in row["sentence"]
    assert "at equal budget" not in row["sentence"]
    maxed = frame()
    maxed.loc[maxed["param"] == "full", "max_evals"] = 500  # spent equal, budgets not
    assert not pairwise(maxed)["equal_budget"].any()


def test_certified_vs_agreement_vs_single_diagonal():
    assert verdict(frame(diag_second="grid"))["diag_level"] == "certified"
    assert "certified (grid + local search)" in verdict(frame(diag_second="grid"))[
        "diagonal best-known"]
    assert verdict(frame(diag_second="de"))["diag_level"] == "agreement"
    single = verdict(frame())
    assert single["diag_level"] == "single optimizer"
    assert "rests on a single optimizer" in single["sentence"]


def test_full_worse_names_the_setting_that_stopped_the_search():
    df = frame()
    df.loc[df["param"] == "full", "best_cost"] += 5.0
    s = verdict(df)["sentence"]
    assert "worse on the training scenario" in s and "optimizer shortfall" in s
    assert "the iteration limit (`optimizer.iters`) in 10 of 10 starts" in s
    assert stop_setting("iters", {"max_iterations": 5}) == \
        "the iteration limit (`optimizer.max_iterations`)"
    assert stop_setting("ftol+polish", {"ftol": 1e-6, "ftol_iter": 5}) == \
        "the stall rule (`optimizer.ftol`, `optimizer.ftol_iter`)"
    assert stop_setting("max_evals", {}) == "the evaluation budget (`optimizer.max_evals`)"


def test_every_equal_budget_test_is_stated_not_only_the_most_significant():
    df = frame()
    second = frame().assign(optimizer="de")
    second.loc[second["param"] == "full", "best_cost"] += 1.0  # the same costs under de
    second["job_id"] = "de-" + second["job_id"]
    s = verdict(pd.concat([df, second], ignore_index=True))["sentence"]
    assert "A12 = 0.5 (de, n = 10/10, Holm p = 1), 1 (pso, n = 10/10, Holm p" in s
    givens = df.assign(param=df["param"].replace({"full": "givens"}))
    givens["job_id"] = "g-" + givens["job_id"]
    s = verdict(pd.concat([df, givens[givens["param"] == "givens"]], ignore_index=True))[
        "sentence"]
    assert "A12 = 1 (pso, full, n = 10/10" in s and "1 (pso, givens, n = 10/10" in s


def test_polish_endings_do_not_split_the_search_stop():
    df = frame()
    df.loc[df["param"] == "full", "best_cost"] += 5.0
    full = df.index[df["param"] == "full"]
    df.loc[full[:3], "stop_reason"] = "iters+polish"
    df.loc[full[3:5], "stop_reason"] = "iters+polish:max_evals"
    df.loc[full[5:], "stop_reason"] = "iters+polish:no_gradient"
    s = verdict(df)["sentence"]
    assert "stopped by pso: the iteration limit (`optimizer.iters`) in 10 of 10 starts;" in s
    assert s.count("the iteration limit") == 1


def test_a_warm_started_start_is_stopped_by_its_full_stage():
    from penaltyrun.jobrecord import polished_stop, warm_stop

    df = frame()
    df.loc[df["param"] == "full", "best_cost"] += 5.0
    full = df.index[df["param"] == "full"]
    df.loc[full, "stop_reason"] = warm_stop(polished_stop("ftol", "converged"),
                                            polished_stop("iters", "no_gradient"))
    s = verdict(df)["sentence"]
    assert "stopped by pso: the iteration limit (`optimizer.iters`) in 10 of 10 starts;" in s
    assert "warm:" not in s


def long_held(costs, converged, by_deadline, arrival):
    return {"scenario": SCENARIOS, "cost": list(costs), "converged": list(converged),
            "converged_by_deadline": list(by_deadline), "arrival_time": list(arrival),
            "horizon": 5000.0, "training_horizon": 100.0}


def test_held_out_answer_does_not_need_convergence_by_the_deadline():
    """No scenario converges by the training deadline: the long-horizon cost ratios still
    answer, and the deadline counts stay a column."""
    diag_h = long_held([10.0] * 12, [True] * 12, [False] * 12, [300.0] * 12)
    full_h = long_held([20.0] * 11 + [5.0], [True] * 11 + [False], [False] * 12,
                       [500.0] * 11 + [None])
    rows = [job("diagonal", "pso", 10.0 + 0.1 * k, diag_h if k == 0 else None)
            for k in range(10)]
    rows += [job("full", "pso", 9.0 + 0.1 * k, full_h if k == 0 else None) for k in range(10)]
    row = verdict(pd.DataFrame(rows))
    h = row["held-out"]
    assert "full cheaper on 1/12, median J_full/J_diag 2 " in h
    assert "median arrival shift 200" in h
    assert "judged at horizon T = 5000; converged by T: diagonal 12/12, full 11/12" in h
    assert "by the training deadline 100: diagonal 0/12, full 0/12" in h
    assert "Wilcoxon signed-rank of the log ratios, Holm p" in h
    assert "but from the held-out scenarios full costs more" in row["sentence"]


def test_identical_held_out_costs_give_no_test():
    same = long_held([10.0] * 12, [True] * 12, [True] * 12, [50.0] * 12)
    rows = [job("diagonal", "pso", 10.0 + 0.1 * k, same if k == 0 else None)
            for k in range(10)]
    rows += [job("full", "pso", 9.0 + 0.1 * k, same if k == 0 else None) for k in range(10)]
    row = verdict(pd.DataFrame(rows))
    assert "no evidence of a difference (full cheaper on 0/12, median J_full/J_diag 1" in \
        row["sentence"]
    assert "Holm p —" in row["held-out"]
