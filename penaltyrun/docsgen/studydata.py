"""One study's committed data as the results pages' templates see it."""

from __future__ import annotations

import json
from functools import cached_property
from pathlib import Path
from typing import Any

from penaltyrun.docsgen import convergence
from penaltyrun.docsgen.studies import RESULTS, TABLES, load_study

#: Text columns of the report's tables where an empty value is a label (the default
#: variant, no note), not a missing number.
LABEL_COLUMNS = ("variant", "problem_variant", "note", "ci_note", "label")


def report_table(stem: str) -> str:
    """``stem`` if the report writes ``<stem>.csv`` (:data:`penaltyrun.report.build.TABLES`).

    Raises
    ------
    ValueError
        For any other name: a template naming a table the report never writes.
    """
    from penaltyrun.report.build import TABLES as REPORT_TABLES
    if stem not in REPORT_TABLES:
        raise ValueError(f"{stem!r} is not a table of the report (it writes: "
                         f"{', '.join(sorted(REPORT_TABLES))})")
    return stem


class StudyData:
    """One study's committed data as templates see it."""

    def __init__(self, root: Path, name: str) -> None:
        self.root = Path(root)
        self.name = name
        self.study = load_study(root, name)
        self.folder = self.study.folder

    @property
    def available(self) -> bool:
        """Whether the merged results are committed."""
        return (self.folder / RESULTS).is_file()

    def has_table(self, stem: str) -> bool:
        """Whether the study's report wrote table ``stem`` (a template's guard for tables a
        report writes only for some problems, e.g. ``paper``)."""
        return (self.folder / TABLES / f"{report_table(stem)}.csv").is_file()

    def has_row(self, stem: str, where: dict[str, Any] | None = None) -> bool:
        """Whether table ``stem`` exists and has a row matching ``where`` (a template's
        guard for a row that names cells of one problem; the study templates call it)."""
        return self.has_table(stem) and not convergence.rows_of(self.table(stem), where).empty

    @property
    def make(self) -> str:
        """The make target that regenerates the study."""
        return self.study.make_target

    @property
    def title(self) -> str:
        """The study's title."""
        return self.study.title

    @cached_property
    def df(self) -> Any:
        """Every record (pandas DataFrame)."""
        from penaltyrun.io.schema import read_results
        return read_results(self.folder / RESULTS)

    def rows(self, where: dict[str, Any] | None = None, converged: bool = False) -> Any:
        """Records matching ``where`` (column → value or list of values), only the
        converged finished starts if ``converged`` (:func:`convergence.rows_of`)."""
        return convergence.rows_of(self.df, where, converged)

    def table(self, stem: str) -> Any:
        """A report table of the study (``tables/<stem>.csv``) as a DataFrame."""
        import pandas as pd
        frame = pd.read_csv(self.folder / TABLES / f"{stem}.csv")
        for column in LABEL_COLUMNS:  # an empty label ("" = default variant) reads as NaN
            if column in frame:
                values = frame[column].astype(object)
                frame[column] = values.where(values.notna(), "").astype(str)
        return frame

    @cached_property
    def provenance(self) -> dict[str, Any]:
        """``provenance.json`` of the study (empty if absent)."""
        path = self.folder / "provenance.json"
        return json.loads(path.read_text()) if path.is_file() else {}
