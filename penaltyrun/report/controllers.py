"""The best tuned controller of each cell: its matrices, its gain, its closed-loop poles,
its channels over time, and plain warnings.

Per problem × case × variant, for each map (parameterization) the converged start with the
lowest cost over every optimizer (the baseline left out) is shown with

* its matrices, its gain (u = −K x, where the problem's ``closed_loop`` hook gives one) and
  its closed-loop poles, to four significant digits, behind a fold;
* a table of its closed-loop diagnostics (:mod:`penaltyrun.problems.diagnostics`): slowest
  real part, smallest damping ratio, ‖K‖₂ and cond(K) — from the stored columns, or, for
  results of an older schema, computed here from the stored matrices;
* a pole map (every map overlaid), the per-channel histories of ``simulate`` with the
  limits the problem declares, and every converged start's cost against its slowest mode
  (with Spearman's ρ per map);
* a warning when a decision variable (eigenvalue, angle or scalar) of a best start sits
  within :data:`BOUND_SHARE` of the box width of a bound of its map's box (see
  :func:`bound_warnings`), and when a full
  map's slowest closed-loop mode is :data:`SLOW_FACTOR` or more times slower than the
  diagonal's (or a loop is not asymptotically stable at the target).

The report never names a problem here: everything comes through the problem protocol.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from penaltyrun.errors import ConfigError
from penaltyrun.io import decode_json
from penaltyrun.problems import diagnostics as dg
from penaltyrun.problems.base import ClosedLoop
from penaltyrun.problems.hooks import hooks
from penaltyrun.report import protocol
from penaltyrun.report.controller_plots import channel_figure, cost_mode_scatter, pole_map
from penaltyrun.report.rows import batches, full_row, groups
from penaltyrun.report.stats import converged
from penaltyrun.report.tables import fenced, fmt, markdown, md_text, with_unit

logger = logging.getLogger(__name__)

#: Share of a box's width within which a decision variable is "at" its bound.
BOUND_SHARE = 0.01
#: A positive box whose upper bound is at least this multiple of its lower bound (an
#: eigenvalue box over decades) is measured in log scale by the bound warning.
LOG_SPAN = 10.0
#: A full map's slowest mode this many times slower than the diagonal's is warned about.
SLOW_FACTOR = 3.0
#: Most maps whose histories are simulated and drawn per cell (diagonal first).
MAX_SIMULATED = 4
#: Significant digits of the matrices shown.
DIGITS = 4
#: Entries of a shown matrix below this share of its largest entry are round-off: shown 0.
ROUNDOFF = 1e-12
COLUMNS = ["map", "by", "cost", "time", "slowest Re s", "min damping", "‖K‖₂", "cond K",
           "poles from"]


def best_per_map(g: pd.DataFrame) -> dict[str, pd.Series]:
    """The converged start with the lowest cost of each map of ``g`` (over every
    optimizer, the baseline excluded), diagonal first."""
    ok = (converged(g) & (g["optimizer"] != "baseline")).to_numpy()
    cost = g["best_cost"][ok].astype(float)  # chosen from these columns: no copy of the rows
    out = {}
    for param, label in cost.groupby(g["param"][ok], sort=True).idxmin().items():
        out[str(param)] = full_row(g, label)
    order = sorted(out, key=lambda p: (p != "diagonal", p))
    return {p: out[p] for p in order}


def _problem(row: pd.Series | Mapping[str, Any]) -> Any:
    """The job's problem, rebuilt without importing anything the data names (None when it
    cannot be: e.g. a plant named by a module the user did not allow)."""
    try:
        return protocol.make(row["problem"], row["case"], row.get("problem_params"))
    except ConfigError:
        return None


def _matrices(row: pd.Series | Mapping[str, Any]) -> dict[str, np.ndarray]:
    return {k: np.asarray(v, float) for k, v in (decode_json(row.get("matrices")) or {}).items()}


def loop_of(row: pd.Series, prob: Any = None) -> tuple[ClosedLoop | None, str]:
    """The closed loop of a job's best candidate and where it came from: the stored
    ``closed_loop`` column, or the problem's hook on the stored matrices (older results;
    ``prob``: the job's problem when already built); (None, reason) when there is none."""
    stored = decode_json(row.get("closed_loop")) if isinstance(row.get("closed_loop"), str) \
        else None
    if stored:
        return dg.loop_from_json(stored), "stored"
    if protocol.module(row["problem"]) is None:
        return None, "problem module not importable"
    prob = _problem(row) if prob is None else prob
    if prob is None:
        return None, "problem not rebuilt from the results"
    if hooks(prob).closed_loop is None:
        return None, "no linearization"
    loop = dg.closed_loop_of(prob, _matrices(row), decode_json(row.get("scalars")) or None)
    return loop, "recomputed from the stored matrices" if loop else "no closed loop"


