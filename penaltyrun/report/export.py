"""Export each cell's best matrices for other tools: JSON and MATLAB ``.mat``.

One pair of files per report cell (problem, case, variant, optimizer, parameterization):
the start with the lowest best cost among the jobs that did not fail. ``<stem>.json`` holds
the matrices as nested lists with the cell, job id, cost and detailed metrics;
``<stem>.mat`` (``scipy.io.savemat``) holds each matrix under its own name (``Q``, ``R``,
``K``, ...), the extra scalars, and the cell as strings (``problem``, ``case_name`` —
``case`` is a MATLAB keyword —, ``variant``, ``optimizer``, ``param``, ``job_id``) and
``best_cost``. ``index.csv`` lists the cells and their files.

File names come from the cell's identity (:class:`~penaltyrun.report.tables.StemBook`): every
name from the data is made a safe stem, and two cells never share a file. The export is
written like the report (:mod:`penaltyrun.report.outdir`): never through a symbolic link,
and the files of a previous export in the same folder are replaced, not mixed with the new
ones. Nothing named in the data is imported (:mod:`penaltyrun.problems.trust`).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.io import savemat

from penaltyrun.io import decode_json, read_results, strict_json
from penaltyrun.jobrecord import NO_RESULT_STATUSES
from penaltyrun.problems import trust
from penaltyrun.report import outdir
from penaltyrun.report.stats import CELL, add_variant
from penaltyrun.report.tables import StemBook

logger = logging.getLogger(__name__)

#: Names that cannot be MATLAB variables.
_MATLAB_RESERVED = {"case", "end", "for", "function", "if", "switch", "while", "global"}


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-." else "_" for ch in str(text)).strip("_")


def cell_stem(row: pd.Series, book: StemBook | None = None) -> str:
    """File stem of a cell: ``<problem>_<case>[_<variant>]_<optimizer>_<param>``, each part
    a safe stem (:func:`~penaltyrun.report.tables.file_stem`), distinct per cell within
    ``book``."""
    return (book or StemBook()).stem(row["problem"], row["case"], row["variant"],
                                     row["optimizer"], row["param"])


def best_per_cell(df: pd.DataFrame) -> pd.DataFrame:
    """The best non-failed job of every cell (``df`` must have the ``variant`` column)."""
    ok = df[~df["status"].isin(NO_RESULT_STATUSES) & df["best_cost"].notna()
            & df["matrices"].notna()]
    if ok.empty:
        return ok
    idx = ok.groupby(CELL, sort=True)["best_cost"].idxmin()
    return ok.loc[idx.values].reset_index(drop=True)


def _matlab_name(name: str) -> str:
    safe = _slug(name).replace("-", "_").replace(".", "_") or "x"
    if not safe[0].isalpha():
        safe = "m_" + safe
    return safe + "_" if safe in _MATLAB_RESERVED else safe


def export_best(src: Path, out: Path) -> list[Path]:
    """Write ``<stem>.json`` and ``<stem>.mat`` for each cell's best matrices.

    Parameters
    ----------
    src : Path
        A results.parquet file or a folder searched recursively.
    out : Path
        Output folder (created).

    Returns
    -------
    list of Path
        Files written (JSON and .mat of each cell, then ``index.csv``).

    Raises
    ------
    ConfigError
        ``out`` is a symbolic link or a file, or leads through a link inside ``src``.
    """
    out = Path(out)
    with trust.reading_results():
        best = best_per_cell(add_variant(read_results(src)))
    names: list[str] = []
    outdir.write_into(out, "--export", lambda tmp: names.extend(_write(best, tmp)),
                      outdir.export_files, prefix=".export-", source=Path(src))
    logger.info("exported the best matrices of %d cells to %s", len(names) // 2, out)
    return [out / name for name in names]


def _write(best: pd.DataFrame, out: Path) -> list[str]:
    """Write the files of :func:`export_best` into ``out``; their names (JSON and .mat of
    each cell, then ``index.csv``)."""
    book = StemBook()
    written: list[str] = []
    index = []
    for _, row in best.iterrows():
        stem = cell_stem(row, book)
        mats = {k: np.asarray(v, dtype=float) for k, v in decode_json(row["matrices"]).items()}
        scalars = decode_json(row["scalars"]) or {}
        cell: dict[str, Any] = {k: str(row[k]) for k in CELL}
        doc = {**cell, "job_id": str(row["job_id"]), "best_cost": float(row["best_cost"]),
               "best_converged": bool(row["best_converged"]),
               "matrices": {k: v.tolist() for k, v in mats.items()}, "scalars": scalars,
               "metrics": decode_json(row["metrics"]),
               "problem_params": decode_json(row["problem_params"]),
               "git_commit": row["git_commit"], "package_version": row["package_version"]}
        json_path = out / f"{stem}.json"
        json_path.write_text(json.dumps(strict_json(doc), indent=1, default=str,
                                        allow_nan=False) + "\n", encoding="utf-8")
        mdict: dict[str, Any] = {_matlab_name(k): v for k, v in mats.items()}
        mdict.update({_matlab_name(k): float(v) for k, v in scalars.items()})
        mdict.update({("case_name" if k == "case" else k): v for k, v in cell.items()})
        mdict.update({"job_id": str(row["job_id"]), "best_cost": float(row["best_cost"])})
        mat_path = out / f"{stem}.mat"
        savemat(mat_path, mdict)
        written += [json_path.name, mat_path.name]
        index.append({**cell, "job_id": row["job_id"], "best_cost": row["best_cost"],
                      "json": json_path.name, "mat": mat_path.name})
    index_path = out / "index.csv"
    pd.DataFrame(index, columns=[*CELL, "job_id", "best_cost", "json", "mat"]).to_csv(
        index_path, index=False, encoding="utf-8")
    written.append(index_path.name)
    return written
