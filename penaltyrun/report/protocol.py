"""What the report learns from each problem through the problem protocol.

The report never names a problem: it asks each problem's module (built-in or a user's, see
:mod:`penaltyrun.problems.report_hooks`) for its cost name and unit, its held-out set, its
paper values, its plots and its extra sections. A module that cannot be imported costs one
warning line; the report then uses only what the Parquet files hold.

Nothing named in the data is imported or called (:mod:`penaltyrun.problems.trust`): a user
problem's hooks run only when the user named its module for this process
(``--problem-module NAME=MODULE``) or installed it as an entry point; otherwise one warning
line says its hooks were not run.
"""

from __future__ import annotations

import json
import logging
from functools import cache
from types import ModuleType
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun import problems
from penaltyrun.io import decode_json
from penaltyrun.problems import report_hooks, trust
from penaltyrun.problems.base import ReportInfo

logger = logging.getLogger(__name__)

#: Warning lines of this report (problems whose module could not be imported, ...).
WARNINGS: list[str] = []
#: ``simulate`` results of this report, per job (:func:`simulate`).
_SIMULATIONS: dict[tuple[str, str, str], Any] = {}


def reset() -> None:
    """Forget cached modules, warnings and simulations (one report at a time)."""
    WARNINGS.clear()
    _SIMULATIONS.clear()
    _module.cache_clear()
    _info.cache_clear()
    _rebuilt.cache_clear()


def warn(text: str) -> None:
    """Record one warning line for the report (and the log), once."""
    if text not in WARNINGS:
        WARNINGS.append(text)
        logger.warning(text)


@cache
def _module(problem: str) -> ModuleType | None:
    try:
        with trust.reading_results():
            return problems.module(problem)
    except trust.NotImportedError:
        warn(f"problem {problem!r}: a user problem whose module was not named, so its report "
             "hooks were not run (reading results never imports a module named in them); "
             "this report uses only the stored columns. To run its hooks, name the module: "
             f"--problem-module {problem if problem.isidentifier() else repr(problem)}=MODULE"
             " (from Python: penaltyrun.load(..., problem=<the module path or the problem "
             "object>))")
        return None
    except Exception as exc:  # a user module missing from PYTHONPATH, or broken
        warn(f"problem {problem!r}: its module cannot be imported ({exc}); this report uses "
             "only what the results hold (no declared unit, problem figures or sections)")
        return None


def module(problem: str) -> ModuleType | None:
    """The problem's module, or None (with one warning) when it cannot be imported."""
    return _module(str(problem))


def params_of(value: Any) -> dict[str, Any]:
    """A job's ``problem_params`` (JSON text or dict) as a dict."""
    data = decode_json(value) if isinstance(value, str) else value
    return dict(data) if isinstance(data, dict) else {}


@cache
def _info(problem: str, case: str, params_json: str) -> ReportInfo:
    mod = module(problem)
    if mod is None:
        return report_hooks.DEFAULT_INFO
    for params in (params_of(params_json), {}):
        try:
            return report_hooks.info(mod, case, params)
        except Exception as exc:  # a hook must not lose the report
            last = exc
    warn(f"problem {problem!r}: report_info failed ({last!r}); generic labels used")
    return report_hooks.DEFAULT_INFO


def info(problem: str, case: str, params: Any = None) -> ReportInfo:
    """The :class:`ReportInfo` of one problem case (the job's parameters where given)."""
    text = params if isinstance(params, str) else json.dumps(params or {}, sort_keys=True,
                                                            default=str)
    return _info(str(problem), str(case), text or "{}")


def info_of(rows: pd.DataFrame) -> ReportInfo:
    """The :class:`ReportInfo` of the first job of ``rows``."""
    first = rows.iloc[0]
    return info(first["problem"], first["case"], first.get("problem_params"))


def _plain(value: Any) -> Any:
    """NaN / None → None; numpy scalars → Python."""
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return None
    if isinstance(value, np.generic):
        return value.item()
    return value