def controller_rows(g: pd.DataFrame) -> pd.DataFrame:
    """One row per map of one problem × case × variant: the best start's closed-loop
    diagnostics (columns :data:`COLUMNS` plus the raw ``param`` and ``slowest``)."""
    unit = protocol.info_of(g).cost_unit
    rows = []
    for param, row in best_per_map(g).items():
        try:
            loop, source = loop_of(row)
        except Exception as exc:  # an old parameter set the problem no longer takes
            logger.warning("closed loop of %s not available: %s", row.get("job_id"), exc)
            loop, source = None, f"not available ({type(exc).__name__})"
        d = dg.diagnose(loop) if loop is not None else None
        rows.append({
            "map": param, "by": f"{row['optimizer']} s{int(row['start'])}",
            "cost": with_unit(float(row["best_cost"]), unit, 5),
            "time": loop.time if loop is not None else "—",
            "slowest Re s": fmt(d.slowest_real, 4) if d else "—",
            "min damping": fmt(d.min_damping, 3) if d else "—",
            "‖K‖₂": fmt(d.gain_norm, 4) if d else "—",
            "cond K": fmt(d.gain_cond, 4) if d else "—",
            "poles from": source,
            "param": param, "slowest": d.slowest_real if d else np.nan,
            "poles": d.poles if d else None, "loop": loop, "row": row})
    return pd.DataFrame(rows)


def matrix_block(name: str, M: Any, rows: tuple[str, ...] = (),
                 cols: tuple[str, ...] = ()) -> list[str]:
    """A matrix as an aligned, fenced text block, entries to :data:`DIGITS` significant
    digits (entries below :data:`ROUNDOFF` times the largest shown as 0), with row and
    column names where given."""
    M = np.atleast_2d(np.asarray(M, float))
    M = np.where(np.abs(M) <= ROUNDOFF * np.max(np.abs(M), initial=0.0), 0.0, M)
    cells = [[fmt(float(v), DIGITS) for v in r] for r in M]
    head = [fenced(c) for c in cols] if len(cols) == M.shape[1] else []
    left = [fenced(r) for r in rows] if len(rows) == M.shape[0] else [""] * M.shape[0]
    width = max(len(c) for c in [*head, *(c for r in cells for c in r)])
    lw = max(len(x) for x in left)
    lines = [f"{md_text(name)} =", "```"]
    if head:
        lines.append(" " * (lw + 1) + " ".join(h.rjust(width) for h in head))
    lines += [(f"{lab.rjust(lw)} " if lw else "") + " ".join(c.rjust(width) for c in r)
              for lab, r in zip(left, cells)]
    return lines + ["```", ""]


def _complex_text(values: np.ndarray) -> str:
    """``a ± bj`` per conjugate pair (one member shown), ``a`` per real value."""
    out = []
    for v in values:
        if v.imag < 0 and np.any(np.isclose(values, np.conj(v), rtol=1e-9, atol=0.0)):
            continue  # the pair is shown with its positive member
        re = fmt(float(v.real), DIGITS)
        out.append(f"{re} ± {fmt(float(v.imag), DIGITS)}j" if v.imag > 0 else re)
    return ", ".join(out)


def pole_line(loop: ClosedLoop) -> str:
    """The closed-loop poles of a loop as one line, slowest first (continuous s; a
    discrete loop also its z)."""
    d = dg.diagnose(loop)
    text = f"Closed-loop poles s (1 / time unit, slowest first): {_complex_text(d.poles)}."
    if loop.time == "discrete":
        text += f" As z (sample time {fmt(loop.dt, DIGITS)}): {_complex_text(d.eigenvalues)}."
    return text


