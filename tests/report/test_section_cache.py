"""The cache of case sections: a cached report is the same file for file as a drawn one,
draws nothing it has drawn before, and any change of the rows, the shared tables or the code
draws the section again; a damaged or unwritable cache costs time, never the report."""

from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.io.schema import RESULTS_FILE
from penaltyrun.problems import trust
from penaltyrun.report import build_report, cache, cases

GOLDEN_INPUT = Path(__file__).parent / "golden" / "zermelo" / "input" / RESULTS_FILE
OPTIONS = {"source_label": "fixture", "probe": False, "basin_points": 0}


def _input(folder: Path, case: str = "default", scale: float = 1.0) -> Path:
    """The PSO diagonal and full starts of the golden Zermelo results as problem case
    ``case`` (costs times ``scale``)."""
    table = pq.read_table(GOLDEN_INPUT)
    keep = [o == "pso" and p in ("diagonal", "full")
            for o, p in zip(table["optimizer"].to_pylist(), table["param"].to_pylist())]
    table = table.filter(pa.array(keep))
    if case != "default":
        table = table.set_column(table.schema.get_field_index("case"), "case",
                                 pa.array([case] * len(table), table.schema.field("case").type))
        table = table.set_column(table.schema.get_field_index("job_id"), "job_id",
                                 pa.array([f"{case}-{j}" for j in table["job_id"].to_pylist()],
                                          table.schema.field("job_id").type))
    if scale != 1.0:
        costs = [c * scale for c in table["best_cost"].to_pylist()]
        table = table.set_column(table.schema.get_field_index("best_cost"), "best_cost",
                                 pa.array(costs, table.schema.field("best_cost").type))
    folder.mkdir(parents=True)
    pq.write_table(table, folder / RESULTS_FILE)
    return folder


