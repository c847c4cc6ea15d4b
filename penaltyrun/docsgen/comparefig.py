"""The equal-budget map-vs-map tests of a study as a figure: A12 with its interval.

For every equal-budget pair diagonal vs full map of a study (the pairs of its committed
``comparison.csv``), the effect A12 = P(a full start beats a diagonal start) with its 95 %
Brunner–Munzel interval (:func:`penaltyrun.report.compare.a12_interval`), computed from the
study's committed ``results.parquet`` and grouped by optimizer (one panel each).

The numbers drawn are written beside the figure as ``docs/results/figures/<study>_a12.csv``
and checked by ``make check-docs`` like the pages' text; the PNG is drawn from that CSV
(only when it changed or the PNG is missing) and checked for presence only: its bytes
depend on the matplotlib version and fonts.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

FIGURES = Path("docs") / "results" / "figures"
#: Confidence level of the intervals.
LEVEL = 0.95
#: Largest difference between the committed table's A12 and the recomputed one.
A12_ATOL = 1e-9
CSV_COLUMNS = ["problem", "case", "variant", "optimizer", "map_a", "map_b", "n_a", "n_b",
               "a12_b_beats_a", "a12_lo", "a12_hi", "ci_note"]


def intervals(results: Any, comparison: Any) -> Any:
    """A12 with its interval for every equal-budget pair of ``comparison``.

    Parameters
    ----------
    results : pandas.DataFrame
        The study's records (``results.parquet``).
    comparison : pandas.DataFrame
        The study's committed ``comparison.csv``.

    Returns
    -------
    pandas.DataFrame
        :data:`CSV_COLUMNS`, one row per equal-budget pair.

    Raises
    ------
    ValueError
        If a recomputed A12 differs from the committed table's (stale tables: regenerate
        the study's report).
    """
    from penaltyrun.report.compare import a12_intervals
    from penaltyrun.report.stats import add_variant

    ci = a12_intervals(add_variant(results), LEVEL)
    keys = ["problem", "case", "variant", "optimizer", "map_a", "map_b"]
    merged = ci.merge(comparison[[*keys, "a12_b_beats_a"]].astype({"variant": str}),
                      on=keys, how="left", suffixes=("", "_table"))
    stale = ~((merged["a12_b_beats_a"] - merged["a12_b_beats_a_table"]).abs() <= A12_ATOL)
    stale &= merged["a12_b_beats_a"].notna() | merged["a12_b_beats_a_table"].notna()
    if stale.any():
        row = merged[stale].iloc[0]
        raise ValueError(f"A12 of {dict(row[keys])} is {row['a12_b_beats_a']} from the "
                         f"records but {row['a12_b_beats_a_table']} in comparison.csv: "
                         "regenerate the study's report")
    return ci[CSV_COLUMNS]


def diagonal_pairs(ci: Any) -> Any:
    """The rows of :func:`intervals` comparing the diagonal with a full map."""
    return ci[(ci["map_a"] == "diagonal") & (ci["map_b"] != "diagonal")].reset_index(drop=True)


def to_csv(frame: Any) -> str:
    """The figure's numbers as CSV text (six significant digits)."""
    return frame.to_csv(index=False, float_format="%.6g", lineterminator="\n")


def _label(row: dict[str, Any], cells: int) -> str:
    """The y label of one comparison: its map, after its cell when the study has several."""
    cell = f"{row['problem']} / {row['case']}" + (f" [{row['variant']}]"
                                                  if row["variant"] else "")
    return f"{cell}: {row['map_b']}" if cells > 1 else str(row["map_b"])