def bound_warnings(row: pd.Series, share: float = BOUND_SHARE) -> list[str]:
    """One line naming the decision variables of a best start within ``share`` of the box
    width of a bound (the box of its map: :func:`penaltyrun.runner.setup.build_layout`);
    none when no variable is there.

    A positive box spanning :data:`LOG_SPAN` or more (an eigenvalue box over decades) must
    also be within ``share`` of its width in log scale, so 0.0036 in [0.001, 10] is not
    "at" 0.001 and 86 in [1e-8, 100] is not "at" 100. An angle whose box spans a full turn
    (2π) is periodic and never warned about.
    """
    from penaltyrun.runner.setup import build_layout

    z = row.get("best_z")
    prob = None if z is None or protocol.module(row["problem"]) is None else _problem(row)
    if prob is None:
        return []
    layout = build_layout(prob, row["param"],
                          decode_json(row.get("param_options")) or {})
    lb, ub = layout.bounds()
    z = np.asarray(z, float)
    if z.shape != lb.shape:
        return []
    names = list(row.get("z_names") if row.get("z_names") is not None else layout.names())
    hits = []
    for i in np.flatnonzero(np.isfinite(lb) & np.isfinite(ub)):
        if ".ang" in names[i] and ub[i] - lb[i] >= 2.0 * np.pi - 1e-9:
            continue  # a full turn: the rotation is periodic, its bounds constrain nothing
        log = lb[i] > 0 and ub[i] >= LOG_SPAN * lb[i]
        for bound, side in ((lb[i], "lower"), (ub[i], "upper")):
            near = abs(z[i] - bound) <= share * (ub[i] - lb[i])
            if near and log:
                near = abs(np.log(max(z[i], lb[i]) / bound)) <= share * np.log(ub[i] / lb[i])
            if near:
                hits.append(f"{names[i]} = {z[i]:.6g} at its {side} bound {bound:.6g} "
                            f"(box [{lb[i]:.6g}, {ub[i]:.6g}])")
    if not hits:
        return []
    return [f"- ⚠ best {row['param']} ({row['optimizer']}): {'; '.join(hits)} — within "
            f"{100 * share:g} % of the box width (and in log scale for a box spanning "
            f"{LOG_SPAN:g}× or more); the box may be too small."]


def mode_warnings(table: pd.DataFrame, factor: float = SLOW_FACTOR) -> list[str]:
    """Lines for loops not asymptotically stable at the target, and for full maps whose
    slowest mode is ``factor`` or more times slower than the diagonal's."""
    lines = []
    slow = dict(zip(table["param"], table["slowest"]))
    for param, s in slow.items():
        if np.isfinite(s) and s >= 0:
            lines.append(f"- ⚠ best {param}: its closed loop is not asymptotically stable at "
                         f"the target (slowest Re s = {s:.4g}).")
    diag = slow.get("diagonal", np.nan)
    if not (np.isfinite(diag) and diag < 0):
        return lines
    for param, s in slow.items():
        if param != "diagonal" and np.isfinite(s) and s < 0 and diag / s >= factor:
            lines.append(f"- ⚠ best {param}: its slowest closed-loop mode (Re s = {s:.4g}) "
                         f"is {diag / s:.3g}× slower than the best diagonal's ({diag:.4g}): "
                         "starts that excite it settle slowly.")
    return lines


def _simulations(table: pd.DataFrame) -> dict[str, Any]:
    sims = {}
    for row in table["row"].iloc[:MAX_SIMULATED]:
        try:
            sims[f"{row['param']} ({row['optimizer']})"] = protocol.simulate(row)
        except Exception as exc:  # one map's simulation must not lose the others
            logger.warning("simulate of the best %s failed: %s", row["param"], exc)
    return {k: v for k, v in sims.items() if v is not None}


def section(g: pd.DataFrame, out: Path, stem: str) -> list[str]:
    """Markdown lines of one problem × case × variant's tuned controllers (figures saved
    into ``out`` with names starting ``controller_<stem>``)."""
    table = controller_rows(g)
    if table.empty:
        return []
    title = f"{g.iloc[0]['problem']} / {g.iloc[0]['case']}"
    lines = ["### Tuned controllers", ""]
    if table["loop"].notna().any():
        lines += ["The best converged start of each map (every optimizer). Poles s of the "
                  "closed loop linearized at the target, continuous-time (a discrete loop's "
                  "z as s = log z / dt), in 1 / time unit; damping ζ = −Re s / |s|; K the "
                  "gain of u = −K x (the gain block below).", "", markdown(table, COLUMNS),
                  ""]
    else:
        lines += ["The best converged start of each map (every optimizer); no closed-loop "
                  "poles: " + ", ".join(sorted(set(table["poles from"]))) + ".", "",
                  markdown(table, ["map", "by", "cost"]), ""]
    for _, r in table.iterrows():
        row, loop = r["row"], r["loop"]
        has_gain = loop is not None and loop.gain is not None
        lines += [f"<details><summary>best {md_text(r['map'])} ({md_text(r['by'])}): matrices"
                  f"{' and gain' if has_gain else ''}</summary>", ""]
        for name, M in _matrices(row).items():
            lines += matrix_block(name, M)
        if has_gain:
            lines += matrix_block("gain", loop.gain, loop.input_names, loop.state_names)
        if loop is not None:
            lines += [pole_line(loop), ""]
        lines += ["</details>", ""]
    poles = {p: s for p, s in zip(table["param"], table["poles"]) if s is not None}
    path = pole_map(poles, f"{title}: closed-loop poles of the best starts",
                    out / f"controller_{stem}_poles.png")
    if path is not None:
        lines += [f"![closed-loop poles]({path.name})", ""]
    sims = _simulations(table)
    if sims:
        path = channel_figure(sims, f"{title}: channels of the best starts",
                              out / f"controller_{stem}_channels.png")
        if path is not None:
            lines += [f"![channels]({path.name})", ""]
    modes = start_modes(g)
    path = cost_mode_scatter(modes, f"{title}: cost against the slowest closed-loop mode",
                             out / f"controller_{stem}_cost_vs_mode.png",
                             protocol.info_of(g).cost_label)
    if path is not None:
        lines += [f"![cost against the slowest mode]({path.name})", ""] + mode_lines(modes)
    warnings = [w for row in table["row"] for w in _safe(bound_warnings, row)]
    warnings += mode_warnings(table)
    if warnings:
        lines += warnings + [""]
    return lines


