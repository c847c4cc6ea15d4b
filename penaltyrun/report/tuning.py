"""Multi-scenario vs single-scenario tuning: the held-out full-vs-diagonal gap side by side.

A job's tuning mode is read from its ``problem_params`` (no extra column): *single* when it
sets neither ``train_scenarios`` nor ``train_sample``, otherwise *multi* with the aggregate
and the number of training scenarios, e.g. ``multi (mean of 8)``
(:mod:`penaltyrun.problems.multiscenario`). Jobs are compared across modes only when
everything else is equal: problem, case, the other problem parameters, optimizer and its
settings (so the budget), and warm start. Within each mode the best diagonal start and the
best start of each full map are paired scenario by scenario on the held-out set, as in
:func:`penaltyrun.report.holdout.paired`: the share of scenarios where full is cheaper, the
median cost ratio J_full/J_diag and the two-sided Wilcoxon signed-rank p of the log ratios;
the CSV adds the older statistics over the scenarios both converge.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.io import decode_json
from penaltyrun.report import holdout
from penaltyrun.report.rows import groups, has
from penaltyrun.report.tables import markdown

#: Problem parameters that define the training set (multi-scenario tuning).
TRAIN_KEYS = ("train_scenarios", "train_aggregate", "train_sample", "train_seed")
SINGLE = "single"
#: Per-mode statistics shown side by side: (key of holdout.paired, column suffix).
STATS = (("scenarios", "scenarios"), ("full_cheaper_share", "full cheaper"),
         ("ratio_median", "median J_full/J_diag"), ("ratio_p", "Wilcoxon p (log ratio)"),
         ("judged_at", "horizon"), ("pairs", "pairs"), ("median_imp_pct", "median impr. %"),
         ("full_better_share", "full better"), ("wilcoxon_p", "Wilcoxon p"),
         ("note", "note"))
#: The statistics of the report's Markdown table (the CSV has every one of :data:`STATS`).
SHOWN = ("scenarios", "full cheaper", "median J_full/J_diag", "Wilcoxon p (log ratio)",
         "horizon")


def _json(value: Any) -> dict[str, Any]:
    data = decode_json(value) if isinstance(value, str) else value
    return dict(data) if isinstance(data, dict) else {}


def training_of(params: Any) -> dict[str, Any]:
    """The training settings of a job's ``problem_params`` (JSON text or dict); ``{}`` for
    single-scenario tuning."""
    p = _json(params)
    listed = p.get("train_scenarios")
    sample = p.get("train_sample") or 0
    if not listed and not sample:
        return {}
    return {k: p.get(k) for k in TRAIN_KEYS if p.get(k) is not None}


def aggregate_label(training: dict[str, Any]) -> str:
    """``<aggregate> of <n>`` of multi-scenario ``training`` settings (e.g. ``mean of 8``):
    the cost the optimizers minimized."""
    n = len(training.get("train_scenarios") or []) + int(training.get("train_sample") or 0)
    return f"{training.get('train_aggregate') or 'mean'} of {n}"


def mode_label(training: dict[str, Any]) -> str:
    """``single`` or ``multi (<aggregate> of <n>)``."""
    return f"multi ({aggregate_label(training)})" if training else SINGLE


def _canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)


def _key(value: Any) -> Any:
    """``value`` as a dictionary key (JSON text for a dict or list)."""
    try:
        hash(value)
    except TypeError:
        return ("json", _canonical(value))
    return value


#: Columns besides ``problem_params`` that :func:`_setting` reads.
SETTING_COLUMNS = ("optimizer_settings", "warm_start")


def _setting(row: dict[str, Any]) -> tuple[str, str]:
    """(comparison key, display text) of everything but the training set."""
    params = {k: v for k, v in _json(row.get("problem_params")).items()
              if k not in TRAIN_KEYS and v is not None}
    opt = _canonical(_json(row.get("optimizer_settings")))
    warm = _canonical(_json(row.get("warm_start")).get("share"))
    shown = ", ".join(f"{k}={v}" for k, v in sorted(params.items())) or "—"
    return _canonical(params) + "|" + opt + "|" + warm, shown


def _setup_codes(df: pd.DataFrame, columns: tuple[str, ...]) -> tuple[np.ndarray, list[tuple]]:
    """Per row of ``df`` the number of its distinct set-up (its values of ``columns``, a
    missing column read as None), and each set-up's values, first rows first.

    Grouping holds one integer a row; values that cannot be grouped (dicts or lists,
    e.g. a frame built in Python) are keyed as canonical JSON, one tuple a row.
    """
    present = [c for c in columns if c in df]
    if not present or df.empty:
        return np.zeros(len(df), np.int64), [(None,) * len(columns)] * bool(len(df))
    try:
        codes = df.groupby(present, sort=False, dropna=False, observed=True).ngroup()
        codes = codes.to_numpy(np.int64)
    except TypeError:  # unhashable values
        keys = list(zip(*(df[c].map(_key) for c in present)))
        codes = pd.factorize(pd.Series(keys, dtype=object))[0].astype(np.int64)
    first = np.unique(codes, return_index=True)[1]
    values = [tuple(df[c].iat[i] if c in df else None for c in columns) for i in first]
    return codes, values


def _column(codes: np.ndarray, per_setup: list[str]) -> pd.Categorical:
    """A categorical column: row i holds ``per_setup[codes[i]]``."""
    setup_codes, labels = pd.factorize(pd.Series(per_setup, dtype=object), sort=True)
    return pd.Categorical.from_codes(setup_codes[codes], categories=list(labels))


def with_modes(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with columns ``tuning`` (mode label), ``tuning_key`` (the training settings as
    JSON), ``setting_key`` and ``setting`` (the rest of the set-up), categorical.

    Each distinct set-up (``problem_params``, ``optimizer_settings``, ``warm_start``) is
    decoded once and the rows hold codes of it, so a large results set costs a few bytes a
    row here, not text a row.
    """
    out = df.copy(deep=False)  # new columns only: the frame itself is not copied
    columns = ("problem_params", *SETTING_COLUMNS)
    codes, setups = _setup_codes(out, columns)
    training = [training_of(v[0]) for v in setups]
    settings = [_setting(dict(zip(columns, v))) for v in setups]
    keys = [_canonical(t) for t in training]
    labels = [mode_label(t) for t in training]
    # two different training sets with the same label get a short hash of their own
    for label in {lab for lab, key in zip(labels, keys) if key != "{}"}:
        same = {key for lab, key in zip(labels, keys) if lab == label}
        if len(same) > 1:
            labels = [f"{lab} #{hashlib.sha1(key.encode()).hexdigest()[:6]}"
                      if lab == label else lab for lab, key in zip(labels, keys)]
    out["tuning_key"] = _column(codes, keys)
    out["tuning"] = _column(codes, labels)
    out["setting_key"] = _column(codes, [s[0] for s in settings])
    out["setting"] = _column(codes, [s[1] for s in settings])
    return out


