"""The job record, defined once: the statuses a job ends with and the fields of its record.

Every job ends as one flat record (``jobs/<job_id>.json``, then one row of
``results.parquet``). :data:`FIELDS` lists every field with its kind, when it is required
and its meaning; the record checks (:mod:`penaltyrun.runner.validate`) and the Parquet
schema (:mod:`penaltyrun.io.schema`) are both derived from it, so they cannot drift apart.
Plain Python without imports from the package, so every layer can use it (also a
problem's report hooks, which sit below the runner).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

#: The optimizer's best candidate met the problem's terminal condition.
OK = "ok"
#: The optimizer's best candidate did not meet the terminal condition.
DIVERGED = "diverged"
#: The job raised, or its worker process died.
FAILED = "failed"
#: The job ran longer than ``runner.job_timeout`` and its worker process was killed.
TIMEOUT = "timeout"
#: Job-level statuses, in the order reports count them.
JOB_STATUSES = (OK, DIVERGED, FAILED, TIMEOUT)
#: Statuses of a job that produced no result (no best cost): a resumed run with
#: ``runner.retry_failed=true`` runs these again, and no statistic counts their costs.
NO_RESULT_STATUSES = (FAILED, TIMEOUT)

#: How a polish ended, after the search's stop reason in ``stop_reason``: ``+polish`` (on
#: its own criteria), ``+polish:<outcome>`` otherwise (``no_gradient``, ``max_evals``).
POLISH_TAG = "+polish"
#: How a polish that ended on its own criteria is named by :func:`split_stop`.
POLISH_CONVERGED = "converged"
_POLISHED = re.compile(r"^(.*)\+polish(?::(\w+))?$", re.DOTALL)


def polished_stop(search: str, outcome: str) -> str:
    """``stop_reason`` of a polished search: the search's own stop reason, then
    ``+polish`` when the polish ended on its own criteria (``outcome`` is
    :data:`POLISH_CONVERGED`), else ``+polish:<outcome>``."""
    return search + (POLISH_TAG if outcome == POLISH_CONVERGED else f"{POLISH_TAG}:{outcome}")


#: A warm-started job's ``stop_reason``: ``warm:<diagonal stage's>|<full stage's>``
#: (:func:`warm_stop`).
WARM_TAG = "warm:"


def warm_stop(diagonal: str, full: str) -> str:
    """``stop_reason`` of a warm-started job from its two stages' stop reasons."""
    return f"{WARM_TAG}{diagonal}|{full}"


def final_search_stop(reason: str) -> str:
    """What stopped the search that ended a job: the search's own stop reason
    (:func:`split_stop`), the full stage's for a warm-started job (:func:`warm_stop`)."""
    search = split_stop(reason)[0]
    if search.startswith(WARM_TAG) and "|" in search:
        return split_stop(search.partition("|")[2])[0]
    return search


def split_stop(reason: str) -> tuple[str, str | None]:
    """The search's stop reason and how its polish ended (:data:`POLISH_CONVERGED`,
    ``no_gradient``, ...; None when no polish ran), from a recorded ``stop_reason``
    (the inverse of :func:`polished_stop`)."""
    match = _POLISHED.match(str(reason))
    if match is None:
        return str(reason), None
    return match.group(1), match.group(2) or POLISH_CONVERGED


#: Version of the record / results schema this code writes (the history:
#: :data:`penaltyrun.io.schema.SCHEMA_HISTORY`). Records of a newer version are refused:
#: their meaning is unknown here.
SCHEMA_VERSION = 10

# Kinds of values, worded as the record checks name them in their messages.
INT = "an integer"
NUMBER = "a number"
TEXT = "text"
BOOL = "true or false"
NUMBERS = "a list of numbers"
INTS = "a list of integers"
TEXTS = "a list of text"
#: A nested value (dict or list) in a record, JSON text in the Parquet file; not checked.
JSON = "JSON"
#: ISO text in a record, a UTC timestamp column in the Parquet file; not checked.
TIME = "a time"

#: ``Field.required``: every record has the field (also a ``failed`` or ``timeout`` one).
ALWAYS = "always"
#: ``Field.required``: an ``ok`` or ``diverged`` record has the field.
FINISHED = "finished"


@dataclass(frozen=True)
class Field:
    """One field of a job record.

    Parameters
    ----------
    kind : str
        One of the kinds above (:data:`INT`, :data:`TEXT`, :data:`JSON`, ...).
    description : str
        What the field holds (the results reference lists it).
    required : str, optional
        :data:`ALWAYS`, :data:`FINISHED`, or ``""``: optional (null or absent allowed).
    column : bool, optional
        Whether the field is a column of ``results.parquet`` (default) or only in the
        record file.
    """

    kind: str
    description: str
    required: str = ""
    column: bool = True