def jobs_of(df: pd.DataFrame) -> list[dict[str, Any]]:
    """Job rows as plain dicts (keys: :func:`penaltyrun.problems.report_hooks.job_keys`)."""
    from penaltyrun.report.rows import with_columns
    from penaltyrun.report.stats import converged

    df = with_columns(df)
    ok = converged(df)
    jobs = []
    for idx, row in df.iterrows():
        mats = decode_json(row.get("matrices")) or {}
        jobs.append({
            "problem": row["problem"], "case": row["case"], "variant": row.get("variant", ""),
            "optimizer": row["optimizer"], "param": row["param"],
            "family": "diagonal" if row["param"] == "diagonal" else "full",
            "start": _plain(row.get("start")), "status": row["status"],
            "converged": bool(ok[idx]), "best_cost": _plain(row.get("best_cost")),
            "n_evals": _plain(row.get("n_evals")), "max_evals": _plain(row.get("max_evals")),
            "stop_reason": _plain(row.get("stop_reason")),
            "matrices": {k: np.asarray(v, float) for k, v in mats.items()},
            "scalars": decode_json(row.get("scalars")) or {},
            "metrics": decode_json(row.get("metrics")) or {},
            "holdout": decode_json(row.get("holdout")),
            "problem_params": params_of(row.get("problem_params")),
            "optimizer_settings": decode_json(row.get("optimizer_settings")) or {},
        })
    return jobs


def simulate(row: pd.Series) -> dict[str, np.ndarray] | None:
    """``simulate`` of a job's best matrices (None when the problem cannot be rebuilt);
    kept per job for this report (several sections draw the same start)."""
    key = (str(row.get("job_id")), str(row.get("config_hash")), str(row.get("matrices")))
    if key not in _SIMULATIONS:
        _SIMULATIONS[key] = _simulate(row)
    return _SIMULATIONS[key]


def simulate_matrices(problem: str, case: str, params: Any, mats: dict[str, Any]
                      ) -> dict[str, np.ndarray] | None:
    """``simulate`` of given matrices (e.g. a paper's) on the problem of stored results
    (None when it cannot be rebuilt); kept for this report, so the variants of one problem
    case that share its parameters (budgets, warm starts) simulate them once."""
    text = params if isinstance(params, str) else json.dumps(params or {}, sort_keys=True,
                                                            default=str)
    key = ("matrices", f"{problem}\0{case}\0{text}",
           json.dumps({k: np.asarray(v, float).tolist() for k, v in sorted(mats.items())}))
    if key not in _SIMULATIONS:
        prob = rebuild(problem, case, params)
        _SIMULATIONS[key] = None if prob is None else prob.simulate(dict(mats))
    return _SIMULATIONS[key]


def _simulate(row: pd.Series) -> dict[str, np.ndarray] | None:
    prob = rebuild(row["problem"], row["case"], row.get("problem_params"))
    if prob is None:
        return None
    mats = {k: np.asarray(v, float) for k, v in (decode_json(row["matrices"]) or {}).items()}
    return prob.simulate(mats, decode_json(row.get("scalars")) or None)


def make(problem: str, case: str, params: Any = None) -> Any:
    """The problem instance of stored results (``params``: JSON text or dict), built without
    importing anything the data names (see :mod:`penaltyrun.problems.trust`).

    Raises
    ------
    ConfigError
        The problem cannot be rebuilt from these results (a user module not named, a plant
        named by module, old parameters).
    """
    with trust.reading_results():
        return problems.make(str(problem), str(case), params_of(params))


@cache
def _rebuilt(problem: str, case: str, params_json: str) -> Any:
    if module(problem) is None:
        return None
    try:
        return make(problem, case, params_json)
    except Exception as exc:  # an unknown case, old or damaged parameters, a plant not allowed
        reason = " ".join(str(exc).split()) or type(exc).__name__
        warn(f"problem {problem!r}, case {case!r}: cannot be rebuilt from the stored "
             f"parameters ({reason}); its sections use only the stored columns")
        return None


def rebuild(problem: str, case: str, params: Any = None) -> Any:
    """The problem instance of stored results, or None (with one warning per problem, case
    and parameters) when it cannot be rebuilt: its module not imported (see :func:`module`),
    a case this version does not know, parameters it does not accept. One instance per
    problem, case and parameters for this report."""
    text = params if isinstance(params, str) else json.dumps(params or {}, sort_keys=True,
                                                            default=str)
    return _rebuilt(str(problem), str(case), text or "{}")


def bounds_of(row: pd.Series) -> dict[str, tuple[float, float]] | None:
    """Eigenvalue bounds per matrix name of a job's problem (None when unknown)."""
    prob = rebuild(row["problem"], row["case"], row.get("problem_params"))
    if prob is None:
        return None
    return {m.name: tuple(float(b) for b in m.eig_bounds) for m in prob.matrices}


__all__ = ["WARNINGS", "bounds_of", "info", "info_of", "jobs_of", "make", "module",
           "params_of", "rebuild", "reset", "simulate", "simulate_matrices", "warn"]
