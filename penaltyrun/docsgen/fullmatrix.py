"""The data of the explanation page "What a full matrix does", from a committed study.

A full penalty matrix tuned on one training start can lower the training cost a lot and
still leave slow, lightly damped closed-loop modes that the training start does not excite.
This module gathers, from a study's committed ``results.parquet`` (with its re-judged
``holdout_long.parquet`` applied, :mod:`penaltyrun.io.longholdout`), what the page shows:

* :attr:`Mechanism.pairs` and :attr:`Mechanism.ratios`: every held-out pairing of the
  report's held-out table (:func:`penaltyrun.report.holdout.holdout_rows`: each cell's best
  diagonal start against the best start of each full map, and the best-known pair), with the
  per-scenario cost ratios J_full / J_diag;
* :attr:`Mechanism.modes`: every converged start's training cost and slowest closed-loop
  real part max Re s (:func:`penaltyrun.report.controllers.start_modes`: the stored column,
  else recomputed from the stored matrices through the problem's ``closed_loop`` hook);
* :attr:`Mechanism.cells`: one row per problem × case with the best-known diagonal and full
  starts (training cost, closed-loop diagnostics of
  :func:`penaltyrun.problems.diagnostics.diagnose`), their held-out ratio statistics and
  Spearman's ρ between the full starts' training cost and their slowest decay rate −max Re s;
* :func:`example_scenario`: one held-out scenario of one cell (the scenario whose ratio is
  closest to the pair's median ratio), whose trajectories :func:`simulate_example`
  integrates.

:mod:`penaltyrun.docsgen.fullmatrix_plots` draws the figures, and the page's template
(``studies/templates/explanation/full-matrix.md``) reads every number through
:class:`Page`, so a number edited by hand fails ``make check-docs``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.docsgen.studies import RESULTS, load_study
from penaltyrun.problems.hooks import hooks

#: Folder of the page's figures, relative to the page.
FIGURE_DIR = "figures"
#: Statistics of the best-known pair copied into :attr:`Mechanism.cells`.
PAIR_COLUMNS = ("ratio_median", "ratio_q05", "ratio_q95", "full_cheaper", "scenarios",
                "ratio_p_holm", "arrival_shift_median", "diag_conv", "full_conv",
                "diag_conv_deadline", "full_conv_deadline", "horizon", "training_horizon")

#: Shares of scenarios (converged at the horizon / by the training deadline) also given as
#: counts.
COUNTED = ("diag_conv", "full_conv", "diag_conv_deadline", "full_conv_deadline")


@dataclass(frozen=True)
class Mechanism:
    """What the page shows of one study (see the module docstring).

    Attributes
    ----------
    pairs : DataFrame
        The held-out table (one row per pairing; ``label`` names it, ``optimizer`` is
        :data:`penaltyrun.report.holdout.BEST_KNOWN` for the best-known pair).
    ratios : dict
        ``label`` → per-scenario cost ratios J_full / J_diag (ndarray).
    modes : DataFrame
        ``problem``, ``case``, ``param``, ``cost`` (training J), ``slowest`` (max Re s, 1/s).
    cells : DataFrame
        One row per problem × case (see :func:`cell_rows`).
    """

    pairs: pd.DataFrame
    ratios: dict[str, np.ndarray]
    modes: pd.DataFrame
    cells: pd.DataFrame


def read(root: Path, name: str) -> pd.DataFrame:
    """Every record of study ``name`` (the re-judged held-out data applied)."""
    from penaltyrun.io.schema import read_results

    path = load_study(root, name).folder / RESULTS
    if not path.is_file():
        raise ValueError(f"study {name!r} has no committed {RESULTS}")
    return read_results(path)


def spearman(cost: Any, slowest: Any) -> float:
    """Spearman's ρ between training cost and decay rate −max Re s (ρ > 0: the cheaper
    starts settle more slowly); NaN with fewer than 3 finite pairs or a constant column."""
    from scipy.stats import spearmanr

    c, s = np.asarray(cost, float), np.asarray(slowest, float)
    ok = np.isfinite(c) & np.isfinite(s)
    if ok.sum() < 3 or np.ptp(c[ok]) == 0 or np.ptp(s[ok]) == 0:
        return float("nan")
    return float(spearmanr(c[ok], -s[ok]).statistic)


def start_modes(df: pd.DataFrame) -> pd.DataFrame:
    """:attr:`Mechanism.modes` of every problem × case of ``df``."""
    from penaltyrun.report.controllers import start_modes as cell_modes

    parts = []
    for (problem, case), g in df.groupby(["problem", "case"], sort=True):
        m = cell_modes(g)
        parts.append(m.assign(problem=problem, case=case))
    columns = ["problem", "case", "param", "cost", "slowest"]
    return pd.concat(parts, ignore_index=True)[columns] if parts else pd.DataFrame(
        columns=columns)


def _diagnostics(row: pd.Series) -> dict[str, float]:
    """Slowest real part, smallest damping ratio and cond K of one job's closed loop."""
    from penaltyrun.problems import diagnostics as dg
    from penaltyrun.report.controllers import loop_of

    loop, _ = loop_of(row)
    if loop is None:
        return {"slowest": np.nan, "damping": np.nan, "cond": np.nan}
    d = dg.diagnose(loop)
    return {"slowest": d.slowest_real, "damping": d.min_damping, "cond": d.gain_cond}


