"""Re-judged held-out data beside a results file: ``holdout_long.parquet``.

A study's ``results.parquet`` keeps each job's held-out results as the job stored them
(older jobs: judged at the training deadline). Re-judging (``python -m penaltyrun.docsgen
study rejudge NAME``) re-evaluates the stored best matrices on the held-out set at the
held-out horizon and writes ``holdout_long.parquet`` beside it: one row per re-judged job
(``job_id``, ``config_hash``, ``holdout`` JSON text, ``status``, ``wall_time_s``) and, in
``holdout_long.json``, its provenance (git commit, package versions, horizon settings).

Reading a results file applies it (:func:`apply`): every job's ``holdout`` becomes its
re-judged value; jobs the re-judging left out (``jobs: paired`` re-judges only the starts
the held-out tables pair) get no held-out data, so no table mixes the two horizons.
``attrs["holdout_source"]`` names the file used.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable
from pathlib import Path

import pandas as pd
import pyarrow as pa

from penaltyrun.io.schema import config_key

logger = logging.getLogger(__name__)

#: File name of the re-judged held-out data, beside ``results.parquet``.
LONG_FILE = "holdout_long.parquet"
#: Its provenance file.
LONG_PROVENANCE = "holdout_long.json"
#: Columns of :data:`LONG_FILE`.
LONG_COLUMNS = ("job_id", "config_hash", "holdout", "status", "wall_time_s")


def _read_checked(path: Path) -> pd.DataFrame:
    """The columns of :data:`LONG_FILE` at ``path`` that :func:`apply` uses, read within the
    limits of a results file and checked as one is (the held-out JSON of every row).

    Raises
    ------
    ValueError, KeyError
        The file is refused (footer, size, a column missing, unusable held-out JSON).
    OSError, pyarrow.ArrowException
        It cannot be read as Parquet.
    """
    # filecheck applies this module to every results frame it makes: imported here, once
    # a re-judged file is found, not at this module's import.
    from penaltyrun.io.filecheck import check_footer, json_object_problem, read_bounded

    refused = check_footer(path)
    if refused:
        raise ValueError(refused)
    long = read_bounded(path, ("job_id", "config_hash", "holdout")).to_pandas()
    for name in ("job_id", "config_hash", "holdout"):
        if name not in long:
            raise KeyError(f"no column {name}")
    for value in long["holdout"].dropna().unique():
        why = json_object_problem("holdout", value)
        if why:
            raise ValueError(why)
    return long


#: ``rejudged`` of :func:`apply`: look for :data:`LONG_FILE` beside the results file.
BESIDE = "beside"


def read_beside(results: Path) -> pd.DataFrame | None:
    """The re-judged held-out table beside the results file ``results`` (its columns
    ``job_id``, ``config_hash``, ``holdout``, checked), or None: there is none, or it
    cannot be used (one warning: the held-out data stored in ``results`` are reported)."""
    path = Path(results).parent / LONG_FILE
    if not path.is_file():
        return None
    try:
        return _read_checked(path)
    except (OSError, pa.ArrowException, ValueError, KeyError, MemoryError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        logger.warning("skipped re-judged held-out file %s: %s (the held-out data stored "
                       "in %s are reported)", path, text, results)
        return None


def replacing(results: Path, needed: Iterable[str]) -> tuple[pd.DataFrame | None,
                                                              tuple[str, ...]]:
    """The re-judged table beside ``results`` (:func:`read_beside`) when the columns
    ``needed`` include ``holdout``, and the stored columns it replaces, which a reader
    need neither read nor check (``("holdout",)`` with a usable table, else none)."""
    rejudged = read_beside(results) if "holdout" in needed else None
    return rejudged, ("holdout",) if rejudged is not None else ()


def apply(frame: pd.DataFrame, results: Path,
          rejudged: pd.DataFrame | str | None = BESIDE) -> pd.DataFrame:
    """``frame`` (read from ``results``) with the ``holdout`` column of the re-judged file
    beside it, matched by ``job_id`` and ``config_hash``; ``frame`` unchanged without one.

    ``rejudged``: that file's table as :func:`read_beside` gives it (a caller that read it
    first need not read the stored held-out column, which it replaces), None (the caller
    found none), or :data:`BESIDE` (read it here).
    """
    if isinstance(rejudged, str):
        rejudged = read_beside(results) if "holdout" in frame else None
    if rejudged is None or "holdout" not in frame:
        return frame
    path = Path(results).parent / LONG_FILE
    table = {(str(j), config_key(h)): v for j, h, v in zip(
        rejudged["job_id"], rejudged["config_hash"], rejudged["holdout"])}
    out = frame.copy()
    out["holdout"] = [table.get((str(j), config_key(h))) for j, h in zip(frame["job_id"],
                                                                   frame["config_hash"])]
    missing = int(out["holdout"].isna().sum() - frame["holdout"].isna().sum())
    if missing > 0:
        logger.info("%s: %d job(s) not re-judged carry no held-out data", path, missing)
    out.attrs = dict(frame.attrs)
    out.attrs["holdout_source"] = str(path)
    return out


__all__ = ["BESIDE", "LONG_COLUMNS", "LONG_FILE", "LONG_PROVENANCE", "apply", "read_beside",
           "replacing"]
