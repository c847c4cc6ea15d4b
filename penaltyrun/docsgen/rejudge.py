"""Re-judge a committed study's held-out results without re-tuning.

``python -m penaltyrun.docsgen study rejudge NAME`` reads ``studies/NAME/results.parquet``,
rebuilds each job's problem from its stored ``problem``, ``case`` and ``problem_params``
(parameters the record does not set take today's defaults, so the held-out horizon of
:mod:`penaltyrun.problems.horizon` applies), re-evaluates the job's stored best matrices
with ``Problem.holdout`` and writes

* ``studies/NAME/holdout_long.parquet``: one row per re-judged job (see
  :mod:`penaltyrun.io.longholdout`; reading the results applies it);
* ``studies/NAME/holdout_long.json``: provenance (git commit, package versions, horizon
  settings per problem and case, job selection, counts, CPU time);
* the study's report tables (``studies/NAME/tables``), rebuilt from the re-judged data.

``jobs="all"`` re-judges every job with held-out data; ``jobs="paired"`` only the starts the
held-out tables pair (each cell's best diagonal and full starts, the best-known pair and the
tuning-mode pairs): the others then carry no held-out data. Jobs run in a process pool
(``workers``), with a log line of progress and the expected remaining time every few
seconds.
"""

from __future__ import annotations

import json
import logging
import os
import subprocess
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from penaltyrun.docsgen.provenance import display_path, machine, package_versions
from penaltyrun.docsgen.studies import RESULTS, TABLES, StudyError, load_study, write_tables
from penaltyrun.io.longholdout import LONG_FILE, LONG_PROVENANCE
from penaltyrun.problems.hooks import hooks
from penaltyrun.runner.options import resolve_workers

logger = logging.getLogger(__name__)

#: Job selections of :func:`rejudge_study`.
SELECTIONS = ("all", "paired")
#: Seconds between two progress lines.
PROGRESS_S = 10.0


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


def rejudge_record(record: dict[str, Any]) -> dict[str, Any]:
    """Re-evaluate one job's stored best matrices on its problem's held-out set.

    Parameters
    ----------
    record : dict
        ``job_id``, ``config_hash``, ``problem``, ``case``, ``problem_params``,
        ``matrices``, ``scalars`` (JSON text as stored).

    Returns
    -------
    dict
        ``job_id``, ``config_hash``, ``holdout`` (JSON text or None), ``status`` (``ok``,
        ``no_holdout`` or ``failed: <reason>``), ``wall_time_s``.
    """
    from penaltyrun import problems
    from penaltyrun.io import decode_json

    start = time.perf_counter()
    out = {"job_id": record["job_id"], "config_hash": record["config_hash"], "holdout": None}
    try:
        prob = problems.make(record["problem"], record["case"],
                             decode_json(record["problem_params"]) or {})
        mats = {k: np.asarray(v, dtype=float)
                for k, v in (decode_json(record["matrices"]) or {}).items()}
        scalars = decode_json(record.get("scalars")) or None
        judge = hooks(prob).holdout
        held = judge(mats, scalars) if judge is not None else None
        out["status"] = "ok" if held is not None else "no_holdout"
        if held is not None:
            out["holdout"] = json.dumps(_plain(held))
    except Exception as exc:  # recorded, never a crash (one bad record among many)
        out["status"] = f"failed: {type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
    out["wall_time_s"] = time.perf_counter() - start
    return out


def select_jobs(df: Any, jobs: str) -> Any:
    """The records to re-judge: every one with held-out data (``all``) or the starts the
    held-out tables pair (``paired``, see the module docstring)."""
    if jobs not in SELECTIONS:
        raise StudyError(f"jobs must be one of {', '.join(SELECTIONS)}, got {jobs!r}")
    have = df[df["holdout"].notna() & df["matrices"].notna()]
    if jobs == "all":
        return have
    from penaltyrun.report import holdout, tuning
    from penaltyrun.report.bestknown import best_rows, with_problem_variant

    frame = with_problem_variant(have)
    if "variant" not in frame:
        frame = frame.assign(variant=frame["problem_variant"])
    keep: set[str] = set()
    for _, g in frame.groupby(["problem", "case", "problem_variant", "variant", "optimizer",
                               "param"], sort=False):
        row = holdout.best_start(g)
        if row is not None:
            keep.add(str(row["job_id"]))
    for _, g in frame.groupby(["problem", "case", "problem_variant"], sort=False):
        keep.update(str(r["job_id"]) for r in best_rows(g).values())
    if "problem_params" in frame:
        modes = tuning.with_modes(frame)
        for _, g in modes.groupby(["problem", "case", "setting_key", "optimizer", "tuning",
                                   "param"], sort=False):
            row = holdout.best_start(g)
            if row is not None:
                keep.add(str(row["job_id"]))
    return have[have["job_id"].astype(str).isin(keep)]


