"""One section of the report per problem × case × variant, and the workers that write them.

A section holds the case's cells and map-against-map tests, its figures, the problem's own
plots, the tuned controllers, basin maps, the cliff probe, the paper's values and the
held-out results. Sections of different problem cases are independent:
:func:`write_sections` writes them in this process or in worker processes
(:mod:`penaltyrun.report.parallel`), bundled by problem case so that the variants of a case
share its simulations, and returns their lines in the report's order either way.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun import problems
from penaltyrun.problems import trust
from penaltyrun.report import (
    basins,
    cache,
    cliffs,
    controllers,
    figures,
    holdout,
    parallel,
    protocol,
    sections,
)
from penaltyrun.report.rows import groups
from penaltyrun.report.tables import StemBook, fmt, markdown, md_line, md_text

logger = logging.getLogger(__name__)

#: Keys of a case section.
CASE_KEYS = ["problem", "case", "variant"]
CELL_COLUMNS = ["optimizer", "param", "budget", "converged", "best", "median", "median 95 % CI",
                "mean", "worst", "paper mean"]
COMPARISON_COLUMNS = ["optimizer", "map_a", "map_b", "n", "budgets (max_evals; spent)",
                      "median_a", "median_b", "A12 (b beats a)", "Holm p", "note"]


def _cells(summary: pd.DataFrame, g: pd.DataFrame, paper: bool) -> pd.DataFrame:
    first = g.iloc[0]
    sel = summary[(summary["problem"] == first["problem"]) & (summary["case"] == first["case"])
                  & (summary["variant"] == first["variant"])].copy()
    limits = {key: _own_limit(c) for key, c in g.groupby(["optimizer", "param"])}
    sel["budget"] = [f"{fmt(m) if np.isfinite(m) else limits.get((o, p), 'none')}; "
                     f"spent {fmt(e, 4)}" for m, e, o, p in
                     zip(sel["max_evals"], sel["mean_evals"], sel["optimizer"], sel["param"])]
    sel["converged"] = [f"{c}/{n}" for c, n in zip(sel["n_converged"], sel["n_jobs"])]
    sel["median 95 % CI"] = [note or f"{fmt(lo, 6)} – {fmt(hi, 6)}" for lo, hi, note in
                             zip(sel["median_ci95_lo"], sel["median_ci95_hi"], sel["ci_note"])]
    sel["paper mean"] = sel["paper_mean"] if paper else np.nan
    return sel


#: Population-size and iteration-limit settings (first present is shown).
SIZE_KEYS = ("n_particles", "swarm_size", "popsize")
ITER_KEYS = ("iters", "max_iterations")


def _own_limit(cell: pd.DataFrame) -> str:
    """An optimizer's own limit when it has no ``max_evals``: e.g. ``30 × 100 iters``."""
    settings = protocol.params_of(cell["optimizer_settings"].iloc[0]) \
        if "optimizer_settings" in cell else {}
    size = next((settings[k] for k in SIZE_KEYS if settings.get(k)), None)
    iters = next((f"{settings[k]} {k}" for k in ITER_KEYS if settings.get(k)), None)
    if size and iters:
        return f"{size} × {iters}"
    return iters or "none"


def _comparisons(comp: pd.DataFrame, g: pd.DataFrame) -> pd.DataFrame:
    first = g.iloc[0]
    if comp.empty:
        return comp
    sel = comp[(comp["problem"] == first["problem"]) & (comp["case"] == first["case"])
               & (comp["variant"] == first["variant"])].copy()
    sel["n"] = [f"{a}/{b}" for a, b in zip(sel["n_a"], sel["n_b"])]
    sel["budgets (max_evals; spent)"] = [
        f"{fmt(ma) if np.isfinite(ma) else 'none'}/{fmt(mb) if np.isfinite(mb) else 'none'}; "
        f"{fmt(ea, 4)}/{fmt(eb, 4)}"
        + (f"; polish {fmt(pa, 4)}/{fmt(pb, 4)}" if np.isfinite(pa) or np.isfinite(pb) else "")
        for ma, mb, ea, eb, pa, pb in
        zip(sel["max_evals_a"], sel["max_evals_b"], sel["evals_a"], sel["evals_b"],
            sel["polish_evals_a"], sel["polish_evals_b"])]
    sel["A12 (b beats a)"] = [f"{fmt(a, 2)} ({m})" if np.isfinite(a) else "—"
                              for a, m in zip(sel["a12_b_beats_a"], sel["a12_magnitude"])]
    sel["Holm p"] = sel["p_holm"]
    return sel


