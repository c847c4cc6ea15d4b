"""``penaltyrun mode=plan <overrides>``: the forecast of a run (or a whole ``-m`` sweep) on
one screen, without running it.

The cells are the ones Hydra would run: with ``-m``, the product of the sweeps of the
command line and of the config's ``hydra.sweeper.params`` (as Hydra's basic sweeper builds
it, :func:`sweep_combinations`); without, the one cell of the command line. For each cell
the jobs are planned exactly as a run plans them
(:meth:`penaltyrun.runner.spec.RunSpec.plan`) and forecast by
:func:`penaltyrun.runner.forecast.forecast_cell` (budgets from the optimizer settings, CPU
per evaluation from ``runner.forecast_samples`` random candidates, measured once per
problem, case and map). Nothing is written: no run directory, no records.

Hydra's multirun runs the cells one after another, each cell's jobs in parallel; the
screen gives the wall time of that, and for a cluster also of all cells at once (one
``penaltyrun`` per cell against the same scheduler; README "Scaling out").
"""

from __future__ import annotations

import itertools
import json
import sys
from collections.abc import Sequence
from typing import Any

from omegaconf import DictConfig

from penaltyrun.cli import spec as cells
from penaltyrun.cli import userconf
from penaltyrun.errors import ConfigError
from penaltyrun.runner import forecast as fc
from penaltyrun.runner.options import available_cores

#: Hydra's own flags: with one of them Hydra handles the command line (e.g. ``--cfg job``).
HYDRA_FLAGS = ("--cfg", "-c", "--help", "-h", "--hydra-help", "--info", "-i",
               "--shell-completion", "-sc", "--resolve", "--package", "-p")


def intercepts(argv: list[str]) -> bool:
    """Whether ``penaltyrun mode=plan`` prints the plan itself: unless a Hydra flag asks
    Hydra for something else (the config, help)."""
    return not any(a.split("=", 1)[0] in HYDRA_FLAGS for a in argv)


def _first_values(parsed: Sequence[Any]) -> list[str]:
    """Task overrides with each sweep at its first value (what a single compose takes)."""
    out = []
    for o in parsed:
        if o.is_sweep_override():
            out.append(f"{o.get_key_element()}={next(iter(o.sweep_string_iterator()))}")
        else:
            out.append(o.input_line)
    return out


def sweep_combinations(parsed: Sequence[Any]) -> list[list[str]]:
    """Every cell of a multirun as its list of ``key=value`` overrides, built as Hydra's basic
    sweeper builds them: one list of values per key (a later override of a key replaces an
    earlier one, so the command line wins over ``hydra.sweeper.params``), their product in
    the order the keys first appear."""
    per_key: dict[str, list[str]] = {}
    for o in parsed:
        key = o.get_key_element()
        if not o.is_sweep_override():
            per_key[key] = [f"{key}={o.get_value_element_as_str()}"]
        elif o.is_discrete_sweep():
            per_key[key] = [f"{key}={v}" for v in o.sweep_string_iterator()]
        else:
            raise ConfigError(key, "an interval() sweep needs a sweeper plugin (optuna, ax); "
                                   "Hydra's basic sweeper runs lists and ranges: use "
                                   "choice(...) or range(...)")
    return [list(c) for c in itertools.product(*per_key.values())]


def expand_cells(argv: list[str]) -> tuple[list[DictConfig], bool]:
    """The composed config of every cell the command line would run, and whether it is a
    multirun (``-m``)."""
    from hydra import compose
    from hydra.core.override_parser.overrides_parser import OverridesParser

    source, argv = userconf.parse_source(argv)
    multirun = "-m" in argv or "--multirun" in argv
    args = [a for a in argv if ("=" in a or a.startswith("~")) and not a.startswith("-")]
    parser = OverridesParser.create()
    parsed = parser.parse_overrides(args)
    hydra_args = [o.input_line for o in parsed if o.key_or_group.startswith("hydra")
                  and not o.is_sweep_override()]
    task = [o for o in parsed if not o.key_or_group.startswith("hydra")]
    with userconf.hydra_context(source):
        userconf.give_config_loader(parsed)
        first = compose(config_name=source.config_name,
                        overrides=_first_values(task) + hydra_args, return_hydra_config=True)
        if not multirun:
            return [first], False
        sweep = dict(first.hydra.sweeper.get("params") or {})
        lines = [f"{k}={v}" for k, v in sweep.items()] + [o.input_line for o in task]
        combos = sweep_combinations(userconf.give_config_loader(parser.parse_overrides(lines)))
        return [compose(config_name=source.config_name, overrides=list(c) + hydra_args)
                for c in combos], True


def _timing_key(job: Any) -> str:
    """What the cost of one evaluation depends on: problem, case, its parameters, map."""
    return json.dumps([job.problem, job.case, job.problem_params, job.param,
                       job.param_options, job.problem_module], sort_keys=True, default=str)


def forecast_cells(cfgs: Sequence[DictConfig], stream: Any = None) -> list[fc.CellForecast]:
    """Forecast every cell; a timing is measured once per problem, case and map."""
    stream = stream or sys.stderr
    tty = bool(getattr(stream, "isatty", lambda: False)())
    timings: dict[str, fc.Timing] = {}
    out = []
    for i, cfg in enumerate(cfgs, start=1):
        spec = cells.run_spec(cfg)
        prob, _, _ = spec.build()
        jobs = spec.plan(prob.case)
        key = _timing_key(jobs[0])
        if tty:
            print(f"\rtiming cell {i}/{len(cfgs)} ...", end="", file=stream, flush=True)
        cell = fc.forecast_cell(jobs, spec.runner.forecast_samples, int(spec.runner.seed),
                                timings.get(key))
        timings[key] = cell.timing
        out.append(cell)
    if tty:
        print("\r" + " " * 40 + "\r", end="", file=stream, flush=True)
    return out