#: Every field of a record, in the order of the Parquet columns.
FIELDS: dict[str, Field] = {
    "run_id": Field(TEXT, "run directory name"),
    "job_id": Field(TEXT, "problem-case-param-optimizer-<settings hash>-sNNN", ALWAYS),
    "problem": Field(TEXT, "problem name", ALWAYS),
    "case": Field(TEXT, "problem case", ALWAYS),
    "param": Field(TEXT, "parameterization (diagonal, full, geagsp, givens, cayley, "
                         "cayley_tan)", ALWAYS),
    "optimizer": Field(TEXT, "optimizer name (pso, pso_matlab, de, cmaes, grid, lbfgs, "
                             "baseline)", ALWAYS),
    "start": Field(INT, "start index within the cell", ALWAYS),
    "seed": Field(INT, "job seed derived from runner.seed", ALWAYS),
    "status": Field(TEXT, " | ".join(JOB_STATUSES), ALWAYS),
    "error": Field(TEXT, "error text (failed, timeout) or why the best did not converge"),
    "best_cost": Field(NUMBER, "best objective value", FINISHED),
    "best_converged": Field(BOOL, "whether the best candidate met the terminal condition"),
    "best_status": Field(TEXT, "problem status of the best candidate"),
    "t_final": Field(NUMBER, "final time of the best candidate (problem time unit)"),
    "best_z": Field(NUMBERS, "best decision vector"),
    "z_names": Field(TEXTS, "labels of the decision variables"),
    "matrices": Field(JSON, "JSON: decoded best matrices {name: nested list}"),
    "scalars": Field(JSON, "JSON: best extra scalars"),
    "metrics": Field(JSON, "JSON: detailed evaluation of the best candidate"),
    "holdout": Field(JSON, "JSON: the best candidate on the problem's held-out set "
                           "(e.g. attitude robustness grid), or null"),
    "closed_loop": Field(JSON, "JSON: the best candidate's closed loop linearized at the "
                               "target (time: continuous | discrete, dt, matrix, gain, "
                               "state_names, input_names), or null (no linearization)"),
    "cl_eig_real": Field(NUMBERS, "closed-loop eigenvalues, real parts (z-plane for a "
                                  "discrete loop), slowest first"),
    "cl_eig_imag": Field(NUMBERS, "closed-loop eigenvalues, imaginary parts"),
    "cl_slowest_real": Field(NUMBER, "slowest real part max Re(s) of the closed-loop poles "
                                     "(1/time unit; discrete: log|z|/dt)"),
    "cl_min_damping": Field(NUMBER, "smallest damping ratio −Re(s)/|s| of the closed-loop "
                                    "poles"),
    "cl_gain_norm": Field(NUMBER, "2-norm of the gain K of u = −K x (null: no gain)"),
    "cl_gain_cond": Field(NUMBER, "2-norm condition number of the gain"),
    "grad_norm": Field(NUMBER, "projected-gradient norm ‖clip(z − ∇, lb, ub) − z‖∞ of the "
                               "cost at best_z (cost unit per unit of z; null: no gradient, "
                               "see gradient_note)"),
    "active_bounds": Field(TEXTS, "variables of best_z on a bound of the box, as "
                                  "'<name>=lower' / '<name>=upper'"),
    "gradient_note": Field(TEXT, "why the cost has no gradient at best_z (empty: it has)"),
    "n_evals": Field(INT, "objective evaluations; with exact gradients (lbfgs, "
                          "polish=gradient) evaluation-equivalents: evaluations plus "
                          "grad_cost × n_gradients"),
    "n_gradients": Field(INT, "exact gradients charged in n_evals (lbfgs, polish=gradient; "
                              "0: none)"),
    "polish_evals": Field(INT, "evaluations (evaluation-equivalents) of n_evals spent by the "
                               "polish (optimizer.polish) after the search; 0: none"),
    "grad_cost": Field(NUMBER, "evaluations charged per exact gradient: what the problem "
                               "declares one gradient to cost, or optimizer.grad_cost (null: "
                               "no gradient charged)"),
    "n_iters": Field(INT, "optimizer iterations"),
    "stop_reason": Field(TEXT, "ftol (stall) | iters | max_evals (budget) | restarts | "
                               "grid+local; after a polish '+polish' (ended on its own "
                               "criteria), '+polish:no_gradient' or '+polish:max_evals'"),
    "n_nonfinite": Field(INT, "non-finite costs replaced by a penalty"),
    "history": Field(NUMBERS, "best cost after each iteration"),
    "trace_evals": Field(INTS, "anytime trace: cumulative evaluations at each improvement "
                               "of the best cost (and at the end)"),
    "trace_best": Field(NUMBERS, "anytime trace: best cost so far at trace_evals"),
    "trace_cpu_s": Field(NUMBERS, "anytime trace: CPU seconds (time.process_time of the "
                                  "job's process) from the start of the search to each "
                                  "point of trace_evals"),
    "max_evals": Field(INT, "evaluation budget of the job (null: none)"),
    "warm_start": Field(JSON, "JSON: the diagonal stage of a warm-started full job (share, "
                              "evaluations and those of its polish, best cost, best diagonal "
                              "matrices), or null"),
    "wall_time_s": Field(NUMBER, "wall time of the job"),
    "optimizer_settings": Field(JSON, "JSON: optimizer settings"),
    "problem_params": Field(JSON, "JSON: problem parameter overrides"),
    "param_options": Field(JSON, "JSON: parameterization options"),
    "config_hash": Field(TEXT, "hash of the resolved config"),
    "config": Field(TEXT, "resolved config (YAML)"),
    "module_hash": Field(TEXT, "hash of the source of a problem given as a module (part "
                               "of the job id)", column=False),
    "package_version": Field(TEXT, "penaltyrun version"),
    "git_commit": Field(TEXT, "git commit of the code (or 'unknown')"),
    "packages": Field(JSON, "JSON: versions of python, numpy, scipy, numba, pyswarms, cma, "
                            "pandas, pyarrow (dask, distributed where used), penaltyrun and "
                            "its git commit"),
    "started_at": Field(TIME, "when the job started (UTC)"),
    "finished_at": Field(TIME, "when the job finished (UTC)"),
    "schema_version": Field(INT, "version of this schema"),
}