def start_modes(g: pd.DataFrame) -> pd.DataFrame:
    """``param``, ``cost`` and ``slowest`` (max Re s) of every converged start of ``g`` (the
    baseline excluded): the stored column, else from the stored matrices (NaN without a
    closed loop)."""
    ok = g[converged(g) & (g["optimizer"] != "baseline")]
    stored = pd.to_numeric(ok["cl_slowest_real"], errors="coerce") \
        if "cl_slowest_real" in ok else pd.Series(np.nan, index=ok.index)
    slowest = pd.Series(stored.astype(float).to_numpy(), index=ok.index)
    built: dict[tuple[str, str, str], Any] = {}
    todo = ok[~np.isfinite(slowest.to_numpy())]
    columns = ["problem", "case", "problem_params", "matrices", "scalars", "closed_loop"]
    for batch in batches(todo, columns[3:]):  # a batch of rows' matrices at a time
        loops = [_start_loop(row, built)
                 for row in batch.reindex(columns=columns).to_dict("records")]
        slowest.loc[batch.index] = dg.slowest_reals(loops)
    return pd.DataFrame({"param": ok["param"].astype(str).to_numpy(),
                         "cost": ok["best_cost"].astype(float).to_numpy(),
                         "slowest": slowest.to_numpy(float)},
                        columns=["param", "cost", "slowest"])


def _start_loop(row: dict[str, Any], built: dict[tuple[str, str, str], Any]
                ) -> ClosedLoop | None:
    """The closed loop of one start for :func:`start_modes` (:func:`loop_of`, each problem
    built once in ``built``); None where there is none or it fails (counted as no closed
    loop; :func:`controller_rows` logs the reason for best starts)."""
    key = (str(row["problem"]), str(row["case"]), str(row["problem_params"]))
    try:
        if key not in built:
            built[key] = _problem(row)
        return loop_of(row, built[key])[0]
    except Exception:
        return None


def mode_lines(modes: pd.DataFrame) -> list[str]:
    """One line with Spearman's ρ between cost and the slowest mode's decay rate per map
    (maps with at least 3 starts that have a closed loop)."""
    from scipy.stats import spearmanr

    parts = []
    for param, m in modes.dropna(subset=["slowest"]).groupby("param", sort=True):
        if len(m) >= 3 and m["cost"].nunique() > 1 and m["slowest"].nunique() > 1:
            rho = spearmanr(m["cost"], -m["slowest"]).statistic
            parts.append(f"{param} {fmt(float(rho), 2)} (n = {len(m)})")
    if not parts:
        return []
    return ["Spearman ρ between a start's cost and its slowest mode's decay rate −max Re s, "
            "every converged start (ρ > 0: cheaper starts settle more slowly): "
            + "; ".join(parts) + ".", ""]


def _safe(func: Any, row: pd.Series) -> list[str]:
    try:
        return func(row)
    except Exception as exc:  # an old parameter set the problem no longer takes
        logger.warning("%s of %s failed: %s", func.__name__, row.get("job_id"), exc)
        return []


def csv_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The ``controllers`` table: one row per problem × case × variant × map with the best
    start's job id and its closed-loop diagnostics (numbers, not text)."""
    rows = []
    for (problem, case, variant), g in groups(df, ["problem", "case", "variant"]):
        for _, r in controller_rows(g).iterrows():
            loop = r["loop"]
            d = dg.diagnose(loop) if loop is not None else None
            rows.append({"problem": problem, "case": case, "variant": variant,
                         "map": r["map"], "job_id": r["row"]["job_id"],
                         "best_cost": float(r["row"]["best_cost"]),
                         "time": loop.time if loop is not None else "",
                         "slowest_real": d.slowest_real if d else np.nan,
                         "min_damping": d.min_damping if d else np.nan,
                         "gain_norm": d.gain_norm if d else np.nan,
                         "gain_cond": d.gain_cond if d else np.nan,
                         "poles_from": r["poles from"]})
    return pd.DataFrame(rows)


__all__ = ["BOUND_SHARE", "SLOW_FACTOR", "best_per_map", "bound_warnings", "controller_rows",
           "csv_rows", "loop_of", "matrix_block", "mode_lines", "mode_warnings", "pole_line",
           "section", "start_modes"]
