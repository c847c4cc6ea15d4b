"""The result of a run or a study: :class:`TuneResult`, :func:`load`, :func:`compare`."""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun import io, problems
from penaltyrun.errors import ConfigError

#: Columns of one cell in :meth:`TuneResult.summary`.
CELL = ["problem", "case", "variant", "param", "optimizer"]


@dataclass(frozen=True)
class Best:
    """The best start of a result (lowest cost among the converged starts, or among all
    starts when none converged).

    Attributes
    ----------
    matrices : dict of str → ndarray, shape (n, n)
        Its penalty matrices.
    scalars : dict of str → float
        Its extra scalar variables (empty for most problems).
    cost : float
        Its cost (the problem's cost unit).
    converged : bool
        Whether that start is a converged one (status ``ok``, converged best candidate).
    job_id, param, optimizer : str
        The job it comes from, its map and optimizer.
    """

    matrices: dict[str, np.ndarray] = field(default_factory=dict)
    scalars: dict[str, float] = field(default_factory=dict)
    cost: float = math.nan
    converged: bool = False
    job_id: str = ""
    param: str = ""
    optimizer: str = ""


def _converged(df: pd.DataFrame) -> pd.Series:
    from penaltyrun.report.stats import converged

    return converged(df)


@contextlib.contextmanager
def _holding(objects: list[Any]) -> Iterator[None]:
    """Hold the in-memory problems ``objects`` (for the report to rebuild them)."""
    with contextlib.ExitStack() as stack:
        for obj in {id(o): o for o in objects if o is not None}.values():
            stack.enter_context(problems.hold(obj))
        yield


class TuneResult:
    """Records of a run (or a study) with its best start, a summary and the report.

    Parameters
    ----------
    run_dir : Path
        The run (or study) folder.
    source : Path, optional
        The results file or folder to read (default ``run_dir``).
    problem : problem object, optional
        The in-memory problem the run tuned (lets :meth:`report` rebuild it).
    """

    def __init__(self, run_dir: str | Path, source: str | Path | None = None,
                 problem: Any = None) -> None:
        self.run_dir = Path(run_dir)
        self.source = Path(source) if source is not None else self.run_dir
        self.problem = problem
        self._records: pd.DataFrame | None = None

    def __repr__(self) -> str:
        return f"TuneResult({str(self.run_dir)!r}, {len(self.records)} starts)"

    @property
    def records(self) -> pd.DataFrame:
        """One row per start, the columns of ``results.parquet``
        (:mod:`penaltyrun.io.schema`; JSON columns stay text, see
        :func:`penaltyrun.io.decode_json`) and ``status_known``, which the reader adds:
        False for a status this version does not know (listed, never counted as
        converged; :func:`penaltyrun.io.read_results`)."""
        if self._records is None:
            self._records = io.read_results(self.source)
        return self._records

    @property
    def best(self) -> Best:
        """The best start (see :class:`Best`)."""
        df = self.records
        ok = _converged(df)
        pool = df[ok] if ok.any() else df
        costs = pd.to_numeric(pool["best_cost"], errors="coerce")
        if costs.notna().sum() == 0:
            return Best()
        row = pool.loc[costs.idxmin()]
        mats = io.decode_json(row["matrices"]) or {}
        return Best(matrices={k: np.asarray(v, dtype=float) for k, v in mats.items()},
                    scalars={k: float(v) for k, v in
                             (io.decode_json(row.get("scalars")) or {}).items()},
                    cost=float(row["best_cost"]), converged=bool(ok.any()),
                    job_id=str(row["job_id"]), param=str(row["param"]),
                    optimizer=str(row["optimizer"]))

    def summary(self) -> pd.DataFrame:
        """One row per cell (problem, case, variant, map, optimizer; a variant labels runs
        with other problem or optimizer settings, as in the report): ``n_starts``,
        ``converged`` (share of converged starts), ``best_cost`` and ``median_cost`` (over
        the converged starts, NaN when none converged), ``median_evals``."""
        from penaltyrun.report import protocol
        from penaltyrun.report.stats import add_variant

        protocol.reset()
        with _holding([self.problem]):
            df = add_variant(self.records)
        df = df.assign(_ok=_converged(df))
        rows = []
        for key, g in df.groupby(CELL, sort=True):
            costs = pd.to_numeric(g.loc[g["_ok"], "best_cost"], errors="coerce").dropna()
            rows.append({**dict(zip(CELL, key)), "n_starts": len(g),
                         "converged": float(g["_ok"].mean()),
                         "best_cost": float(costs.min()) if len(costs) else math.nan,
                         "median_cost": float(costs.median()) if len(costs) else math.nan,
                         "median_evals": float(pd.to_numeric(g["n_evals"],
                                                             errors="coerce").median())})
        return pd.DataFrame(rows, columns=[*CELL, "n_starts", "converged", "best_cost",
                                           "median_cost", "median_evals"])

    def report(self, out_dir: str | Path | None = None, paper: bool = True,
               workers: int | str = 1, cache_dir: str | Path | None = None) -> Path:
        """Write the report of these results (what ``penaltyrun-report`` writes: tables,
        figures, ``report.md``, ``report.html``) and return its folder.

        Parameters
        ----------
        out_dir : str or Path, optional
            Output folder (default ``<run_dir>/report``).
        paper : bool
            Put the paper's numbers beside these where it reports them.
        workers : int or "auto"
            Processes writing the sections of different problem cases (``auto``: one per
            core), as ``penaltyrun-report --workers``; results of a problem object held in
            this process are always reported in this process.
        cache_dir : str or Path, optional
            Cache of drawn case sections, as ``penaltyrun-report --cache-dir``: sections
            drawn before with the same rows and code are copied from it (the same files).
            Default: none, every section is drawn.

        Raises
        ------
        ConfigError
            ``workers`` is not a positive integer or ``auto``.
        """
        from penaltyrun import report

        out = Path(out_dir) if out_dir is not None else self.run_dir / "report"
        with _holding([self.problem]):
            report.build_report(self.source, out, paper=paper, workers=workers,
                                cache_dir=cache_dir)
        return out