def cell_rows(df: pd.DataFrame, pairs: pd.DataFrame, modes: pd.DataFrame) -> pd.DataFrame:
    """One row per problem × case with a best-known held-out pair.

    Columns: ``problem``, ``case``, ``full_map``, ``diag_optimizer``, ``full_optimizer``,
    ``diag_job``, ``full_job``, ``diag_cost``, ``full_cost`` (training J), ``saving_pct``
    (100 (1 − J_full / J_diag)), ``diag_slowest``, ``full_slowest`` (max Re s, 1/s),
    ``diag_damping``, ``full_damping`` (min ζ), ``diag_cond``, ``full_cond`` (cond K),
    ``slow_factor`` (diag_slowest / full_slowest: how many times slower the full matrix's
    slowest mode decays), ``diag_tau``, ``full_tau`` (its time constant −1 / max Re s, s),
    ``rho`` and ``n_full`` (Spearman's ρ over the converged full
    starts of the cell, every full map pooled), :data:`PAIR_COLUMNS` and, for each share of
    :data:`COUNTED`, ``<share>_n``: the number of held-out scenarios.
    """
    from penaltyrun.report.bestknown import best_rows
    from penaltyrun.report.holdout import BEST_KNOWN

    rows = []
    known = pairs[pairs["optimizer"] == BEST_KNOWN] if not pairs.empty else pairs
    for _, pair in known.iterrows():
        g = df[(df["problem"] == pair["problem"]) & (df["case"] == pair["case"])]
        best = best_rows(g[g["holdout"].notna()])
        diag, full = best["diagonal"], best["full"]
        dd, fd = _diagnostics(diag), _diagnostics(full)
        fm = modes[(modes["problem"] == pair["problem"]) & (modes["case"] == pair["case"])
                   & (modes["param"] != "diagonal")]
        rows.append({
            "problem": pair["problem"], "case": pair["case"], "full_map": pair["full_map"],
            "diag_optimizer": diag["optimizer"], "full_optimizer": full["optimizer"],
            "diag_job": diag["job_id"], "full_job": full["job_id"],
            "diag_cost": float(diag["best_cost"]), "full_cost": float(full["best_cost"]),
            "saving_pct": 100.0 * (1.0 - float(full["best_cost"]) / float(diag["best_cost"])),
            **{f"diag_{k}": v for k, v in dd.items()},
            **{f"full_{k}": v for k, v in fd.items()},
            "slow_factor": dd["slowest"] / fd["slowest"],
            "diag_tau": -1.0 / dd["slowest"], "full_tau": -1.0 / fd["slowest"],
            "rho": spearman(fm["cost"], fm["slowest"]),
            "n_full": int(np.isfinite(fm["slowest"].to_numpy(float)).sum()),
            **{k: pair[k] for k in PAIR_COLUMNS},
            **{f"{k}_n": int(round(pair[k] * pair["scenarios"])) for k in COUNTED}})
    return pd.DataFrame(rows)


def mechanism(df: pd.DataFrame) -> Mechanism:
    """:class:`Mechanism` of a study's records (see the module docstring)."""
    from penaltyrun.report.holdout import holdout_rows

    pairs, ratios = holdout_rows(df)
    modes = start_modes(df)
    return Mechanism(pairs=pairs, ratios=ratios, modes=modes,
                     cells=cell_rows(df, pairs, modes))


