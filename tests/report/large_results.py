"""Synthetic large results sets for memory tests of the report (not a test module).

:func:`write_large_results` writes ``rows`` job rows of the real results schema as one
Parquet file, row group by row group, so that writing never holds the whole set: Zermelo
jobs of several optimizers × maps × budgets (cells), each start with a best cost, an
evaluation count and a short anytime trace, a few per cell diverged.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from penaltyrun.io.schema import RESULTS_FILE, ROW_GROUP_ROWS, SCHEMA
from penaltyrun.jobrecord import SCHEMA_VERSION

#: Cells of a synthetic set: (optimizer, map, max_evals).
CELLS = tuple((opt, param, budget) for opt in ("pso", "de") for param in ("diagonal", "full")
              for budget in (200, 400, 800))
#: Rows per row group written: as penaltyrun writes results files.
GROUP_ROWS = ROW_GROUP_ROWS
#: Anytime trace points of every start.
TRACE_POINTS = 4


def _group(first: int, n: int, rng: np.random.Generator) -> pa.Table:
    """Rows ``first .. first + n`` (start index ``i``: cell ``i % len(CELLS)``); each
    start's gain K = [[a, b], [b, c]] is positive definite, b = 0 under the diagonal map."""
    index = np.arange(first, first + n)
    cell = index % len(CELLS)
    opt = np.array([c[0] for c in CELLS])[cell]
    param = np.array([c[1] for c in CELLS])[cell]
    budget = np.array([c[2] for c in CELLS])[cell]
    start = index // len(CELLS)
    cost = 10.0 + rng.gamma(2.0, 0.05, n) - 0.05 * (param == "full")
    ok = rng.random(n) > 0.02
    evals = (budget * rng.uniform(0.6, 1.0, n)).astype(np.int64)
    trace_e = np.sort(rng.integers(1, evals[:, None] + 1, (n, TRACE_POINTS)), axis=1)
    gain = rng.gamma(1.0, 0.3, (n, TRACE_POINTS))
    gain[:, -1] = 0.0
    trace_b = cost[:, None] + gain[:, ::-1].cumsum(axis=1)[:, ::-1]  # best so far, to cost
    k = rng.uniform(0.2, 2.0, (n, 3))
    k[:, 1] = rng.uniform(-0.5, 0.5, n) * np.sqrt(k[:, 0] * k[:, 2]) * (param == "full")
    matrices = [json.dumps({"K": [[a, b], [b, c]]}) for a, b, c in k.tolist()]
    settings = [json.dumps({"n_particles": 20, "iters": int(b) // 20}) for b in budget]

    def lists(values: np.ndarray, typ: pa.DataType) -> pa.Array:
        offsets = pa.array(np.arange(0, values.size + 1, values.shape[1], dtype=np.int32))
        return pa.ListArray.from_arrays(offsets, pa.array(values.ravel(), typ))

    data = {
        "run_id": pa.array(np.char.add("run", (cell % 3).astype(str))),
        "job_id": pa.array([f"zermelo-default-{p}-{o}-b{b}-s{s:07d}"
                            for p, o, b, s in zip(param, opt, budget, start)]),
        "problem": pa.array(np.full(n, "zermelo")), "case": pa.array(np.full(n, "default")),
        "param": pa.array(param), "optimizer": pa.array(opt),
        "start": pa.array(start), "seed": pa.array(index),
        "status": pa.array(np.where(ok, "ok", "diverged")),
        "best_cost": pa.array(np.where(ok, cost, 1e6 + cost)),
        "best_converged": pa.array(ok), "n_evals": pa.array(evals),
        "matrices": pa.array(matrices), "scalars": pa.array(np.full(n, "{}")),
        "trace_evals": lists(trace_e, pa.int64()), "trace_best": lists(trace_b, pa.float64()),
        "max_evals": pa.array(budget.astype(np.int64)),
        "optimizer_settings": pa.array(settings),
        "config_hash": pa.array(np.char.add("h", (cell % len(CELLS)).astype(str))),
        "git_commit": pa.array(np.full(n, "synthetic")),
        "schema_version": pa.array(np.full(n, SCHEMA_VERSION, dtype=np.int64)),
    }
    columns = [data[f.name] if f.name in data else pa.nulls(n, f.type) for f in SCHEMA]
    return pa.Table.from_arrays(columns, schema=SCHEMA)


def write_large_results(folder: Path, rows: int, seed: int = 0) -> Path:
    """Write ``rows`` synthetic job rows to ``folder/results.parquet``; returns the path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / RESULTS_FILE
    rng = np.random.default_rng(seed)
    with pq.ParquetWriter(path, SCHEMA) as writer:
        for first in range(0, rows, GROUP_ROWS):
            writer.write_table(_group(first, min(GROUP_ROWS, rows - first), rng))
    return path
