"""Rows whose stored matrices the report can use: those that fit their problem.

A results file can hold matrices of another problem (a key the problem does not tune) or of
the wrong size, e.g. edited or damaged data; every section that decodes a start's matrices
(best-known tables, the paper's matrices, controllers, basin maps, probes, exports) would
fail on them. :func:`fitting_rows` leaves such rows out of the report once, with one warning
per problem case naming their runs, before any section reads them.
"""

from __future__ import annotations

import pandas as pd

from penaltyrun.errors import ResultsUnreadableError
from penaltyrun.io import decode_json
from penaltyrun.report import protocol


def _misfit(value: object, sizes: dict[str, int]) -> bool:
    """Whether the stored matrices ``value`` (JSON text) lack a matrix of ``sizes`` or hold
    one of another shape (a job that stores none, e.g. one that failed, fits)."""
    try:
        mats = decode_json(value)
    except (ValueError, TypeError):
        return True
    if mats is None:
        return False
    if not isinstance(mats, dict):
        return True
    for name, size in sizes.items():
        matrix = mats.get(name)
        if not isinstance(matrix, list) or len(matrix) != size or \
                any(not isinstance(r, list) or len(r) != size for r in matrix):
            return True
    return False


def fitting_rows(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` without the rows whose ``matrices`` lack a matrix their problem tunes or hold
    one of another size than the problem's; problems that cannot be rebuilt are not
    checked, nor a frame read without its matrices. One warning per problem case.

    Raises
    ------
    ResultsUnreadableError
        No row is left.
    """
    if "matrices" not in df or df.empty:
        return df
    keep = pd.Series(True, index=df.index)
    keys = ["problem", "case", "problem_params"]
    for (problem, case, params), rows in df.groupby(keys, sort=True, dropna=False,
                                                   observed=True):
        prob = protocol.rebuild(problem, case, None if params != params else params)
        specs = getattr(prob, "matrices", None) if prob is not None else None
        if not specs:
            continue
        sizes = {spec.name: int(spec.size) for spec in specs}
        bad = rows.index[[_misfit(v, sizes) for v in rows["matrices"]]]
        if len(bad):
            keep[bad] = False
            runs = sorted({str(r) for r in df.loc[bad, "run_id"]})
            shapes = ", ".join(f"{n} {s}×{s}" for n, s in sizes.items())
            protocol.warn(f"left out {len(bad)} job(s) of {problem} / {case} whose stored "
                          f"matrices do not fit the problem ({shapes}); run(s): "
                          f"{', '.join(runs[:3])}{' ...' if len(runs) > 3 else ''}")
    if not keep.any():
        raise ResultsUnreadableError("no usable results: the stored matrices of every job "
                                     "do not fit its problem (see the warnings above)")
    return df if keep.all() else df[keep]