def example_scenario(df: pd.DataFrame, m: Mechanism, problem: str, case: str) -> dict[str, Any]:
    """The held-out scenario of a cell's best-known pair whose cost ratio J_full / J_diag is
    closest to the pair's median ratio (the first such label in sorted order).

    Returns
    -------
    dict
        ``problem``, ``case``, ``scenario`` (label), ``ratio``; per matrix (``diag_``,
        ``full_`` prefixes) ``cost``, ``converged``, ``arrival`` (s, NaN if not arrived),
        ``job`` (job id); ``horizon`` and ``training_horizon`` (s).

    Raises
    ------
    ValueError
        If the cell has no best-known held-out pair.
    """
    from penaltyrun.report.holdout import scenario_table

    cell = m.cells[(m.cells["problem"] == problem) & (m.cells["case"] == case)]
    if len(cell) != 1:
        raise ValueError(f"{problem} / {case}: no best-known held-out pair in the study")
    cell = cell.iloc[0]
    jobs = df.set_index(df["job_id"].astype(str))
    tables = {k: scenario_table(jobs.loc[str(cell[f"{k}_job"]), "holdout"])
              for k in ("diag", "full")}
    common = tables["diag"].index.intersection(tables["full"].index).sort_values()
    d, f = tables["diag"].loc[common], tables["full"].loc[common]
    ratio = (f["cost"] / d["cost"]).to_numpy(float)
    good = np.isfinite(ratio) & (ratio > 0)
    k = int(np.argmin(np.where(good, np.abs(np.log(ratio) - np.log(np.median(ratio[good]))),
                               np.inf)))
    out = {"problem": problem, "case": case, "scenario": str(common[k]),
           "ratio": float(ratio[k]), "horizon": float(cell["horizon"]),
           "training_horizon": float(cell["training_horizon"])}
    for key, t in (("diag", d), ("full", f)):
        out.update({f"{key}_cost": float(t["cost"].iloc[k]),
                    f"{key}_converged": bool(t["converged"].iloc[k]),
                    f"{key}_arrival": float(t["arrival_time"].iloc[k]),
                    f"{key}_job": str(cell[f"{key}_job"])})
    return out


def simulate_example(df: pd.DataFrame, ex: dict[str, Any], n_points: int = 800
                     ) -> dict[str, dict[str, np.ndarray]]:
    """Trajectories of both matrices of :func:`example_scenario` from its held-out initial
    state, each up to its arrival time (or the held-out horizon when it never arrives).

    The initial state comes from the problem's ``holdout_scenarios`` (the label names it);
    the histories are the problem's scipy DOP853 reference integration
    (:func:`penaltyrun.problems.attitude.reference.trajectory`) at the held-out horizon's
    parameters. Needs a problem with ``gain`` and ``holdout_scenarios`` (the attitude laws).

    Returns
    -------
    dict
        ``"diagonal"`` and ``"full"`` → ``t`` (s), ``q``, ``w`` (rad/s), ``u`` (N·m), ``J``
        (N²·m²·s), ``dist`` (distance to the target), as the reference integration gives.
    """
    from penaltyrun.io import decode_json
    from penaltyrun.problems import horizon
    from penaltyrun.problems.attitude.reference import trajectory
    from penaltyrun.report import protocol

    jobs = df.set_index(df["job_id"].astype(str))
    sims = {}
    for key, name in (("diag", "diagonal"), ("full", "full")):
        row = jobs.loc[ex[f"{key}_job"]]
        prob = protocol.make(row["problem"], row["case"], row.get("problem_params"))
        scenarios = hooks(prob).holdout_scenarios
        if not hasattr(prob, "gain") or scenarios is None:
            raise ValueError(f"{row['problem']}: no gain / held-out scenarios to simulate")
        sc = scenarios()
        labels = [str(s) for s in sc["scenario"]]
        y0 = np.asarray(sc["y0"][labels.index(ex["scenario"])], float)
        mats = {k: np.asarray(v, float) for k, v in decode_json(row["matrices"]).items()}
        params = horizon.at_horizon(prob, ex["horizon"]).params
        arrival = ex[f"{key}_arrival"]
        t_end = arrival if np.isfinite(arrival) else ex["horizon"]
        sims[name] = trajectory(prob.gain(mats), params, t_end, n_points, y0)
    return sims