@pytest.fixture
def drawn(monkeypatch):
    """Count the case sections drawn (not copied from the cache)."""
    calls = []
    original = cases.case_lines

    def counting(g, ctx, out, paper, stem):
        calls.append(stem)
        return original(g, ctx, out, paper, stem)

    monkeypatch.setattr(cases, "case_lines", counting)
    return calls


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_a_second_report_copies_every_section_and_is_the_same_file_for_file(tmp_path, drawn):
    src = _input(tmp_path / "in")
    plain = build_report(src, tmp_path / "plain", **OPTIONS)
    first = build_report(src, tmp_path / "first", cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 2 and any(p.suffix == ".png" for p in first.iterdir())
    second = build_report(src, tmp_path / "second", cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 2  # nothing drawn again
    assert _files(plain) == _files(first) == _files(second)
    assert not any(p.name.startswith(".") for p in second.iterdir())


@pytest.mark.slow  # two worker processes (~8 s); the cache itself is in the default suite
def test_the_workers_use_the_cache_too(tmp_path, drawn):
    """Two problem cases in two worker processes fill the cache; the report in this process
    then copies both (the counter sees only this process's draws)."""
    src = tmp_path / "in"
    _input(src / "a")
    _input(src / "b", case="other_case")
    pooled = build_report(src, tmp_path / "pooled", workers=2, cache_dir=tmp_path / "cache",
                          **OPTIONS)
    local = build_report(src, tmp_path / "local", workers=1, cache_dir=tmp_path / "cache",
                         **OPTIONS)
    assert drawn == []
    assert _files(pooled) == _files(local)


def test_changed_rows_or_code_draw_the_section_again(tmp_path, drawn, monkeypatch):
    build_report(_input(tmp_path / "in"), tmp_path / "r0", cache_dir=tmp_path / "cache",
                 **OPTIONS)
    assert len(drawn) == 1
    changed = build_report(_input(tmp_path / "in2", scale=1.5), tmp_path / "r1",
                           cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 2
    assert _files(changed) == _files(build_report(tmp_path / "in2", tmp_path / "r2",
                                                  **OPTIONS))
    monkeypatch.setattr(cache, "code_fingerprint", lambda: "f" * 64)
    build_report(tmp_path / "in", tmp_path / "r3", cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 4  # r2 drew without a cache; r3 with other code
    build_report(tmp_path / "in", tmp_path / "r4", cache_dir=tmp_path / "cache", paper=False,
                 **OPTIONS)
    assert len(drawn) == 5


def test_a_damaged_entry_is_removed_and_drawn_again(tmp_path, drawn, caplog):
    src = _input(tmp_path / "in")
    first = build_report(src, tmp_path / "first", cache_dir=tmp_path / "cache", **OPTIONS)
    figure = next((tmp_path / "cache").rglob("*.png"))
    figure.write_bytes(b"not the figure")
    with caplog.at_level(logging.WARNING, logger="penaltyrun.report.cache"):
        again = build_report(src, tmp_path / "again", cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 2 and "damaged" in caplog.text
    assert _files(first) == _files(again)
    link = next((tmp_path / "cache").rglob("*.png"))
    link.unlink()
    link.symlink_to(first / link.name)
    build_report(src, tmp_path / "third", cache_dir=tmp_path / "cache", **OPTIONS)
    assert len(drawn) == 3


def test_an_unwritable_cache_costs_time_not_the_report(tmp_path, drawn, caplog):
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache folder would be")
    with caplog.at_level(logging.WARNING, logger="penaltyrun.report.cache"):
        out = build_report(_input(tmp_path / "in"), tmp_path / "out", cache_dir=blocker,
                           **OPTIONS)
    assert (out / "report.md").exists() and "cannot write" in caplog.text
    assert len(drawn) == 1


def test_a_problem_the_user_named_a_module_for_is_not_cached(tmp_path, drawn):
    """Its code is outside the key; a module named for another problem changes nothing."""
    src = _input(tmp_path / "in")
    trust.name_module("zermelo", "penaltyrun.problems.zermelo")
    try:
        build_report(src, tmp_path / "out", cache_dir=tmp_path / "cache", **OPTIONS)
    finally:
        trust.forget_named()
    assert len(drawn) == 1 and not list((tmp_path / "cache").rglob("manifest.json"))
    trust.name_module("cartpole", "some_lab.cartpole")
    try:
        build_report(src, tmp_path / "out", cache_dir=tmp_path / "cache", **OPTIONS)
    finally:
        trust.forget_named()
    assert len(drawn) == 2 and list((tmp_path / "cache").rglob("manifest.json"))


def test_old_code_versions_are_pruned(tmp_path):
    sections = tmp_path / cache.SECTIONS
    for age, name in enumerate(["a", "b", "c", "d"]):
        (sections / name).mkdir(parents=True)
        (sections / name / "x").write_text(name)
        mtime = 1_000_000 + 1000 * age
        os.utime(sections / name, (mtime, mtime))
    current = cache.SectionCache(tmp_path, "e" * 64)
    stale, fresh = (current.folder / "ab" / f"{cache.TMP_PREFIX}{n}" for n in ("1", "2"))
    for tmp in (stale, fresh):
        tmp.mkdir(parents=True)
    os.utime(stale, (1_000_000, 1_000_000))
    current.prune(keep=3)  # this code version and the two used last before it
    assert sorted(p.name for p in sections.iterdir()) == ["c", "d", current.folder.name]
    assert fresh.exists() and not stale.exists()  # a killed report's half-written entry


def test_the_code_fingerprint_follows_every_file_but_compiled_caches(tmp_path):
    tree = tmp_path / "pkg"
    shutil.copytree(Path(cache.__file__).parent, tree / "report")
    before = cache.tree_digest(tree)
    (tree / "report" / "__pycache__").mkdir(exist_ok=True)
    (tree / "report" / "__pycache__" / "x.pyc").write_bytes(b"compiled")
    assert cache.tree_digest(tree) == before
    source = tree / "report" / "cases.py"
    source.write_text(source.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    assert cache.tree_digest(tree) != before


def test_a_stored_probe_of_the_case_is_part_of_its_key(tmp_path, drawn):
    """A probe file added beside the results changes the section (it says where its probe
    came from): the cached one is not reused."""
    from penaltyrun.io import storedprobe
    from penaltyrun.io.schema import read_results
    from penaltyrun.report import cliffs
    from penaltyrun.report.bestknown import best_rows

    src = _input(tmp_path / "in")
    options = {**OPTIONS, "probe": True}
    build_report(src, tmp_path / "r0", cache_dir=tmp_path / "cache", **options)
    assert len(drawn) == 1
    rows = []
    for row in best_rows(read_results(src / RESULTS_FILE)).values():
        result, _ = cliffs.probe_row(row)
        rows.append(storedprobe.record(row["job_id"], row["config_hash"], row["best_z"],
                                       result))
    storedprobe.write(src / storedprobe.PROBE_FILE, rows, {})
    stored = build_report(src, tmp_path / "r1", cache_dir=tmp_path / "cache", **options)
    assert len(drawn) == 2
    assert "read from `probe.parquet`" in (stored / "report.md").read_text()
    build_report(src, tmp_path / "r2", cache_dir=tmp_path / "cache", **options)
    assert len(drawn) == 2


def test_a_shared_table_by_case_keys_a_section_by_its_own_cases_only():
    """The paper-matrix tables (keyed by problem, case, variant) enter a section's key
    with the entries of its own problem case alone: another case's table leaves it."""
    from penaltyrun.report.cache import _case_rows

    one, other = pd.DataFrame({"map": ["K"]}), pd.DataFrame({"map": ["Q"]})
    tables = {("zermelo", "default", ""): one, ("zermelo", "default", "iters=10"): one,
              ("zermelo", "far", ""): other}
    assert list(_case_rows(tables, "zermelo", "default")) == [("zermelo", "default", ""),
                                                               ("zermelo", "default",
                                                                "iters=10")]
    assert _case_rows({}, "zermelo", "default") == {}
    assert _case_rows({"basin": 3}, "zermelo", "default") == {"basin": 3}
