"""Probe a committed study's best points for cliffs of the criterion.

``python -m penaltyrun.docsgen study probe NAME`` reads ``studies/NAME/results.parquet``,
takes each problem × case's best converged diagonal and full start (over every optimizer,
as the best-known table does), rebuilds its problem from the stored ``problem``, ``case``,
``problem_params`` and its decision layout from ``param`` and ``param_options``, and runs
:func:`penaltyrun.optim.probe.probe` around its stored ``best_z``. It writes

* ``studies/NAME/probe.csv``: one row per probed point: where it comes from, its cost
  (recomputed, and the record's), and per step of the ladder the largest relative cost
  change from moving one variable by that fraction of its range, the variable that gave it
  and how many steps changed whether the run converged; the most negative change of all
  steps and its step (a step that lowers the cost: the point is not a local minimum along
  that variable); the CPU seconds it took;
* ``studies/NAME/probe.json``: provenance (git commit, package versions, ladder).

The results pages read the CSV; nothing is evaluated when they are rendered.

``python -m penaltyrun.docsgen study store-probes NAME`` probes the points the report
probes (each problem × case × variant's best diagonal and full start, over every optimizer)
and stores the whole probes, at full precision, in ``studies/NAME/probe.parquet``
(:mod:`penaltyrun.io.storedprobe`); a report of the study reads them instead of evaluating
the same steps again.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from penaltyrun.docsgen.provenance import display_path, package_versions
from penaltyrun.docsgen.rejudge import git_commit
from penaltyrun.docsgen.studies import RESULTS, StudyError, load_study
from penaltyrun.optim.probe import CLIFF, STEPS
from penaltyrun.runner.options import resolve_workers

logger = logging.getLogger(__name__)

#: Data file and provenance file of a study's probe.
PROBE_FILE, PROBE_PROVENANCE = "probe.csv", "probe.json"
def probe_record(record: dict[str, Any], steps: tuple[float, ...] = STEPS) -> dict[str, Any]:
    """Probe one stored best point (a results row as a dict, with its ``family``); the row
    of :data:`PROBE_FILE` (:func:`penaltyrun.report.cliffs.summary`)."""
    from penaltyrun.report.cliffs import probe_row, summary

    t0 = time.process_time()
    probed = probe_row(record, steps)
    if probed is None:
        raise StudyError(f"cannot probe {record['job_id']}: problem {record['problem']!r}, "
                         f"case {record['case']!r} not rebuilt from the stored parameters")
    result, names = probed
    return summary(record, result, names, cpu_s=round(time.process_time() - t0, 1))


def best_points(df: Any) -> list[dict[str, Any]]:
    """Each problem × case's best converged diagonal and full start (the rows of
    :func:`penaltyrun.report.bestknown.best_rows`), as dicts with their ``family``."""
    from penaltyrun.report.bestknown import best_rows

    points = []
    for _, group in df.groupby(["problem", "case"], sort=True):
        for family, row in sorted(best_rows(group).items()):
            points.append({**row.to_dict(), "family": family})
    return points


def _probed(root: Path, name: str, select: Callable[[Any], list[dict[str, Any]]],
            work: Callable[..., dict[str, Any]], steps: tuple[float, ...],
            workers: int | str, label: str,
            described: Callable[[dict[str, Any]], str] = lambda row: ""
            ) -> tuple[Any, list[dict[str, Any]]]:
    """Study ``name`` and ``work(point, steps)`` of each of its points ``select(results)``,
    in ``workers`` processes, logged as ``label`` (``described(row)`` after each).

    Raises
    ------
    StudyError
        If the study has no merged results.
    """
    from penaltyrun.io.schema import read_results

    study = load_study(root, name)
    results = study.folder / RESULTS
    if not results.is_file():
        raise StudyError(f"study {name!r} has no {RESULTS} (run `{study.make_target}`)")
    points = select(read_results(results))
    logger.info("%s %s: %d best points, ladder %s of each variable's range", label, name,
                len(points), ", ".join(f"{s:g}" for s in steps))
    rows = []
    workers = max(1, min(resolve_workers(workers), len(points) or 1))
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for row in pool.map(work, points, [steps] * len(points)):
            rows.append(row)
            logger.info("%s %s: %d/%d%s", label, name, len(rows), len(points), described(row))
    return study, rows


def probe_study(root: Path, name: str, *, workers: int | str = "auto",
                steps: tuple[float, ...] = STEPS) -> Path:
    """Probe study ``name`` (module docstring); return the written CSV.

    Raises
    ------
    StudyError
        If the study has no merged results or a point's problem cannot be rebuilt.
    """
    import pandas as pd

    from penaltyrun.report.cliffs import KEYS, step_columns

    def described(row: dict[str, Any]) -> str:
        return (f" ({row['problem']} / {row['case']}, {row['map']}): largest change "
                f"{row[step_columns(steps[-1])[0]]:.3g} % at {steps[-1]:g}")

    study, rows = _probed(root, name, best_points, probe_record, steps, workers, "probe",
                          described)
    columns = KEYS + [c for s in steps for c in step_columns(s)]  # the CSV's fixed order
    path, tmp = study.folder / PROBE_FILE, study.folder / (PROBE_FILE + ".tmp")
    pd.DataFrame(rows, columns=columns).to_csv(tmp, index=False, float_format="%.6g")
    os.replace(tmp, path)  # a reader never sees half a file
    info = {"git_commit": git_commit(root), "packages": package_versions(),
            "steps": list(steps), "cliff_threshold": CLIFF, "points": len(rows)}
    tmp = study.folder / (PROBE_PROVENANCE + ".tmp")
    tmp.write_text(json.dumps(info, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, study.folder / PROBE_PROVENANCE)
    logger.info("probe %s: wrote %s", name, display_path(path, root))
    return path


def stored_record(record: dict[str, Any], steps: tuple[float, ...] = STEPS
                  ) -> dict[str, Any]:
    """Probe one stored best point (a results row as a dict); the row of
    :data:`penaltyrun.io.storedprobe.PROBE_FILE`."""
    from penaltyrun.io import storedprobe
    from penaltyrun.report.cliffs import probe_row

    probed = probe_row(record, steps)
    if probed is None:
        raise StudyError(f"cannot probe {record['job_id']}: problem {record['problem']!r}, "
                         f"case {record['case']!r} not rebuilt from the stored parameters")
    return storedprobe.record(record["job_id"], record.get("config_hash"),
                              record["best_z"], probed[0])


def report_points(df: Any) -> list[dict[str, Any]]:
    """The points the report probes: each problem × case × variant's best converged
    diagonal and full start (:func:`penaltyrun.report.cliffs.section`), as dicts."""
    from penaltyrun.report.bestknown import best_rows
    from penaltyrun.report.cases import CASE_KEYS
    from penaltyrun.report.fitting import fitting_rows
    from penaltyrun.report.stats import add_variant

    frame = fitting_rows(add_variant(df))
    points = {}
    for _, group in frame.groupby(CASE_KEYS, sort=True):
        for _, row in sorted(best_rows(group).items()):
            points.setdefault((row["job_id"], str(row.get("config_hash"))), row.to_dict())
    return list(points.values())


def store_probes(root: Path, name: str, *, workers: int | str = "auto",
                 steps: tuple[float, ...] = STEPS) -> Path:
    """Probe the report's points of study ``name`` and write them to
    ``studies/NAME/probe.parquet`` (module docstring); return its path.

    Raises
    ------
    StudyError
        If the study has no merged results or a point's problem cannot be rebuilt.
    """
    from penaltyrun.io import storedprobe

    study, rows = _probed(root, name, report_points, stored_record, steps, workers,
                          "store-probes")
    info = {"git_commit": git_commit(root), "packages": package_versions(),
            "steps": list(steps), "points": len(rows)}
    path = storedprobe.write(study.folder / storedprobe.PROBE_FILE, rows, info)
    logger.info("store-probes %s: wrote %s", name, display_path(path, root))
    return path


def read_probe(root: Path, name: str) -> Any:
    """The committed probe of study ``name`` as a DataFrame, or None without one."""
    import pandas as pd
    path = Path(root) / "studies" / name / PROBE_FILE
    return pd.read_csv(path) if path.is_file() else None


def cliff_table(root: Path, name: str, spec: str = ".3g") -> str:
    """The probe of study ``name`` as Markdown (:func:`penaltyrun.report.cliffs.summary_table`,
    the report's table of the same probe): per best point, the largest relative cost
    change (%) at each step of the ladder, the smallest step that reaches a cliff
    (:data:`~penaltyrun.optim.probe.CLIFF`) and the most negative change found; a note
    naming the command where the study has no probe."""
    from penaltyrun.docsgen.layout import markdown_table
    from penaltyrun.report.cliffs import summary_table

    frame = read_probe(root, name)
    if frame is None:
        return (f"*`{name}` has no probe of its best points (`python -m penaltyrun.docsgen "
                f"study probe {name}`).*")
    return markdown_table(summary_table(frame, spec), spec)


def cliff_counts(root: Path, name: str, within: float = 1e-4) -> dict[str, int]:
    """Of the probed best points of study ``name``: how many (``points``), how many reach a
    cliff with a step of at most ``within`` of a variable's range (``cliffs``), and how many
    a step of the ladder made cheaper (``improved``: not a local minimum at that scale).
    All 0 without a probe."""
    frame = read_probe(root, name)
    if frame is None:
        return {"points": 0, "cliffs": 0, "improved": 0}
    step = frame["smallest_cliff_step"]
    return {"points": int(len(frame)), "cliffs": int((step.notna() & (step <= within)).sum()),
            "improved": int((frame["lowest_change_pct"] < 0).sum())}


#: Distance (rad) from a jump of the map under which a best point counts as on it.
MAP_JUMP_WITHIN = 1e-4
#: Uniformly random points of a box drawn for the baseline share, and their seed.
BASELINE_POINTS, BASELINE_SEED = 20_000, 0


def map_jumps(root: Path, name: str, within: float = MAP_JUMP_WITHIN) -> list[dict[str, Any]]:
    """Where study ``name``'s searches with a discontinuous map (GEAGSP) ended: per problem
    × case × map × optimizer, the finished starts (``starts``), how many best points lie
    within ``within`` of a jump of the map (``near``, from
    :func:`penaltyrun.report.cliffs.skip_margin`), their median margin, and the share of
    :data:`BASELINE_POINTS` uniformly random points of the same box that are as close
    (``baseline``, seeded). Computed from the committed results when the page is rendered;
    cells whose map is continuous are left out."""
    import numpy as np

    from penaltyrun.io.schema import read_results
    from penaltyrun.jobrecord import OK
    from penaltyrun.report.cliffs import rebuilt_layout, skip_margin

    results = load_study(root, name).folder / RESULTS
    if not results.is_file():
        return []
    df = read_results(results)
    df = df[df["status"] == OK]
    out = []
    for keys, group in df.groupby(["problem", "case", "param", "optimizer"], sort=True):
        margins = np.array([m for m in (skip_margin(row) for _, row in group.iterrows())
                            if m is not None])
        if not margins.size or np.isinf(margins).all():
            continue
        layout = rebuilt_layout(group.iloc[0])[1]
        lb, ub = layout.bounds()
        box = np.random.default_rng(BASELINE_SEED).uniform(lb, ub, (BASELINE_POINTS, lb.size))
        out.append(dict(zip(["problem", "case", "param", "optimizer"], keys),
                        starts=int(margins.size), near=int((margins < within).sum()),
                        median=float(np.median(margins)),
                        baseline=float((layout.skip_margin(box) < within).mean())))
    return out
