"""Trade-off fronts: energy against arrival time, and nominal against held-out cost.

A **sweep** is a set of cells that differ only in the price of a second ρ of the
free-final-time criterion (:data:`penaltyrun.problems.criteria.TIME_ENERGY`,
J = E(t_f) + ρ t_f): every ρ is a single-objective tune with the same optimizers, budgets
and records as any other cell. The energy E and the arrival time t_f of a tuned matrix are
in its record (``metrics``: ``energy``, ``arrival_time``), so the fronts are built from the
records alone, nothing re-run.

* **A start's front**: the (E, t_f) points of start index k across the sweep (its tuned
  matrices at every ρ where it converged), reduced to the non-dominated set
  (:func:`nondominated`, pymoo's non-dominated sorting; both objectives minimized).
* **Its hypervolume** (:func:`hypervolume`, pymoo's indicator): the area the front dominates
  up to a reference point, in decades (log10 E, log10 t_f), so that a relative saving counts
  the same at either end of the sweep (E falls by orders of magnitude over it). The
  reference point is common to every start and map of a sweep: per coordinate the largest
  converged value of the sweep (all maps, starts and ρ) plus :data:`REF_MARGIN` of its range
  (:func:`reference_point`). A start without a converged point has hypervolume 0.
* **Per sweep**: each full map against the diagonal map, the hypervolumes of their starts
  compared by the report's rank test (two-sided Mann–Whitney U, A12 = P(a full start's
  hypervolume exceeds a diagonal start's), Holm over :data:`FAMILY`); where the fronts
  differ is read from the pooled fronts (every start, every ρ) and from the per-ρ
  comparisons of the report's equal-budget table.
* **Nominal against held-out**: per cell (one ρ) and map, each start is the point (its
  training cost, the mean of its held-out costs at the held-out horizon, graded failures
  included); the map's front is the non-dominated set over its starts, with a reference
  point common to the maps of the cell.

J = E + ρ t_f is a weighted sum of the two objectives: a sweep of ρ finds the supported
points of a front (those on its convex hull) and never a point in a concave dent. The
report accepts that: each ρ is a criterion a user tunes for, so the front is made of
deployable tunes at the same prices for both maps, and a linear loop's E falls about as
t_f⁻³, a convex trade-off whose front the supported points cover.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from penaltyrun.io import decode_json
from penaltyrun.io.lazy import fill_columns
from penaltyrun.jobrecord import NO_RESULT_STATUSES, OK
from penaltyrun.problems import criteria
from penaltyrun.report.compare import MAP_ORDER, NO_TEST, budget, equal_budget, map_order
from penaltyrun.report.holdout import scenario_table
from penaltyrun.report.rows import narrow
from penaltyrun.report.stats import MIN_N_TEST, a12, a12_magnitude, holm

#: The swept setting (the price of a second of ``time_energy``).
SWEPT = "rho"
#: A sweep key: the cells of one sweep share it (``sweep`` = the variant without ρ).
SWEEP = ["problem", "case", "sweep", "optimizer"]
#: Reference-point margin: a share of each coordinate's range (in decades) beyond the largest
#: value, so that the worst point of a sweep still adds area.
REF_MARGIN = 0.1
#: Margin (decades) when a coordinate has no range (one distinct value).
REF_FLAT = 0.1
#: Words are chosen at this level (the p-values are always printed).
ALPHA = 0.05
#: Holm family of the hypervolume tests, named in the report.
FAMILY = ("every diagonal-vs-full hypervolume test of this report's trade-off fronts (all "
          "sweeps, optimizers and full maps together)")
START_COLUMNS = ["problem", "case", "sweep", "optimizer", "param", "start", "n_swept",
                 "n_converged", "n_front", "hypervolume", "ref_energy", "ref_time", "front"]
TEST_COLUMNS = ["problem", "case", "sweep", "optimizer", "map_a", "map_b", "n_a", "n_b",
                "equal_budget", "hv_median_a", "hv_median_b", "a12_b_beats_a",
                "a12_magnitude", "p_mwu", "p_holm", "dominated_a", "dominated_b",
                "b_dominates_times", "words", "note"]
HOLDOUT_COLUMNS = ["problem", "case", "variant", "optimizer", "param", SWEPT, "n_starts",
                   "n_front", "hypervolume", "ref_nominal", "ref_heldout", "dominated",
                   "front"]


def nondominated(points: Any) -> np.ndarray:
    """The non-dominated subset of ``points`` (n, 2), both coordinates minimized, without
    duplicates, sorted by the first coordinate (pymoo's non-dominated sorting)."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    pts = np.unique(np.asarray(points, dtype=float).reshape(-1, 2), axis=0)
    if len(pts) < 2:
        return pts
    front = pts[NonDominatedSorting().do(pts, only_non_dominated_front=True)]
    return front[np.argsort(front[:, 0], kind="stable")]


def hypervolume(points: Any, ref: Any) -> float:
    """Area dominated by ``points`` (n, 2) and bounded by ``ref`` (2,) (pymoo's indicator);
    points not strictly below ``ref`` in both coordinates add nothing; 0 for none."""
    from pymoo.indicators.hv import HV

    ref = np.asarray(ref, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = pts[np.all(pts < ref, axis=1)]
    return float(HV(ref_point=ref)(pts)) if len(pts) else 0.0


def dominated_share(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mask over the points of ``a`` (n, 2): dominated by some point of ``b`` (no worse in
    both coordinates, better in one)."""
    if len(a) == 0 or len(b) == 0:
        return np.zeros(len(a), dtype=bool)
    le = np.all(b[None, :, :] <= a[:, None, :], axis=2)
    lt = np.any(b[None, :, :] < a[:, None, :], axis=2)
    return np.any(le & lt, axis=1)


def reference_point(logs: np.ndarray) -> np.ndarray:
    """The common reference point (decades) of a sweep's points ``logs`` (n, 2): per
    coordinate max + :data:`REF_MARGIN` · (max − min), or max + :data:`REF_FLAT`."""
    hi, lo = logs.max(axis=0), logs.min(axis=0)
    span = hi - lo
    return hi + np.where(span > 0, REF_MARGIN * span, REF_FLAT)


def _sweep_label(variant: str) -> str:
    """The variant without its ``rho=…`` part (a value with commas keeps its pieces)."""
    return ",".join(t for t in str(variant).split(",") if not t.startswith(f"{SWEPT}="))


def _maybe_time_energy(df: pd.DataFrame) -> pd.Series:
    """Rows whose recorded ``problem_params`` name the ``time_energy`` criterion (decoded
    once per distinct value; every problem with that criterion records it there)."""
    if "problem_params" not in df:
        return pd.Series(False, index=df.index)
    seen: dict[Any, bool] = {}
    for value in df["problem_params"].dropna().unique():
        params = decode_json(value)
        seen[value] = isinstance(params, dict) and \
            params.get("criterion") == criteria.TIME_ENERGY
    return df["problem_params"].map(lambda v: seen.get(v, False)).astype(bool)


#: Columns a sweep's points are made of (the rows selected are copied with these alone).
POINT_COLUMNS = ("problem", "case", "variant", "optimizer", "param", "start", "status",
                 "best_converged", "best_cost", "metrics", "holdout", "max_evals", "n_evals")


def sweep_points(df: pd.DataFrame) -> pd.DataFrame:
    """One row per finished start of a ``time_energy`` cell that belongs to a sweep (≥ 2
    values of ρ under one :data:`SWEEP` key): ``rho``, ``energy``, ``arrival_time`` and
    ``converged`` (status ok, converged, positive finite energy and time) from ``metrics``."""
    rows = []
    # Only rows whose recorded problem parameters may name time_energy are read further
    # (a lazily read frame fills their metrics and held-out data alone).
    keep = _maybe_time_energy(df) & ~df["status"].isin(NO_RESULT_STATUSES)
    df = narrow(df, POINT_COLUMNS)[keep]
    if df.empty:
        return pd.DataFrame()
    df = fill_columns(df, ["metrics", "holdout"])
    for r in df.itertuples(index=False):
        m = decode_json(r.metrics) or {}
        if m.get("criterion") != criteria.TIME_ENERGY or m.get(SWEPT) is None:
            continue
        energy = float(m.get("energy", np.nan))
        t = m.get("arrival_time")
        t = np.nan if t is None else float(t)
        ok = (r.status == OK and bool(r.best_converged) and np.isfinite(energy)
              and np.isfinite(t) and energy > 0 and t > 0)
        rows.append({"problem": r.problem, "case": r.case, "sweep": _sweep_label(r.variant),
                     "variant": r.variant, "optimizer": r.optimizer, "param": r.param,
                     "start": int(r.start), SWEPT: float(m[SWEPT]), "energy": energy,
                     "arrival_time": t, "converged": ok, "cost": float(r.best_cost),
                     "holdout": r.holdout, "max_evals": r.max_evals, "n_evals": r.n_evals,
                     "status": r.status})
    pts = pd.DataFrame(rows)
    if pts.empty:
        return pts
    swept = pts.groupby(SWEEP)[SWEPT].transform("nunique")
    return pts[swept >= 2].reset_index(drop=True)


def _logs(g: pd.DataFrame) -> np.ndarray:
    conv = g[g["converged"]]
    return np.log10(conv[["energy", "arrival_time"]].to_numpy(float)).reshape(-1, 2)


def start_fronts(pts: pd.DataFrame) -> pd.DataFrame:
    """Per sweep × map × start: its front (JSON list of [energy, arrival time]), size and
    hypervolume (decades²) against the sweep's reference point (``ref_energy``,
    ``ref_time`` in the original units)."""
    rows = []
    for key, g in pts.groupby(SWEEP, sort=True):
        logs = _logs(g)
        if not len(logs):
            continue
        ref = reference_point(logs)
        for (param, start), s in g.groupby(["param", "start"], sort=True):
            front = nondominated(_logs(s))
            rows.append({**dict(zip(SWEEP, key)), "param": param, "start": int(start),
                         "n_swept": int(s[SWEPT].nunique()),
                         "n_converged": int(s["converged"].sum()), "n_front": len(front),
                         "hypervolume": hypervolume(front, ref),
                         "ref_energy": float(10 ** ref[0]), "ref_time": float(10 ** ref[1]),
                         "front": json.dumps((10 ** front).tolist())})
    out = pd.DataFrame(rows, columns=START_COLUMNS)
    order = {m: i for i, m in enumerate(MAP_ORDER)}
    return out.sort_values(by=[*SWEEP, "param", "start"],
                           key=lambda c: c.map(lambda v: order.get(v, len(order)))
                           if c.name == "param" else c, kind="stable").reset_index(drop=True)


def pooled_front(g: pd.DataFrame) -> np.ndarray:
    """The non-dominated set (energy, arrival time) of every converged point of ``g``."""
    conv = g[g["converged"]]
    return nondominated(conv[["energy", "arrival_time"]].to_numpy(float))


def _words(p_holm: float, effect: float, map_b: str) -> str:
    if not np.isfinite(p_holm):
        return "no test"
    if p_holm < ALPHA:
        return (f"{map_b} front larger (hypervolume)" if effect > 0.5
                else "diagonal front larger (hypervolume)")
    return "no evidence of a difference"


def _times(front: np.ndarray, mask: np.ndarray) -> str:
    """Arrival-time span of the dominated points of a front, e.g. ``"52.1–348 s"``."""
    if not mask.any():
        return ""
    t = front[mask, 1]
    return f"{t.min():.4g}–{t.max():.4g} s" if t.min() < t.max() else f"{t.min():.4g} s"


def hypervolume_tests(pts: pd.DataFrame, hv: pd.DataFrame) -> pd.DataFrame:
    """Each full map against the diagonal map of every sweep: the hypervolumes of their
    starts (two-sided Mann–Whitney U, A12 = P(b's hypervolume > a's), Holm over the rows;
    only at equal budgets), and the pooled fronts' dominance: share of each map's pooled
    front dominated by the other's, and the arrival times where b dominates a."""
    rows = []
    for key, g in hv.groupby(SWEEP, sort=True):
        maps = map_order(g["param"].unique())
        if "diagonal" not in maps:
            continue
        sel = pts[(pts[SWEEP] == pd.Series(key, index=SWEEP)).all(axis=1)]
        for b in (m for m in maps if m != "diagonal"):
            xa = g.loc[g["param"] == "diagonal", "hypervolume"].to_numpy(float)
            xb = g.loc[g["param"] == b, "hypervolume"].to_numpy(float)
            equal = equal_budget(budget(sel[sel["param"] == "diagonal"]),
                                 budget(sel[sel["param"] == b]))
            p = float(stats.mannwhitneyu(xb, xa, alternative="two-sided").pvalue) \
                if equal and min(xa.size, xb.size) >= 2 else np.nan
            effect = a12(xb, xa) if equal else np.nan
            notes = [] if equal else [NO_TEST]
            if equal and min(xa.size, xb.size) < MIN_N_TEST:
                notes.append(f"underpowered (n < {MIN_N_TEST})")
            fa = pooled_front(sel[sel["param"] == "diagonal"])
            fb = pooled_front(sel[sel["param"] == b])
            da, db = dominated_share(fa, fb), dominated_share(fb, fa)
            rows.append({**dict(zip(SWEEP, key)), "map_a": "diagonal", "map_b": b,
                         "n_a": int(xa.size), "n_b": int(xb.size), "equal_budget": equal,
                         "hv_median_a": float(np.median(xa)) if xa.size else np.nan,
                         "hv_median_b": float(np.median(xb)) if xb.size else np.nan,
                         "a12_b_beats_a": effect, "a12_magnitude": a12_magnitude(effect),
                         "p_mwu": p, "dominated_a": float(da.mean()) if da.size else np.nan,
                         "dominated_b": float(db.mean()) if db.size else np.nan,
                         "b_dominates_times": _times(fa, da), "note": "; ".join(notes)})
    out = pd.DataFrame(rows)
    if out.empty:
        return pd.DataFrame(columns=TEST_COLUMNS)
    out["p_holm"] = holm(out["p_mwu"].to_numpy())
    out["words"] = [_words(p, e, b) for p, e, b in
                    zip(out["p_holm"], out["a12_b_beats_a"], out["map_b"])]
    return out[TEST_COLUMNS]


def heldout_mean(holdout: Any) -> float:
    """Mean held-out cost of one record at the held-out horizon (graded failures in), NaN
    without held-out results."""
    table = scenario_table(holdout) if holdout is not None else None
    if table is None:
        return np.nan
    costs = table["cost"].to_numpy(float)
    return float(costs.mean()) if np.isfinite(costs).all() else np.nan


def holdout_fronts(pts: pd.DataFrame) -> pd.DataFrame:
    """Per cell of a sweep (one ρ) and map: the front of (training cost, mean held-out cost)
    over its starts, its size, its hypervolume (decades²) against a reference point common
    to the cell's maps, and the share of its front dominated by the other maps' fronts."""
    if pts.empty:
        return pd.DataFrame(columns=HOLDOUT_COLUMNS)
    pts = pts.assign(heldout=[heldout_mean(h) for h in pts["holdout"]])
    good = pts[np.isfinite(pts["heldout"]) & (pts["heldout"] > 0) & (pts["cost"] > 0)]
    rows = []
    for key, g in good.groupby(["problem", "case", "variant", "optimizer"], sort=True):
        logs = np.log10(g[["cost", "heldout"]].to_numpy(float))
        ref = reference_point(logs)
        fronts = {m: nondominated(np.log10(s[["cost", "heldout"]].to_numpy(float)))
                  for m, s in g.groupby("param")}
        for m in map_order(list(fronts)):
            others = [f for n, f in fronts.items() if n != m]
            dom = dominated_share(fronts[m], np.vstack(others)) if others else \
                np.zeros(len(fronts[m]), bool)
            rows.append({**dict(zip(["problem", "case", "variant", "optimizer"], key)),
                         "param": m, SWEPT: float(g[SWEPT].iloc[0]),
                         "n_starts": int((g["param"] == m).sum()),
                         "n_front": len(fronts[m]),
                         "hypervolume": hypervolume(fronts[m], ref),
                         "ref_nominal": float(10 ** ref[0]),
                         "ref_heldout": float(10 ** ref[1]),
                         "dominated": float(dom.mean()) if dom.size else np.nan,
                         "front": json.dumps((10 ** fronts[m]).tolist())})
    out = pd.DataFrame(rows, columns=HOLDOUT_COLUMNS)
    return out.sort_values(["problem", "case", "optimizer", SWEPT], kind="stable"
                           ).reset_index(drop=True)


def fronts_of(df: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """Every fronts table of ``df`` (with ``variant``): ``points`` (the sweep's records),
    ``fronts`` (per start), ``fronts_tests`` (per sweep and full map) and ``fronts_holdout``
    (per cell and map); empty frames when ``df`` holds no sweep."""
    pts = sweep_points(df)
    if pts.empty:
        empty = pd.DataFrame()
        return {"points": empty, "fronts": empty, "fronts_tests": empty,
                "fronts_holdout": empty}
    hv = start_fronts(pts)
    return {"points": pts, "fronts": hv, "fronts_tests": hypervolume_tests(pts, hv),
            "fronts_holdout": holdout_fronts(pts)}


def write(tables: dict[str, pd.DataFrame], out: Path) -> None:
    """``fronts.csv``, ``fronts_tests.csv`` and ``fronts_holdout.csv`` where they have
    rows."""
    for stem in ("fronts", "fronts_tests", "fronts_holdout"):
        if not tables[stem].empty:
            tables[stem].to_csv(out / f"{stem}.csv", index=False, encoding="utf-8")


__all__ = ["FAMILY", "HOLDOUT_COLUMNS", "REF_MARGIN", "START_COLUMNS", "SWEEP", "SWEPT",
           "TEST_COLUMNS", "dominated_share", "fronts_of", "holdout_fronts", "hypervolume",
           "hypervolume_tests", "nondominated", "pooled_front", "reference_point",
           "start_fronts", "sweep_points", "write"]
