"""Rows whose stored matrices the report can use: those that fit their problem.

A results file can hold matrices of another problem (a key the problem does not tune), of
the wrong size, or that no search of the problem can give (not symmetric positive definite,
eigenvalues outside the problem's bounds), e.g. edited or damaged data; every section that
decodes a start's matrices (best-known tables, the paper's matrices, controllers, basin
maps, probes, exports) would fail on them. :func:`fitting_rows` leaves such rows out of the
report once, with one warning per problem case naming their runs (and files, where the frame
says where its rows come from), before any section reads them.
"""

from __future__ import annotations

import pandas as pd

from penaltyrun.errors import ConfigError, ResultsUnreadableError
from penaltyrun.io import decode_json
from penaltyrun.io.filecheck import SOURCE
from penaltyrun.problems.base import spd_spectrum
from penaltyrun.report import protocol

#: Slack of the eigenvalue bounds a stored matrix is checked against, relative to the bound
#: and to the matrix's largest eigenvalue: the eigenvalues of Q Λ Qᵀ recomputed from its
#: JSON differ from Λ by rounding of the order of 1e-16 times the largest.
BOUND_SLACK, SPECTRUM_SLACK = 1e-6, 1e-12


def _misfit(value: object, specs: dict[str, tuple[int, float, float]]) -> bool:
    """Whether the stored matrices ``value`` (JSON text) lack a matrix of ``specs`` (name →
    size, lower and upper eigenvalue bound) or hold one that is not a symmetric
    positive-definite matrix of that size with its eigenvalues within the bounds (a job
    that stores none, e.g. one that failed, fits)."""
    try:
        mats = decode_json(value)
    except (ValueError, TypeError):
        return True
    if mats is None:
        return False
    if not isinstance(mats, dict):
        return True
    for name, (size, lower, upper) in specs.items():
        try:  # a missing matrix, another shape, ragged or non-numeric rows: refused too
            _, eig = spd_spectrum(name, mats.get(name), size)
        except ConfigError:
            return True
        slack = SPECTRUM_SLACK * eig[-1]
        if eig[0] < lower * (1.0 - BOUND_SLACK) - slack or \
                eig[-1] > upper * (1.0 + BOUND_SLACK) + slack:
            return True
    return False


def fitting_rows(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` without the rows whose ``matrices`` lack a matrix their problem tunes or hold
    one of another size than the problem's, not symmetric positive definite, or with
    eigenvalues outside the problem's bounds; problems that cannot be rebuilt are not
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
        fits = {spec.name: (int(spec.size), *(float(b) for b in spec.eig_bounds))
                for spec in specs}
        bad = rows.index[[_misfit(v, fits) for v in rows["matrices"]]]
        if len(bad):
            keep[bad] = False
            runs = sorted({str(r) for r in df.loc[bad, "run_id"]})
            files = sorted({str(f) for f in df.loc[bad, SOURCE]}) if SOURCE in df else []
            shapes = ", ".join(f"{n} {s}×{s}, eigenvalues {lo:g} to {hi:g}"
                               for n, (s, lo, hi) in fits.items())
            protocol.warn(f"left out {len(bad)} job(s) of {problem} / {case} whose stored "
                          f"matrices do not fit the problem ({shapes}); run(s): "
                          f"{', '.join(runs[:3])}{' ...' if len(runs) > 3 else ''}"
                          + (f"; file(s): {', '.join(files[:3])}"
                             f"{' ...' if len(files) > 3 else ''}" if files else ""))
    if not keep.any():
        raise ResultsUnreadableError("no usable results: the stored matrices of every job "
                                     "do not fit its problem (see the warnings above)")
    return df if keep.all() else df[keep]