def case_lines(g: pd.DataFrame, ctx: dict, out: Path, paper: bool, stem: str) -> list[str]:
    """The Markdown lines of one problem × case × variant section (rows ``g``), its figures
    written into ``out`` named with ``stem``; ``ctx`` holds the report's shared tables."""
    first = g.iloc[0]
    variant = first["variant"]
    heading = title(first["problem"], first["case"], variant)
    plain = f"{first['problem']} / {first['case']}" + (f" [{variant}]" if variant else "")
    info = protocol.info_of(g)
    lines = [f"## {heading}", "", f"Cost: {info.cost_label}. Budget: `max_evals`, or the "
             "optimizer's own limit (population × iterations); then the mean evaluations "
             "spent per start.", "",
             markdown(_cells(ctx["summary"], g, paper), CELL_COLUMNS), ""]
    comp = _comparisons(ctx["comp"], g)
    if not comp.empty:
        lines += ["### Map vs map, same optimizer and variant", "",
                  "Tested only where the budgets are equal; Holm p over the family declared in "
                  "Statistics.", "", markdown(comp, COMPARISON_COLUMNS), ""]
    steps = [("figures", lambda: _figures(g, ctx["bk"], out, stem, plain, info, paper)),
             ("problem plots", lambda: sections.plots_section(g, out, stem)),
             ("tuned controllers", lambda: controllers.section(g, out, stem)),
             ("basins of attraction", lambda: basins.section(g, out, stem,
                                                             ctx["basin_points"])
              if ctx["basin_points"] > 0 else []),
             ("cliffs", lambda: cliffs.section(g, out, stem, ctx["probes"])
              if ctx["probe"] else []),
             ("paper values", lambda: sections.paper_section(g, ctx["paper"],
                                                             ctx["paper_matrices"])
              if paper else []),
             ("held-out", lambda: holdout.problem_section(g, ctx["held"], ctx["imps"], out)
              if not variant or variant == first["problem_variant"] else [])]
    for name, step in steps:
        try:
            lines += step()
        except Exception as exc:  # a figure that cannot be drawn must not lose the tables
            logger.warning("%s of %s failed: %s", name, plain, exc)
            lines += [md_line(f"({name} failed: {exc!r})"), ""]
    return lines


def title(problem: str, case: str, variant: str) -> str:
    """``problem / case [variant]`` as inert Markdown (names from the data escaped)."""
    return f"{md_text(problem)} / {md_text(case)}" + (f" [{md_text(variant)}]"
                                                      if variant else "")


def _figures(g: pd.DataFrame, bk: pd.DataFrame, out: Path, stem: str, title: str,
             info: object, paper: bool) -> list[str]:
    label = info.cost_label
    lines = []
    for name, path in (
            ("anytime", figures.anytime(g, bk, label, title, out / f"anytime_{stem}.png")),
            ("ECDF", figures.ecdf_figure(g, bk, title, out / f"ecdf_{stem}.png")),
            ("costs", figures.cost_distribution(
                g, label, f"{title}: best cost per converged start", out / f"costs_{stem}.png",
                info.paper if paper else None))):
        if isinstance(path, str):
            lines += [path, ""]
        elif path is not None:
            lines += [f"![{name}]({path.name})", ""]
    if not any(line.startswith("![anytime]") for line in lines):
        lines += ["(no anytime traces in these results — older schema: anytime and ECDF "
                  "figures skipped)", ""]
    return lines


#: Tables and settings every section reads (built once by the report, sent once to each
#: worker, part of the key of a cached section).
SHARED = ("summary", "comp", "bk", "held", "imps", "paper", "paper_matrices",
          "basin_points", "probe", "probes")