class Page:
    """The numbers and figures a template reads for one study (every number formatted from
    the data).

    Parameters
    ----------
    root : Path
        Repository root.
    name : str
        The study.
    example : (problem, case)
        The cell of the example trajectory (:func:`example_scenario`).
    """

    #: Figure key → file name under :data:`FIGURE_DIR` (relative to the page).
    FIGURES = {"ratios": "full-matrix-ratios.png", "modes": "full-matrix-modes.png",
               "trajectory": "full-matrix-trajectory.png"}

    def __init__(self, root: Path, name: str, example: tuple[str, str]) -> None:
        self.root = Path(root)
        self.name = name
        self.example_cell = (str(example[0]), str(example[1]))
        self.df = read(root, name)
        self.m = mechanism(self.df)
        #: Figure keys the template linked to (:meth:`figure`): the ones drawn.
        self.requested: set[str] = set()

    def has(self, *cells: tuple[str, str] | list[str]) -> bool:
        """Whether the data hold a best-known held-out pair for each cell (problem, case)
        and for the example cell (a template's guard: other data render a note instead)."""
        have = set(zip(self.m.cells.get("problem", []), self.m.cells.get("case", [])))
        return all((str(p), str(c)) in have for p, c in (*cells, self.example_cell))

    @cached_property
    def ex(self) -> dict[str, Any]:
        """:func:`example_scenario` of the example cell."""
        return example_scenario(self.df, self.m, *self.example_cell)

    def cell(self, problem: str, case: str, column: str, spec: str = ".3g") -> str:
        """One column of a cell's row, formatted with ``spec``."""
        from penaltyrun.docsgen.layout import fmt

        row = self.m.cells[(self.m.cells["problem"] == problem)
                           & (self.m.cells["case"] == case)]
        if len(row) != 1:
            raise ValueError(f"{self.name}: no best-known pair for {problem} / {case}")
        value = row[column].iloc[0]
        return fmt(value, spec) if not isinstance(value, str) else value

    def value(self, column: str, agg: str = "min", spec: str = ".3g") -> str:
        """``agg`` (min, max, median, count) of a column over the cells."""
        from penaltyrun.docsgen.layout import fmt

        values = self.m.cells[column].astype(float)
        return str(len(values)) if agg == "count" else fmt(getattr(values, agg)(), spec)

    def span(self, column: str, spec: str = ".3g") -> str:
        """``"a to b"``: the smallest and largest value of a column over the cells (one
        value when they format alike)."""
        lo, hi = self.value(column, "min", spec), self.value(column, "max", spec)
        return lo if lo == hi else f"{lo} to {hi}"

    def which(self, column: str, agg: str = "max") -> str:
        """``problem / case`` of the cell where a column takes its ``agg`` (min or max)."""
        values = self.m.cells[column].astype(float)
        row = self.m.cells.loc[values.idxmax() if agg == "max" else values.idxmin()]
        return f"{row['problem']} / {row['case']}"

    def example(self, field: str, spec: str = ".3g") -> str:
        """One field of the example scenario (:func:`example_scenario`), formatted with
        ``spec``."""
        from penaltyrun.docsgen.layout import fmt

        value = self.ex[field]
        return value if isinstance(value, str) else fmt(value, spec)

    def table(self) -> str:
        """The cells as a Markdown table (training, closed loop, held-out)."""
        from penaltyrun.docsgen.layout import fmt

        head = ["cell", "best full map", "training J diag → full", "saving",
                "slowest Re s diag / full (1/s)", "min ζ diag / full", "ρ (full starts)",
                "held-out J_full / J_diag: median (5–95 %)", "full cheaper"]
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for _, r in self.m.cells.iterrows():
            lines.append("| " + " | ".join([
                f"{r['problem']} / {r['case']}", str(r["full_map"]),
                f"{fmt(r['diag_cost'], '.3g')} → {fmt(r['full_cost'], '.3g')}",
                f"{fmt(r['saving_pct'], '.0f')} %",
                f"{fmt(r['diag_slowest'], '.2g')} / {fmt(r['full_slowest'], '.2g')}",
                f"{fmt(r['diag_damping'], '.2f')} / {fmt(r['full_damping'], '.2f')}",
                f"{fmt(r['rho'], '.2f')} (n = {int(r['n_full'])})",
                f"{fmt(r['ratio_median'], '.3g')} ({fmt(r['ratio_q05'], '.2g')}–"
                f"{fmt(r['ratio_q95'], '.3g')})",
                f"{int(r['full_cheaper'])}/{int(r['scenarios'])}"]) + " |")
        return "\n".join(lines)

    def figure(self, key: str) -> str:
        """The path of figure ``key`` relative to the page (:attr:`FIGURES`)."""
        if key not in self.FIGURES:
            raise ValueError(f"no figure {key!r} (there are: {', '.join(self.FIGURES)})")
        self.requested.add(key)
        return f"{FIGURE_DIR}/{self.FIGURES[key]}"

    def write_figures(self, folder: Path) -> list[Path]:
        """Draw the figures the template linked to into ``folder`` (the example trajectories
        are integrated here: seconds); return their paths."""
        from penaltyrun.docsgen import fullmatrix_plots as plots

        if not self.requested:
            return []
        return plots.write_all(self.df, self.m, self.ex, folder,
                               {k: self.FIGURES[k] for k in sorted(self.requested)})


__all__ = ["COUNTED", "FIGURE_DIR", "PAIR_COLUMNS", "Mechanism", "Page", "cell_rows",
           "example_scenario", "mechanism", "read", "simulate_example", "spearman",
           "start_modes"]