def draw(csv_text: str, path: Path, title: str) -> Path:
    """Draw the figure of ``csv_text`` (:func:`to_csv` of :func:`diagonal_pairs`) into
    ``path``: one panel per optimizer, A12 with its interval per comparison (an open
    marker where there is no interval), chance (0.5) marked."""
    import matplotlib
    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    import pandas as pd

    from penaltyrun.report.tables import save_figure

    frame = pd.read_csv(io.StringIO(csv_text), keep_default_na=False,
                        na_values={c: [""] for c in ("a12_b_beats_a", "a12_lo", "a12_hi")})
    frame["variant"] = frame["variant"].astype(str)
    cells = frame[["problem", "case", "variant"]].drop_duplicates().shape[0]
    frame["label"] = [_label(r, cells) for r in frame.to_dict("records")]
    labels = list(dict.fromkeys(frame["label"]))
    optimizers = list(dict.fromkeys(frame["optimizer"]))
    fig, axes = plt.subplots(1, len(optimizers), sharey=True, squeeze=False,
                             figsize=(2.0 + 2.6 * len(optimizers), 1.2 + 0.32 * len(labels)))
    for ax, optimizer in zip(axes[0], optimizers):
        sel = frame[frame["optimizer"] == optimizer]
        y = [labels.index(v) for v in sel["label"]]
        has = sel["a12_lo"].notna().to_numpy()
        err = [(sel["a12_b_beats_a"] - sel["a12_lo"])[has], (sel["a12_hi"]
                                                            - sel["a12_b_beats_a"])[has]]
        ax.errorbar(sel["a12_b_beats_a"][has], [v for v, h in zip(y, has) if h], xerr=err,
                    fmt="o", color="C0", ms=4, capsize=2, lw=1)
        ax.plot(sel["a12_b_beats_a"][~has], [v for v, h in zip(y, has) if not h], "o",
                mfc="none", color="C3", ms=5)
        ax.axvline(0.5, color="k", lw=0.8, ls="--")
        ax.set_xlim(0.0, 1.0)
        ax.set_title(str(optimizer), fontsize=10)
        ax.grid(True, axis="x", alpha=0.3)
    axes[0][0].set_yticks(range(len(labels)), labels, fontsize=8)
    axes[0][0].invert_yaxis()
    fig.supxlabel("A12 = P(full start beats diagonal start), 95 % Brunner–Munzel interval "
                  "(open: no interval)", fontsize=9)
    fig.suptitle(title, fontsize=10)
    path.parent.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, path)


def section(name: str, results: Any, comparison: Any,
            figures: dict[Path, str]) -> str:
    """The equal-budget part of a results page for study ``name``: the figure (its CSV
    registered in ``figures`` under its path), a sentence on how to read it and, behind a
    fold, the comparison table with the intervals."""
    from penaltyrun.docsgen.layout import fmt, fold, markdown_table

    ci = intervals(results, comparison)
    plot = diagonal_pairs(ci)
    parts = []
    if plot.empty:
        parts.append("*No diagonal–full pair of this study ran at equal budgets: no figure "
                     "(the table below says why for each pair).*")
    else:
        csv_rel = FIGURES / f"{name}_a12.csv"
        figures[csv_rel] = to_csv(plot)
        parts.append(f"![A12 of every equal-budget diagonal–full comparison of {name}, by "
                     f"optimizer](figures/{csv_rel.with_suffix('.png').name})")
        parts.append("Each point is A12, the probability that a start of the full map ends "
                     "cheaper than a start of the diagonal (converged starts, same optimizer "
                     "and budget; 0.5: no difference), with its 95 % Brunner–Munzel "
                     f"interval. The numbers: `{csv_rel.as_posix()}`.")
    keys = ["problem", "case", "variant", "optimizer", "map_a", "map_b"]
    table = comparison.astype({"variant": str}).merge(
        ci[[*keys, "a12_lo", "a12_hi"]], on=keys, how="left")
    table["n (a / b)"] = [f"{a} / {b}" for a, b in zip(table["n_a"], table["n_b"])]
    table["median (a / b)"] = [f"{fmt(a)} / {fmt(b)}"
                               for a, b in zip(table["median_a"], table["median_b"])]
    ci_notes = ci.set_index(keys)["ci_note"]
    table["A12 (95 % CI)"] = [
        "—" if a != a else f"{fmt(a, '.3f')} ({fmt(lo, '.3f')}–{fmt(hi, '.3f')})"
        if lo == lo else f"{fmt(a, '.3f')} ({ci_notes.get(key, 'no interval')})"
        for a, lo, hi, key in zip(table["a12_b_beats_a"], table["a12_lo"], table["a12_hi"],
                                  table[keys].itertuples(index=False, name=None))]
    table = table.rename(columns={"p_holm": "Holm p"})
    shown = ["problem", "case", *(["variant"] if (table["variant"] != "").any() else []),
             "optimizer", "map_a", "map_b", "n (a / b)", "median (a / b)", "A12 (95 % CI)",
             "Holm p", "note"]
    parts.append(fold("The equal-budget tests: A12 = P(b beats a), two-sided Mann–Whitney "
                      "U, Holm p", markdown_table(table[shown])))
    return "\n\n".join(parts)