def write_sections(df: pd.DataFrame, ctx: dict[str, Any], out: Path, paper: bool,
                   workers: int, done: Callable[[str], None]) -> Iterator[list[str]]:
    """The lines of each case section of ``df``, in the order of
    ``df.groupby(CASE_KEYS, sort=True)``.

    Parameters
    ----------
    df : DataFrame
        The report's rows.
    ctx : dict
        The shared tables (:data:`SHARED`) and ``cache``, the
        :class:`~penaltyrun.report.cache.SectionCache` of the sections (None: no cache).
    out : Path
        Folder of the figures.
    paper : bool
        Show the paper's values.
    workers : int
        Processes writing sections: 1 writes them in this process (without a cache, with
        one section's rows copied out of ``df`` at a time); more start a pool of
        ``min(workers, problem cases)`` workers.
    done : callable
        Called with each section's name when it is written (progress).
    """
    stems = StemBook()
    n_cases = df.groupby(CASE_KEYS[:2], sort=True).ngroups
    in_process = workers <= 1 or n_cases <= 1 or _held_in_memory()
    if in_process and ctx.get("cache") is None:  # no bundle to key: a section's rows at a time
        for key, g in groups(df, CASE_KEYS):
            lines = case_lines(g, ctx, out, paper, stems.stem(*key))
            done(_name(key))
            yield lines
        return
    bundles = _bundles(df, stems, out, paper)
    if in_process:
        for names, bundle in bundles:
            for name, lines in zip(names, _write(bundle, ctx)):
                done(name)
                yield lines
        return
    shared = {key: ctx[key] for key in SHARED}
    shared["cache"] = ctx.get("cache")
    results = parallel.ordered_map(
        _work, bundles, min(workers, n_cases), _start_worker,
        (trust.snapshot(), shared, list(protocol.WARNINGS),
         logging.getLogger().getEffectiveLevel()),
        local=lambda bundle: _write(bundle, ctx),
        done=lambda names: [done(name) for name in names])
    for written in results:
        yield from written


def _held_in_memory() -> bool:
    """Whether a problem of the results is an object held in this process (a library
    run's): worker processes could not rebuild it."""
    from penaltyrun.problems import OBJECT_PREFIX

    return any(path.startswith(OBJECT_PREFIX) for path in trust.named().values())


Bundle = tuple[Path, bool, list[tuple[pd.DataFrame, str]]]


def _bundles(df: pd.DataFrame, stems: StemBook, out: Path, paper: bool
             ) -> Iterator[tuple[list[str], Bundle]]:
    """The case sections of ``df`` bundled by problem case: (their names, (out, paper,
    [(rows, file stem), ...])), stems given in the report's order."""
    names: list[str] = []
    cases: list[tuple[pd.DataFrame, str]] = []
    current = None
    for key, g in groups(df, CASE_KEYS):
        if cases and tuple(key[:2]) != current:
            yield names, (out, paper, cases)
            names, cases = [], []
        current = tuple(key[:2])
        names.append(_name(key))
        cases.append((g, stems.stem(*key)))
    if cases:
        yield names, (out, paper, cases)


def _name(key: tuple) -> str:
    """A section's name in the progress bar: its problem, case and variant."""
    return " / ".join(str(x) for x in key if x)


def _write(bundle: Bundle, ctx: dict[str, Any]) -> list[list[str]]:
    """The lines of each section of a bundle (through the report's cache of sections when
    the bundle may be cached)."""
    out, paper, cases = bundle
    return cache.cached(ctx.get("cache") if _cacheable(cases) else None, cases, paper, ctx,
                        SHARED, out, lambda folder: [case_lines(g, ctx, folder, paper, stem)
                                                     for g, stem in cases])


def _cacheable(cases: list[tuple[pd.DataFrame, str]]) -> bool:
    """Whether a bundle's sections are a function of its rows and penaltyrun's code alone:
    a built-in problem the user did not name another module for, whose rows name no user
    code or data file (its ``CODE_PARAMS`` and ``FILE_PARAMS``)."""
    name = str(cases[0][0]["problem"].iloc[0])
    if name not in problems.REGISTRY or name in trust.named():
        return False
    named = sum(problems.user_code_params(name), ())
    return not any(protocol.params_of(value).get(param) for rows, _ in cases
                   for value in rows.get("problem_params", ()) for param in named)


#: The shared tables in a worker process (:func:`_start_worker`).
_WORKER_CTX: dict[str, Any] = {}


def _start_worker(trust_state: tuple, shared: dict[str, Any], warnings: list[str],
                  log_level: int) -> None:
    """Set a worker process up: what reading results may import, the shared tables, the
    warnings the report has given (not logged again), logging at the report's level,
    figures drawn without a display."""
    import matplotlib

    matplotlib.use("Agg")
    logging.basicConfig(level=log_level, format="%(levelname)s %(name)s: %(message)s")
    trust.restore(trust_state)
    protocol.reset()
    protocol.WARNINGS.extend(warnings)
    _WORKER_CTX.clear()
    _WORKER_CTX.update(shared)


def _work(bundle: Bundle) -> list[list[str]]:
    """A bundle's sections in a worker process (results are read: nothing named in them is
    imported)."""
    with trust.reading_results():
        return _write(bundle, _WORKER_CTX)


__all__ = ["CASE_KEYS", "CELL_COLUMNS", "COMPARISON_COLUMNS", "SHARED", "case_lines",
           "title", "write_sections"]