def comparison(df: pd.DataFrame) -> pd.DataFrame:
    """One row per set-up × full map that was tuned both single- and multi-scenario.

    Returns
    -------
    DataFrame
        ``problem``, ``case``, ``setting`` (the variant label of :func:`penaltyrun.report.
        stats.add_variant` where present), ``optimizer``, ``max_evals``, ``full_map`` and,
        per tuning mode M (``single`` first), ``M: scenarios``, ``M: full cheaper``
        (share of every held-out scenario), ``M: median J_full/J_diag``,
        ``M: Wilcoxon p (log ratio)``, ``M: horizon`` (see
        :func:`penaltyrun.report.holdout.paired`) and, over the scenarios both converge,
        ``M: pairs``, ``M: median impr. %``, ``M: full better``, ``M: Wilcoxon p``,
        ``M: note``. Empty when no set-up has both.
    """
    if not has(df, "holdout") or "problem_params" not in df or df.empty:
        return pd.DataFrame()
    m = with_modes(df)
    rows = []
    keys = ["problem", "case", "setting_key", "optimizer"]
    for (problem, case, _, optimizer), g in groups(m, keys):
        modes = sorted(g["tuning"].unique(), key=lambda t: (t != SINGLE, t))
        if SINGLE not in modes or len(modes) < 2:
            continue
        for full_map in sorted(p for p in g["param"].unique() if p != "diagonal"):
            row: dict[str, Any] = {"problem": problem, "case": case,
                                   "setting": _shown(g), "optimizer": optimizer,
                                   "max_evals": g["max_evals"].iloc[0] if "max_evals" in g
                                   else None, "full_map": full_map}
            found = False
            for mode in modes:
                res = _paired(g[g["tuning"] == mode], full_map)
                found |= res is not None
                for key, suffix in STATS:
                    row[f"{mode}: {suffix}"] = (res or {}).get(key, np.nan if key != "note"
                                                               else "no held-out data")
            if found:
                rows.append(row)
    return pd.DataFrame(rows)