def horizon_settings(df: Any) -> list[dict[str, Any]]:
    """Held-out horizon of each problem × case × parameter set of ``df`` (as re-judged)."""
    from penaltyrun import problems
    from penaltyrun.io import decode_json
    from penaltyrun.problems import horizon

    rows = []
    for (problem, case, params), _ in df.groupby(["problem", "case", "problem_params"],
                                                 sort=True):
        try:
            prob = problems.make(problem, case, decode_json(params) or {})
        except Exception as exc:  # reported in the provenance
            rows.append({"problem": problem, "case": case, "error": str(exc)})
            continue
        base = getattr(prob, "base", prob).params
        entry = {"problem": problem, "case": case}
        if all(hasattr(base, k) for k in horizon.SETTINGS):
            step = getattr(base, "sample_time_s", None)
            entry.update({"t_max": float(base.t_max),
                          "holdout_horizon_factor": float(base.holdout_horizon_factor),
                          "holdout_t_max_cap": float(base.holdout_t_max_cap),
                          "horizon": horizon.holdout_horizon(
                              base.t_max, base.holdout_horizon_factor,
                              base.holdout_t_max_cap, step)})
        else:
            entry["horizon"] = "free final time: held-out runs end on arrival or at the " \
                "problem's own caps, as in training"
        if entry not in rows:
            rows.append(entry)
    return rows


def rejudge_study(root: Path, name: str, *, jobs: str = "all", workers: int | str = "auto",
                  tables: bool = True) -> Path:
    """Re-judge study ``name`` (see the module docstring); return the written data file.

    Raises
    ------
    StudyError
        If the study has no merged results or no held-out data.
    """
    import pandas as pd

    from penaltyrun.io.schema import read_results

    study = load_study(root, name)
    results = study.folder / RESULTS
    if not results.is_file():
        raise StudyError(f"study {name!r} has no {RESULTS} (run `{study.make_target}`)")
    previous = study.folder / LONG_FILE
    kept = previous.with_suffix(".previous")
    if previous.is_file():  # read the records as stored, not a previous re-judging
        os.replace(previous, kept)
    try:
        df = read_results(results)
    finally:
        if kept.is_file():
            os.replace(kept, previous)
    todo = select_jobs(df, jobs)
    if todo.empty:
        raise StudyError(f"study {name!r} has no held-out data to re-judge")
    columns = ["job_id", "config_hash", "problem", "case", "problem_params", "matrices",
               "scalars"]
    records = todo[columns].to_dict("records")
    n_workers = min(resolve_workers(workers), len(records))
    logger.info("rejudge %s: %d of %d jobs (%s), %d worker(s)", name, len(records), len(df),
                jobs, n_workers)
    rows, t0, last = [], time.perf_counter(), 0.0
    with ProcessPoolExecutor(max_workers=n_workers) as pool:
        for row in pool.map(rejudge_record, records, chunksize=1):
            rows.append(row)
            now = time.perf_counter() - t0
            if now - last >= PROGRESS_S or len(rows) == len(records):
                last = now
                eta = now / len(rows) * (len(records) - len(rows))
                logger.info("rejudge %s: %d/%d jobs, %.0f s elapsed, ~%.0f s left", name,
                            len(rows), len(records), now, eta)
    frame = pd.DataFrame(rows, columns=["job_id", "config_hash", "holdout", "status",
                                        "wall_time_s"])
    tmp = study.folder / (LONG_FILE + ".tmp")
    frame.to_parquet(tmp, compression="zstd", index=False)
    os.replace(tmp, study.folder / LONG_FILE)
    status = frame["status"].str.split(":").str[0].value_counts()
    info = {"git_commit": git_commit(root), "packages": package_versions(), "jobs": jobs,
            "machine": machine(),
            "rejudged": int(len(frame)), "records": int(len(df)),
            "status": {str(k): int(v) for k, v in status.items()},
            "cpu_s": round(float(frame["wall_time_s"].sum()), 1),
            "horizons": horizon_settings(todo)}
    (study.folder / LONG_PROVENANCE).write_text(json.dumps(info, indent=2, sort_keys=True)
                                                + "\n")
    failed = frame[frame["status"].str.startswith("failed")]
    for _, r in failed.head(5).iterrows():
        logger.warning("rejudge %s: %s %s", name, r["job_id"], r["status"])
    if tables:
        with tempfile.TemporaryDirectory(prefix="rejudge-") as tmpdir:
            write_tables(results, Path(tmpdir), study.folder / TABLES,
                         label=display_path(results, root))
    logger.info("rejudge %s: wrote %s (%d jobs, %d failed, %.0f CPU s)", name,
                display_path(study.folder / LONG_FILE, root), len(frame), len(failed),
                info["cpu_s"])
    return study.folder / LONG_FILE


def git_commit(root: Path) -> str:
    """Commit of the repository at ``root`` (``-dirty`` if tracked files of the package
    source are modified: the study folders being re-judged do not count), or ``unknown``."""
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                "penaltyrun"], cwd=root, capture_output=True, text=True,
                               timeout=5).stdout
        return sha + ("-dirty" if dirty.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


__all__ = ["SELECTIONS", "git_commit", "horizon_settings", "rejudge_record", "rejudge_study",
           "select_jobs"]