def folder_argument(value: Any, key: str) -> Path:
    """``value`` (a folder given to the Python API) as a Path.

    Raises
    ------
    ConfigError
        On ``key``: not a str or os.PathLike (e.g. a number or None).
    """
    if not isinstance(value, (str, os.PathLike)):
        raise ConfigError(key, f"must be a path (str or Path), got {type(value).__name__}")
    return Path(value)


def load(path: str | Path, *, problem: Any = None) -> TuneResult:
    """The results of a run folder, a study folder (``studies/<name>``), any folder with
    ``results.parquet`` files below it (e.g. the parent of several runs), or one
    ``results.parquet`` file.

    Parameters
    ----------
    path : str or Path
    problem : problem object or str, optional
        The in-memory problem (:func:`~penaltyrun.from_cost`) the results come from, or
        the dotted path of the problem module outside penaltyrun they were run with
        (``"my_pkg.my_module"``), so that :meth:`TuneResult.report` can rebuild it.
        Reading results never imports a module named in them: without this, the report
        of a problem outside penaltyrun works from the stored columns alone.
        penaltyrun's own problems need nothing.

    Raises
    ------
    ConfigError
        ``path`` does not exist.
    FileNotFoundError, ResultsUnreadableError
        No results file, or none readable, under ``path`` (when the records are read).
    """
    path = folder_argument(path, "path")
    if not path.exists():
        raise ConfigError("path", f"{path} does not exist")
    if problem is not None:
        from penaltyrun.api.tuning import resolve_problem

        name, module, _ = resolve_problem(problem)  # a name, a module path or an object
        if isinstance(problem, str):
            if module:
                problems.register(name, module)
            problem = None
    if path.is_file():
        return TuneResult(path.parent, path, problem=problem)
    own = path / io.RESULTS_FILE
    return TuneResult(path, own if own.is_file() else path, problem=problem)


def _records(result: Any) -> tuple[pd.DataFrame, Any]:
    if isinstance(result, TuneResult):
        return result.records, result.problem
    if isinstance(result, pd.DataFrame):
        return result, None
    if isinstance(result, (str, Path)):
        return load(result).records, None
    raise ConfigError("compare", f"expected a TuneResult, a DataFrame of records or a "
                      f"path, got {type(result).__name__}")


def compare(result_a: Any, result_b: Any) -> pd.DataFrame:
    """The map-vs-map statistics of two results, as the report's comparison table.

    Every pair of maps within each (problem, case, variant, optimizer) of the two results
    together: converged counts, success rates, medians, the change of the median in %, the
    Vargha–Delaney A12, the Mann–Whitney U p-value and its Holm adjustment (see
    :func:`penaltyrun.report.compare.pairwise`).

    Parameters
    ----------
    result_a, result_b : TuneResult, DataFrame of records, or path
        E.g. the diagonal and the full run of one problem.

    Returns
    -------
    DataFrame
        One row per pair of maps (``map_a``, ``map_b``, ``median_a``, ``median_b``,
        ``a12_b_beats_a``, ``p_mwu``, ``p_holm``, ...). The maps of a pair are in the
        report's order (the diagonal first), whatever the order of the two arguments:
        ``a12_b_beats_a`` is the probability that a start of ``map_b`` beats one of
        ``map_a``.
    """
    from penaltyrun.report import protocol
    from penaltyrun.report.compare import pairwise
    from penaltyrun.report.stats import add_variant

    (df_a, prob_a), (df_b, prob_b) = _records(result_a), _records(result_b)
    both = pd.concat([df_a, df_b], ignore_index=True).drop_duplicates("job_id")
    protocol.reset()  # problem modules as they are now, not as an earlier call saw them
    with _holding([prob_a, prob_b]):
        return pairwise(add_variant(both))


__all__ = ["Best", "TuneResult", "compare", "load"]