def _shown(g: pd.DataFrame) -> str:
    """The set-up as the report names it: the single-scenario jobs' variant label (problem
    parameters that differ from the case's defaults) when known, else every parameter."""
    single = g[g["tuning"] == SINGLE]
    if "variant" in single and single["variant"].notna().any():
        return str(single["variant"].dropna().iloc[0]) or "—"
    return str(single["setting"].iloc[0])


def _paired(g: pd.DataFrame, full_map: str) -> dict[str, Any] | None:
    """holdout.paired of the best diagonal and best ``full_map`` start of one mode."""
    drow = holdout.best_start(g[g["param"] == "diagonal"])
    frow = holdout.best_start(g[g["param"] == full_map])
    if drow is None or frow is None:
        return None
    from penaltyrun.report import protocol

    drop = protocol.info_of(g).discretization_kinds
    dtab = holdout.scenario_table(drow["holdout"], drop)
    ftab = holdout.scenario_table(frow["holdout"], drop)
    if dtab is None or ftab is None:
        return None
    return holdout.paired(dtab, ftab)


def study_sections(df: pd.DataFrame, out: Path, paper: bool) -> list[str]:
    """Markdown lines of the tuning-mode comparison (empty without both modes)."""
    table = comparison(df)
    if table.empty:
        return []
    table.to_csv(out / "holdout_tuning_modes.csv", index=False, encoding="utf-8")
    return ["## Held-out scenarios: multi-scenario vs single-scenario tuning", "",
            "The full-vs-diagonal gap on the held-out set for each tuning mode, side by "
            "side: same problem, case, other parameters, optimizer and budget; within each "
            "mode the best diagonal and the best full start, paired by scenario at the "
            "held-out horizon (column *horizon*). Full cheaper = share of every held-out "
            "scenario where J_full < J_diag; median of J_full/J_diag; Wilcoxon signed-rank "
            "of the log ratios, two-sided (raw p); the statistics over the scenarios both "
            "converge are in the CSV. `multi (mean of n)`: tuned on the mean (or max) of n "
            "training scenarios.", "", markdown(long_form(table), LONG_COLUMNS), ""]


LONG_COLUMNS = ["problem / case", "setting", "optimizer", "full_map", "tuning", *SHOWN]


def long_form(table: pd.DataFrame) -> pd.DataFrame:
    """One row per set-up × full map × tuning mode (≤ 10 columns for the report)."""
    rows = []
    for _, r in table.iterrows():
        modes = sorted({c.split(": ")[0] for c in r.index if ": " in c},
                       key=lambda t: (t != SINGLE, t))
        for mode in modes:
            rows.append({"problem / case": f"{r['problem']} / {r['case']}",
                         "setting": r["setting"], "optimizer": r["optimizer"],
                         "full_map": r["full_map"], "tuning": mode,
                         **{suffix: r[f"{mode}: {suffix}"] for suffix in SHOWN}})
    return pd.DataFrame(rows)


__all__ = ["SINGLE", "TRAIN_KEYS", "aggregate_label", "comparison", "mode_label", "study_sections",
           "training_of", "with_modes"]
