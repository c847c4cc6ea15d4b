"""Cliff probes stored beside a results file: ``probe.parquet``.

The report probes each case's best diagonal and full point for cliffs of the criterion
(:mod:`penaltyrun.report.cliffs`): about eight evaluations per decision variable, which
for a low-thrust transfer is most of the report's CPU time. The probe is a pure function
of the stored point, its problem and the ladder of steps, so a study can store it once
(``python -m penaltyrun.docsgen study store-probes NAME``) and every later report of the
study reads it instead of evaluating again: one row per probed start with

* ``job_id``, ``config_hash``: the start (as in ``results.parquet``);
* ``best_z``: the decision vector that was probed (the report uses a row only when it is
  the start's stored ``best_z``, bit for bit);
* ``steps``: the ladder (fractions of each variable's range; used only when it is the
  report's own ladder);
* ``cost``, ``converged``: J(z) and its run's status, recomputed;
* ``change``, ``status_change``: the relative cost changes and status flips of each step,
  variable and side, flattened in (step, variable, side) order
  (:class:`~penaltyrun.optim.probe.CliffProbe`).

The file's key-value metadata (``penaltyrun``) records the git commit and package
versions that computed it. A file that fails any check (read within the limits of a
results file, columns, types, shapes) is skipped with one warning naming it, and its
probes are computed as if it were not there. Nothing read from it is ever run.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.io.filecheck import check_footer, read_bounded
from penaltyrun.io.schema import config_key
from penaltyrun.optim.probe import CliffProbe

logger = logging.getLogger(__name__)

#: File name of the stored probes, beside ``results.parquet``.
PROBE_FILE = "probe.parquet"
#: Key of the file's provenance in its Parquet key-value metadata.
METADATA_KEY = b"penaltyrun"
#: The file's schema (one definition for its writer and its reader).
SCHEMA = pa.schema([
    ("job_id", pa.string()), ("config_hash", pa.string()),
    ("best_z", pa.list_(pa.float64())), ("steps", pa.list_(pa.float64())),
    ("cost", pa.float64()), ("converged", pa.bool_()),
    ("change", pa.list_(pa.float64())), ("status_change", pa.list_(pa.bool_())),
])
#: Columns of :data:`PROBE_FILE`, in order.
COLUMNS = tuple(SCHEMA.names)


def record(job_id: str, config_hash: object, z: np.ndarray, result: CliffProbe
           ) -> dict[str, Any]:
    """One row of :data:`PROBE_FILE`: the probe ``result`` of start ``job_id`` around ``z``."""
    return {"job_id": str(job_id), "config_hash": config_key(config_hash),
            "best_z": np.asarray(z, float).tolist(),
            "steps": np.asarray(result.steps, float).tolist(), "cost": float(result.cost),
            "converged": bool(result.converged),
            "change": np.asarray(result.change, float).ravel().tolist(),
            "status_change": np.asarray(result.status_change, bool).ravel().tolist()}


def write(path: Path, rows: Iterable[dict[str, Any]], provenance: dict[str, Any]) -> Path:
    """Write ``rows`` (:func:`record`) to ``path`` with ``provenance`` in its metadata;
    written beside and renamed into place, so a reader never sees half a file."""
    path = Path(path)
    table = pa.Table.from_pylist(list(rows), schema=SCHEMA).replace_schema_metadata(
        {METADATA_KEY: json.dumps(provenance, sort_keys=True).encode()})
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)
    return path


def _checked(frame: pd.DataFrame) -> str | None:
    """Why rows read from a probe file are refused (None: they are not)."""
    for name in COLUMNS:
        if name not in frame:
            return f"no column {name}"
    for row in frame.itertuples(index=False):
        if not isinstance(row.job_id, str) or not row.job_id:
            return "a row without a job id"
        z, steps = (np.asarray(row.best_z, float), np.asarray(row.steps, float))
        if z.ndim != 1 or not z.size or not np.isfinite(z).all():
            return f"{row.job_id}: best_z is not a finite vector"
        if (steps.ndim != 1 or not steps.size or not np.isfinite(steps).all()
                or (steps <= 0).any() or (np.diff(steps) <= 0).any()):
            return f"{row.job_id}: steps are not increasing positive fractions"
        size = steps.size * z.size * 2
        if (not isinstance(row.cost, (float, np.floating)) or not np.isfinite(row.cost)
                or row.cost == 0):
            return f"{row.job_id}: cost is not a finite non-zero number"
        if not isinstance(row.converged, (bool, np.bool_)):
            return f"{row.job_id}: converged is not true or false"
        change = np.asarray(row.change, float)
        if change.shape != (size,) or np.isinf(change).any():
            return f"{row.job_id}: change does not hold {size} finite or missing values"
        flips = row.status_change
        if flips is None or len(flips) != size or any(f is None for f in flips):
            return f"{row.job_id}: status_change does not hold {size} flags"
    return None


def read_one(path: Path) -> pd.DataFrame:
    """The checked rows of the probe file ``path``.

    Raises
    ------
    ValueError, KeyError
        The file is refused (footer, size, a column or a row that fails its check).
    OSError, pyarrow.ArrowException
        It cannot be read as Parquet.
    """
    refused = check_footer(path)
    if refused:
        raise ValueError(refused)
    table = read_bounded(path, COLUMNS)
    missing = [n for n in COLUMNS if n not in table.column_names]
    if missing:
        raise KeyError(f"no column {missing[0]}")
    try:
        table = table.select(list(COLUMNS)).cast(SCHEMA.remove_metadata())
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError) as exc:
        raise ValueError(f"a column of the wrong type ({str(exc).splitlines()[0]})") from exc
    frame = table.to_pandas()
    frame["config_hash"] = [config_key(h) for h in frame["config_hash"]]
    why = _checked(frame)
    if why:
        raise ValueError(why)
    return frame


def read_beside(results: Iterable[Path | str]) -> pd.DataFrame:
    """The stored probes beside each results file of ``results`` (:data:`PROBE_FILE` in
    its folder), every file read once; a refused file is skipped with one warning naming
    it. Empty (with :data:`COLUMNS`) when there are none."""
    frames = []
    for folder in sorted({Path(p).parent for p in results}):
        path = folder / PROBE_FILE
        if not path.is_file() or path.is_symlink():
            continue
        try:
            frames.append(read_one(path))
        except (OSError, pa.ArrowException, ValueError, KeyError, TypeError,
                MemoryError) as exc:
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            logger.warning("skipped stored probe file %s: %s (its probes are computed)",
                           path, text)
    if not frames:
        return pd.DataFrame(columns=list(COLUMNS))
    return pd.concat(frames, ignore_index=True).drop_duplicates(["job_id", "config_hash"])


def lookup(stored: pd.DataFrame | None, job_id: object, config_hash: object, z: np.ndarray,
           steps: tuple[float, ...]) -> CliffProbe | None:
    """The stored probe of start ``job_id`` around exactly ``z`` with exactly the ladder
    ``steps``, or None (then the probe is computed)."""
    if stored is None or stored.empty:
        return None
    rows = stored[(stored["job_id"] == str(job_id))
                  & (stored["config_hash"] == config_key(config_hash))]
    z = np.asarray(z, float)
    for row in rows.itertuples(index=False):
        stored_z, stored_steps = np.asarray(row.best_z, float), np.asarray(row.steps, float)
        if not (stored_z.shape == z.shape and np.array_equal(stored_z, z)
                and np.array_equal(stored_steps, np.asarray(steps, float))):
            continue
        shape = (stored_steps.size, z.size, 2)
        change = np.asarray(row.change, float)
        flips = np.asarray(row.status_change, bool)
        if change.size == flips.size == stored_steps.size * z.size * 2:
            return CliffProbe(stored_steps, float(row.cost), bool(row.converged),
                              change.reshape(shape), flips.reshape(shape))
    return None


__all__ = ["COLUMNS", "METADATA_KEY", "PROBE_FILE", "SCHEMA", "lookup", "read_beside",
           "read_one", "record", "write"]