def _row(cell: fc.CellForecast, workers: int | None) -> str:
    cpu = cell.job_cpu_s
    n = len(cell.jobs)
    timing = cell.timing
    if timing.samples_s:
        per = f"{timing.mean_s:.3g} [{min(timing.samples_s):.2g}–{max(timing.samples_s):.2g}]"
    else:
        per = "not timed"
    wall = None if cpu is None or workers is None else \
        fc.job_level_wall([cpu] * n, fc.local_slots(workers))
    evals = "no bound" if cell.evals is None else f"{cell.evals:,}"
    return (f"{cell.label:<36} {n:>4} {evals:>10} {cell.extra:>6}  {per:<22} "
            f"{fc.hours(None if cpu is None else cpu * n, False):>9} "
            f"{fc.hours(wall, False):>9}")


def render(cells_fc: Sequence[fc.CellForecast], cfgs: Sequence[DictConfig],
           multirun: bool, model: fc.WallModel = fc.job_level_wall) -> str:
    """The plan screen: one row per cell, totals, this machine and 64 / 512 cores."""
    workers = cells.run_spec(cfgs[0]).runner.local_workers()
    n_jobs = sum(len(c.jobs) for c in cells_fc)
    samples = max((len(c.timing.samples_s) for c in cells_fc), default=0)
    how = "multirun: Hydra runs the cells one after another" if multirun else "one cell"
    lines = [f"penaltyrun plan: {len(cells_fc)} cell{'s' * (len(cells_fc) != 1)}, "
             f"{n_jobs} jobs ({how})",
             f"s/eval: CPU s per evaluation, mean [min–max] of {samples} random batches "
             f"of the box", "        (the optimizer's batch size; time.process_time, after one "
             "warm-up evaluation)", "",
             f"{'cell (problem/case/param/optimizer)':<36} {'jobs':>4} {'evals/job≤':>10} "
             f"{'+after':>6}  {'s/eval [min–max]':<22} {'CPU':>9} {'wall':>9}"]
    lines += [_row(c, workers) for c in cells_fc]
    known = [c for c in cells_fc if c.job_cpu_s is not None]
    per_cell = [[c.job_cpu_s] * len(c.jobs) for c in known]
    every = [cpu for jobs in per_cell for cpu in jobs]
    total_evals = sum(c.total_evals or 0 for c in cells_fc)
    here_s = None if workers is None else sum(model(j, fc.local_slots(workers))
                                              for j in per_cell)
    here = fc.hours(here_s, False)
    lines.append(f"{'total':<36} {n_jobs:>4} {total_evals:>10,} {'':>6}  {'':<22} "
                 f"{fc.hours(sum(every), False):>9} {here:>9}")
    lines.append(f"total CPU ≈ {fc.hours(sum(every))}")
    lines.append("")
    where = "a remote dask cluster (size unknown here)" if workers is None else \
        f"{workers} workers on {available_cores()} cores (runner.workers=" \
        f"{cfgs[0].runner.workers})"
    lines.append(f"this machine: {where}: wall ≈ {fc.hours(here_s)}"
                 + (", cells in turn" if multirun else ""))
    several = multirun and len(per_cell) > 1
    lines.append("wall time on a dask cluster, one job per core (runner.backend=dask):")
    lines.append(f"  {'cores':>9}  {'all cells at once':>18}  "
                 f"{'cells in turn (-m)' if several else '':>18}  {'bound*':>9}")
    for cores in fc.CLUSTER_CORES:
        in_turn = fc.hours(sum(model(j, cores) for j in per_cell)) if several else ""
        lines.append(f"  {cores:>9}  {fc.hours(model(every, cores)):>18}  {in_turn:>18}  "
                     f"{fc.hours(fc.wall_bound(every, cores)):>9}")
    lines.append("  * max(longest job, total CPU / cores): no job-level schedule is faster")
    if several:
        lines.append("  all cells at once: one penaltyrun per cell against the same scheduler "
                     "(README \"Scaling out\")")
    lines += _notes(cells_fc)
    return "\n".join(lines)


def _notes(cells_fc: Sequence[fc.CellForecast]) -> list[str]:
    """Caveats: what the numbers leave out."""
    notes = ["notes: evals/job is an upper bound (a stall rule may stop earlier); +after: the",
             "       best candidate's detailed and held-out evaluations; random candidates are",
             "       the first iteration's: later ones may be cheaper or dearer."]
    unbounded = [c.label for c in cells_fc if c.evals is None]
    if unbounded:
        notes.append(f"       no evaluation bound (left out of the totals; set "
                     f"optimizer.max_evals): {', '.join(unbounded)}")
    failed = sorted({c.timing.error for c in cells_fc if c.timing.error and
                     not c.timing.samples_s})
    notes += [f"       {err}" for err in failed]
    return notes


def run(argv: list[str]) -> None:
    """Print the plan of the command line ``argv`` (checked by the preflight already)."""
    cfgs, multirun = expand_cells(argv)
    print(render(forecast_cells(cfgs), cfgs, multirun), flush=True)


def print_cell_plan(cfg: DictConfig) -> None:
    """Print the plan of one composed config (``mode=plan`` reached inside Hydra's app)."""
    print(render(forecast_cells([cfg]), [cfg], False), flush=True)
