"""The docs check's first link: every committed study table recomputed from its data.

The results pages and the README are rendered from each study's committed tables
(``studies/NAME/tables/*.csv``); those tables come from the study's ``results.parquet`` (and
``holdout_long.parquet``, see :mod:`penaltyrun.io.longholdout`) through the report. The check
rebuilds the report's tables from the data into a temporary folder and compares them with
the committed ones: numbers to a relative 1e-9 (NaN equals NaN; the closed-loop diagnostics
recomputed from stored matrices, :data:`RECOMPUTED_COLUMNS`, to 1e-6), numbers written as
JSON arrays in a text cell (a front's points) likewise, other text exactly, and the set of
files. A table edited by hand, or data changed without regenerating the tables
(``python -m penaltyrun.docsgen study tables NAME`` rebuilds them), fails it.
"""

from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from penaltyrun.docsgen.provenance import display_path
from penaltyrun.docsgen.studies import RESULTS, TABLES, list_studies, load_study

#: Relative tolerance of the numbers in a recomputed table.
RTOL = 1e-9
#: Columns of closed-loop diagnostics that a table may recompute from the stored matrices
#: with LAPACK (Riccati solution, eigenvalues, singular values), and their tolerance: a pole
#: small against the closed loop's norm is known only to about machine epsilon times that
#: norm, and LAPACK builds for different processors round differently (a slowest pole of
#: −0.0095 1/s of an attitude LQR gain moved by 1.8e-8 of itself between two machines).
RECOMPUTED_COLUMNS = ("slowest_real", "min_damping", "gain_norm", "gain_cond")
RTOL_RECOMPUTED = 1e-6


def compare_csv(committed: Path, fresh: Path) -> str | None:
    """Why two CSV tables differ (None: they agree; see the module docstring)."""
    a, b = pd.read_csv(committed), pd.read_csv(fresh)
    if list(a.columns) != list(b.columns):
        return f"columns differ: {list(a.columns)} vs {list(b.columns)} from the data"
    if len(a) != len(b):
        return f"{len(a)} rows, {len(b)} from the data"
    for column in a.columns:
        x, y = a[column], b[column]
        if pd.api.types.is_numeric_dtype(x) and pd.api.types.is_numeric_dtype(y):
            xv, yv = x.to_numpy(float), y.to_numpy(float)
            rtol = RTOL_RECOMPUTED if column in RECOMPUTED_COLUMNS else RTOL
            bad = ~np.isclose(xv, yv, rtol=rtol, atol=0.0, equal_nan=True)
        else:
            bad = np.array([not _same_text(u, v, RTOL) for u, v in
                            zip(x.fillna("").astype(str), y.fillna("").astype(str))], bool)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            return (f"column {column!r}, row {k}: committed {x.iloc[k]!r}, from the data "
                    f"{y.iloc[k]!r}")
    return None


def _same_text(a: str, b: str, rtol: float) -> bool:
    """Whether two text cells agree: equal, or both JSON arrays of numbers of one shape
    equal to ``rtol`` (their last digits move with the processor's floating-point paths,
    as any computed number does)."""
    if a == b:
        return True
    if not (a.startswith("[") and b.startswith("[")):
        return False
    try:
        u = np.asarray(json.loads(a), dtype=float)
        v = np.asarray(json.loads(b), dtype=float)
    except (ValueError, TypeError, RecursionError):
        return False
    return u.shape == v.shape and bool(np.allclose(u, v, rtol=rtol, atol=0.0, equal_nan=True))


def check_study(root: Path, name: str) -> list[str]:
    """Differences between study ``name``'s committed tables and tables rebuilt from its
    committed data (empty when they agree or the study has no merged data)."""
    from penaltyrun.docsgen.studies import write_tables

    study = load_study(root, name)
    results, tables = study.folder / RESULTS, study.folder / TABLES
    if not results.is_file() or not tables.is_dir():
        return []
    label = display_path(results, root)
    with tempfile.TemporaryDirectory(prefix="check-tables-") as tmp:
        fresh = Path(tmp) / TABLES
        write_tables(results, Path(tmp) / "report", fresh, label=label)
        shown = display_path(tables, root)
        problems = []
        committed_csv = {p.name for p in tables.glob("*.csv")}
        fresh_csv = {p.name for p in fresh.glob("*.csv")}
        for missing in sorted(fresh_csv - committed_csv):
            problems.append(f"{shown}/{missing}: missing (the data gives this table)")
        for extra in sorted(committed_csv - fresh_csv):
            problems.append(f"{shown}/{extra}: not produced by the data")
        for file in sorted(committed_csv & fresh_csv):
            why = compare_csv(tables / file, fresh / file)
            if why:
                problems.append(f"{shown}/{file}: differs from the data ({why}); run "
                                f"`python -m penaltyrun.docsgen study tables {name}`")
    return problems


def check_all(root: Path) -> list[str]:
    """:func:`check_study` of every study under ``root``."""
    return [p for name in list_studies(root) for p in check_study(root, name)]


__all__ = ["RTOL", "check_all", "check_study", "compare_csv"]
