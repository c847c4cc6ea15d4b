"""A results folder received from someone else: reading it runs no code named in it, and
the report writes nothing outside its folder.

Each test plants one hostile input in synthetic results (no optimizer runs: fast) and
asserts the documented outcome."""

from __future__ import annotations

import base64
import json
import logging
import re
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from penaltyrun import problems
from penaltyrun.cli import report_main
from penaltyrun.errors import ConfigError
from penaltyrun.io.schema import RESULTS_FILE, to_table
from penaltyrun.report import build_report
from penaltyrun.report.export import export_best

#: A module that leaves a marker file when imported and when its function is called.
PLANTED = '''
from pathlib import Path

Path({marker!r}).write_text("imported")


def f(X, U):
    Path({marker!r} + ".called").write_text("called")
    return X * 0.0


SYS = ([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]])
'''


def rows(problem="planted_problem", case="only", params=None, config="", n=3,
         params_list=None, **extra):
    """Job records of one diagonal and one full cell (pso), ``n`` converged starts each."""
    out = []
    for param in ("diagonal", "full"):
        for k in range(n):
            p = params_list[k % len(params_list)] if params_list else (params or {})
            out.append({"job_id": f"{param}-{k}-{abs(hash(json.dumps(p)))}", "problem": problem,
                        "case": case, "param": param, "optimizer": "pso", "start": k,
                        "seed": k, "status": "ok", "best_cost": 1.0 + k + (param == "full"),
                        "best_converged": True, "n_evals": 10, "config_hash": "h",
                        "matrices": {"K": [[1.0 + k, 0.0], [0.0, 1.0]]}, "scalars": {},
                        "metrics": {}, "problem_params": p, "optimizer_settings": {},
                        "config": config, "git_commit": "test", **extra})
    return out


def write(folder: Path, records) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    pq.write_table(to_table(records, "run"), folder / RESULTS_FILE)
    return folder / RESULTS_FILE


@pytest.fixture
def planted(tmp_path, monkeypatch):
    """A received folder with a module beside the results, the folder on sys.path (as
    ``PYTHONPATH=.`` would put it) and the current directory."""
    folder = tmp_path / "received"
    folder.mkdir()
    marker = str(tmp_path / "MARKER")
    for name in ("planted_mod", "planted_plant"):
        (folder / f"{name}.py").write_text(PLANTED.format(marker=marker), encoding="utf-8")
        sys.modules.pop(name, None)
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.chdir(folder)
    yield folder, Path(marker)
    for name in ("planted_mod", "planted_plant"):
        sys.modules.pop(name, None)
    problems.trust.forget_named()


def test_s1_problem_module_of_the_stored_config_is_not_imported(planted):
    folder, marker = planted
    config = "problem:\n  name: planted_problem\n  module: planted_mod\n"
    write(folder, rows(config=config))
    out = build_report(folder, folder / "report")
    assert not marker.exists() and "planted_mod" not in sys.modules
    text = (out / "report.md").read_text(encoding="utf-8")
    notes = [line for line in text.splitlines() if "were not run" in line]
    assert len(notes) == 1 and "--problem-module planted_problem=MODULE" in notes[0]
    assert "## planted_problem / only" in text  # cells from the stored columns alone


def test_s1_a_builtin_name_with_a_stored_module_uses_the_builtin(planted):
    folder, marker = planted
    config = "problem:\n  name: zermelo\n  module: planted_mod\n"
    export_best(write(folder, rows(problem="zermelo", case="default", config=config)),
                folder / "export")
    assert not marker.exists() and "planted_mod" not in sys.modules


@pytest.mark.parametrize("name", ["this", "planted_mod", "os.path", "planted_mod:f"])
def test_s2_a_module_name_as_the_problem_is_not_imported(planted, name):
    folder, marker = planted
    sys.modules.pop("this", None)
    write(folder, rows(problem=name, config=f"problem:\n  module: {name}\n"))
    build_report(folder / RESULTS_FILE, folder / "out")
    assert "this" not in sys.modules and "planted_mod" not in sys.modules
    assert not marker.exists()


@pytest.mark.parametrize("key", ["dynamics", "plant"])
def test_s3_an_lqr_plant_named_by_module_is_not_imported(planted, key):
    folder, marker = planted
    params = {"A": [[0.0, 1.0], [0.0, 0.0]], "B": [[0.0], [1.0]], key: "planted_plant:f"}
    if key == "plant":
        params = {"plant": "planted_plant:SYS"}
    write(folder, rows(problem="lqr", case="default", params=params))
    out = build_report(folder, folder / "report")
    assert not marker.exists() and not Path(str(marker) + ".called").exists()
    assert "planted_plant" not in sys.modules
    assert (out / "report.md").is_file()
    with problems.trust.reading_results(), pytest.raises(problems.trust.NotImportedError):
        problems.make("lqr", "default", params)


@pytest.mark.parametrize("content", ["SECRET_TOKEN: [unclosed\n",
                                     "A: SECRET_TOKEN + 1\nB: [[1.0]]\n"])
def test_a_plant_file_named_by_results_is_never_quoted(tmp_path, content, caplog):
    secret = tmp_path / "private.yaml"  # a YAML file of the reader's own, named by the data
    secret.write_text(content, encoding="utf-8")
    folder = tmp_path / "received"
    write(folder, rows(problem="lqr", case="default", params={"plant_file": str(secret)}))
    with caplog.at_level(logging.WARNING):
        out = build_report(folder, folder / "report")
    shown = caplog.text + "".join(p.read_text(encoding="utf-8", errors="replace")
                                  for p in out.rglob("*") if p.suffix in (".md", ".html"))
    assert "cannot be built from the stored parameters, which name a file" in caplog.text
    assert str(secret) in caplog.text and "SECRET_TOKEN" not in shown
    with pytest.raises(ConfigError, match="SECRET_TOKEN"):  # your own run: the line shown
        problems.make("lqr", "default", {"plant_file": str(secret)})


def test_a_module_named_on_the_command_line_runs_its_hooks(planted, capsys):
    folder, marker = planted
    module = textwrap.dedent('''
        from pathlib import Path
        from penaltyrun.problems.base import ReportInfo
        Path({marker!r}).write_text("imported")
        CASES = ("only",)
        DEFAULT_CASE = "only"
        def make_problem(case, params):
            raise RuntimeError("not needed by this report")
        def report_info(case, params):
            return ReportInfo(cost_name="named cost", cost_unit="J")
    ''').format(marker=str(marker))
    (folder / "named_mod.py").write_text(module, encoding="utf-8")
    write(folder, rows(config="problem:\n  module: planted_mod\n"))
    report_main([str(folder), "--problem-module", "planted_problem=named_mod"])
    text = (folder / "report" / "report.md").read_text(encoding="utf-8")
    assert marker.read_text() == "imported" and "planted_mod" not in sys.modules
    assert "named cost (J)" in text and "were not run" not in text
    sys.modules.pop("named_mod", None)


def test_a_malformed_problem_module_option_is_one_line(planted, capsys):
    folder, _ = planted
    write(folder, rows())
    with pytest.raises(SystemExit) as exc:
        report_main([str(folder), "--problem-module", "no_equals_sign"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "NAME=MODULE" in err[0]


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*")}


@pytest.mark.parametrize("name", ["../../escaped", "/ABS/escaped", "..", "a/../../b",
                                  "..\\..\\win"])
def test_s4_a_problem_name_that_is_a_path_writes_inside_the_folder(tmp_path, name):
    name = name.replace("/ABS", str(tmp_path / "abs"))
    (tmp_path / "abs").mkdir()
    folder = tmp_path / "deep" / "received"
    write(folder, rows(problem=name, case=name, params_list=[{"v": name}, {"v": 2}]))
    before = _files(tmp_path)
    build_report(folder, folder / "report")
    export_best(folder, folder / "export")
    new = _files(tmp_path) - before
    assert new and all((folder / "report") in p.parents or (folder / "export") in p.parents
                       or p in (folder / "report", folder / "export") for p in new), new


def test_s5_a_name_with_markdown_embeds_no_local_file(tmp_path):
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG\r\n\x1a\nSECRET-BYTES-OF-A-LOCAL-FILE")
    evil = f"p\n![k]({secret})\n<img src=\"{secret}\">\n| a | b |\n# heading"
    folder = tmp_path / "received"
    records = rows(problem=evil, case=evil, params_list=[{"v": evil}, {"v": 1}])
    write(folder, records + [{**records[0], "job_id": evil, "status": "failed",
                              "error": evil}])
    out = build_report(folder, tmp_path / "report")
    page = (out / "report.html").read_text(encoding="utf-8")
    assert base64.b64encode(secret.read_bytes()).decode()[:24] not in page
    assert not re.search(r"<img [^>]*src=\"(?!data:)", page)  # figures only, embedded
    assert "<h1>heading" not in page and "<h1># heading" not in page
    text = (out / "report.md").read_text(encoding="utf-8")
    assert not [line for line in text.splitlines()
                if line.startswith(("![k]", "<img", "# heading", "| a | b |"))]


def test_l5_long_variant_labels_export_every_cell_to_its_own_files(tmp_path):
    long = "x" * 200
    folder = tmp_path / "received"
    write(folder, rows(problem="zz_user", params_list=[{"label": long + "a"},
                                                      {"label": long + "b"}], n=4))
    files = export_best(folder, tmp_path / "export")
    names = [f.name for f in files]
    assert len(names) == 9 and len(set(names)) == 9  # 4 cells × (json, mat) + index
    assert all(len(n) < 200 for n in names)
    cells = {(d["variant"], d["param"]) for d in
             (json.loads(f.read_text()) for f in files if f.suffix == ".json")}
    assert len(cells) == 4


def test_s8_a_report_link_in_a_received_folder_is_refused(tmp_path, capsys):
    folder = tmp_path / "received"
    write(folder, rows(problem="zz_user"))
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "report.md").write_text("precious\n", encoding="utf-8")
    (folder / "report").symlink_to(victim)
    with pytest.raises(SystemExit) as exc:
        report_main([str(folder)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "symbolic link" in err[0] and "remove the link" in err[0]
    assert [p.name for p in victim.iterdir()] == ["report.md"]
    assert (victim / "report.md").read_text(encoding="utf-8") == "precious\n"
    (folder / "export").symlink_to(victim)
    with pytest.raises(Exception, match="symbolic link"):
        export_best(folder, folder / "export")
    assert [p.name for p in victim.iterdir()] == ["report.md"]


def test_s8_links_inside_the_report_folder_are_replaced_not_written_through(tmp_path):
    folder = tmp_path / "received"
    write(folder, rows(problem="zz_user"))
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n", encoding="utf-8")
    out = folder / "report"
    out.mkdir()
    for name in ("report.md", "report.html", "summary.csv", "comparison.csv"):
        (out / name).symlink_to(victim)
    build_report(folder, out)
    assert victim.read_text(encoding="utf-8") == "precious\n"
    assert not any(p.is_symlink() for p in out.iterdir())
    (folder / "export").mkdir()
    (folder / "export" / "index.csv").symlink_to(victim)
    export_best(folder, folder / "export")
    assert victim.read_text(encoding="utf-8") == "precious\n"


def test_f18_an_output_folder_of_another_report_is_cleaned_not_mixed(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    old = {"comparison.csv": "old", "comparison.md": "old", "holdout.csv": "old",
           "paper.csv": "old", "old_figure.png": "png",
           "report.md": "# old\n\n![old](old_figure.png)\n"}
    for name, text in old.items():
        (out / name).write_text(text, encoding="utf-8")
    (out / "notes.txt").write_text("the user's own file\n", encoding="utf-8")
    (out / "unlisted.png").write_text("the user's own figure\n", encoding="utf-8")
    folder = tmp_path / "received"
    one_map = [r for r in rows(problem="zz_user") if r["param"] == "full"]
    write(folder, one_map)  # one map: no comparison, no held-out
    build_report(folder, out)
    names = {p.name for p in out.iterdir()}
    assert not names & {"comparison.csv", "comparison.md", "holdout.csv", "paper.csv",
                        "old_figure.png"}
    assert {"notes.txt", "unlisted.png", "report.md", "summary.csv"} <= names
    assert (out / "report.md").read_text(encoding="utf-8") != old["report.md"]
    exp = tmp_path / "export"
    write(folder / "two", rows(problem="zz_other"))
    export_best(folder / "two", exp)
    first = {p.name for p in exp.iterdir()}
    export_best(folder / RESULTS_FILE, exp)
    second = {p.name for p in exp.iterdir()}
    assert len(first) == 5 and len(second) == 3 and not first & second - {"index.csv"}


def test_a_plant_module_allowed_on_the_command_line_is_imported(planted):
    folder, marker = planted
    params = {"A": [[0.0, 1.0], [0.0, 0.0]], "B": [[0.0], [1.0]],
              "dynamics": "planted_plant:f"}
    write(folder, rows(problem="lqr", case="default", params=params,
                       matrices={"Q": [[1.0, 0.0], [0.0, 1.0]], "R": [[1.0]]}))
    report_main([str(folder), "--plant-module", "planted_plant"])
    assert marker.read_text() == "imported"  # allowed: imported (and f checked at 0)
    assert "planted_mod" not in sys.modules


@pytest.mark.slow  # about 7 s: a child Python imports penaltyrun
def test_s1_python_m_report_cli_in_a_received_folder_imports_nothing_from_it(tmp_path):
    """``python -m`` puts the current folder on sys.path: modules planted there under the
    names of penaltyrun's dependencies do not run."""
    import os
    import subprocess

    folder = tmp_path / "received"
    write(folder, rows(problem="zz_user", config="problem:\n  module: planted_mod\n"))
    for name in ("typing", "yaml", "matplotlib", "scipy", "tqdm", "planted_mod"):
        (folder / f"{name}.py").write_text(
            f"open({str(tmp_path / ('HIJACKED_' + name))!r}, 'w').write('x')\n", "utf-8")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", "."], cwd=folder,
                          env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert not list(tmp_path.glob("HIJACKED_*"))
    assert (folder / "report" / "report.md").is_file()


def test_report_cli_takes_the_current_folder_off_sys_path(tmp_path, monkeypatch):
    from penaltyrun import safepath

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PYTHONPATH", raising=False)
    monkeypatch.setattr(sys, "path", [str(tmp_path), "/lib"])
    safepath.drop_current_folder()
    assert sys.path == ["/lib"]
    monkeypatch.setattr(sys, "path", [str(tmp_path), "/lib"])
    monkeypatch.setenv("PYTHONPATH", ".")  # the user put it there: kept
    safepath.drop_current_folder()
    assert sys.path == [str(tmp_path), "/lib"]


@pytest.mark.parametrize("orig, argv, expected", [
    (["python", "-m", "penaltyrun.report_cli", "."], ["-m", "."], True),
    (["python", "-mpenaltyrun.report_cli"], ["-m"], True),
    (["python", "-Bm", "penaltyrun.report_cli", "."], ["-m", "."], True),
    (["python", "-Bmpenaltyrun.report_cli", "."], ["-m", "."], True),
    (["python", "--check-hash-based-pycs", "default", "-m", "penaltyrun.report_cli", "-o",
      "x"], ["-m", "-o", "x"], True),
    (["python", "-X", "dev", "-B", "-m", "penaltyrun.report_cli"], ["-m"], True),
    (["python", "-m", "penaltyrun.cli", "problem=zermelo"], ["-m", "problem=zermelo"], False),
    (["python", "script.py", "-m", "penaltyrun.report_cli"],
     ["script.py", "-m", "penaltyrun.report_cli"], False),
    (["penaltyrun-report", "."], ["penaltyrun-report", "."], False),
    (["python", "-c", "import penaltyrun"], ["-c"], False)])
def test_the_package_knows_when_it_runs_as_the_report_module(orig, argv, expected):
    from penaltyrun import safepath

    assert safepath.run_as(safepath.REPORT_MODULE, argv, orig) is expected


def test_an_empty_pythonpath_entry_does_not_keep_the_current_folder(tmp_path, monkeypatch):
    from penaltyrun import safepath

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PYTHONPATH", "/lib:")
    monkeypatch.setattr(sys, "path", [str(tmp_path), "/lib", "", "/std"])
    safepath.drop_current_folder()
    assert sys.path == ["/lib", "/std"]


def test_an_unknown_case_is_reported_from_its_stored_columns(tmp_path):
    """A case this version does not know (renamed, or from a newer version) costs one
    warning; its cell keeps its tables, the other cells their whole report."""
    folder = tmp_path / "received"
    write(folder / "a", rows(problem="zermelo", case="default"))
    write(folder / "b", rows(problem="zermelo", case="no_such_case", config_hash="h2"))
    out = build_report(folder, tmp_path / "report")
    text = (out / "report.md").read_text(encoding="utf-8")
    plain = text.replace("\\_", "_")
    assert "## zermelo / default" in plain and "## zermelo / no_such_case" in plain
    warned = [line for line in plain.splitlines() if "cannot be rebuilt" in line]
    assert len(warned) == 1 and "no_such_case" in warned[0]
    assert list(out.glob("zermelo_default_phase_plane*.png"))  # the known case's figures
    assert not list(out.glob("zermelo_no_such_case*phase_plane*.png"))


def test_stored_parameters_of_the_wrong_kind_leave_the_problem_unbuilt_with_one_warning(
        tmp_path):
    """B8: a start position stored as text is refused when the problem is rebuilt (one
    warning naming the parameter); the paper's-matrices table is left out."""
    from penaltyrun.report import protocol
    from penaltyrun.report.sections import paper_matrix_tables

    protocol.reset()
    frame = pd.DataFrame(rows(problem="zermelo", case="default", params={"x0": "far"}))
    frame["variant"] = ""
    for column in ("problem_params", "matrices"):
        frame[column] = [json.dumps(v) for v in frame[column]]
    assert paper_matrix_tables(frame) == {}
    assert len([w for w in protocol.WARNINGS if "problem.params.x0" in w]) == 1


def test_stored_parameters_the_problem_accepts_but_cannot_run_cost_one_warning(
        tmp_path, monkeypatch):
    """B8: parameters that pass the problem's construction but fail its evaluation: the
    paper's-matrices table is left out with one warning, nothing else is lost."""
    from penaltyrun.problems.zermelo import Zermelo
    from penaltyrun.report import protocol
    from penaltyrun.report.sections import paper_matrix_tables

    def fails(self, *args, **kwargs):
        raise ValueError("cannot run these parameters")

    monkeypatch.setattr(Zermelo, "evaluate", fails)
    monkeypatch.setattr(Zermelo, "evaluate_batch", fails)
    protocol.reset()
    frame = pd.DataFrame(rows(problem="zermelo", case="default"))
    frame["variant"] = ""
    for column in ("problem_params", "matrices"):
        frame[column] = [json.dumps(v) for v in frame[column]]
    assert paper_matrix_tables(frame) == {}
    assert len([w for w in protocol.WARNINGS if "could not be evaluated" in w]) == 1


def test_s8_an_export_link_is_refused_before_the_report_is_written(tmp_path, capsys):
    folder = tmp_path / "received"
    write(folder, rows(problem="zz_user"))
    victim = tmp_path / "victim"
    victim.mkdir()
    (folder / "export").symlink_to(victim)
    with pytest.raises(SystemExit) as exc:
        report_main([str(folder), "-o", str(tmp_path / "rep"), "--export",
                     str(folder / "export")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--export" in err[0] and "symbolic link" in err[0]
    assert not (tmp_path / "rep").exists() and not any(victim.iterdir())


def test_b8_a_file_of_no_rows_alone_is_one_line_and_exit_2(tmp_path, capsys):
    empty = tmp_path / "received"
    empty.mkdir()
    pq.write_table(to_table(rows()[:0], "run"), empty / RESULTS_FILE)
    with pytest.raises(SystemExit) as stop:
        report_main([str(empty), "-o", str(tmp_path / "out")])
    assert stop.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "no job rows under" in lines[0]


def test_b8_a_start_time_beyond_pythons_dates_is_reported_with_the_cache(tmp_path):
    """A stored time of 2**62 µs (year 146 140) has no text form in Python; the section
    cache keys it by its count instead."""
    records = [{**r, "started_at": pd.Timestamp(2**62, unit="us", tz="UTC")}
               for r in rows(problem="zermelo", case="default")]
    src = write(tmp_path / "received", records)
    out = build_report(src, tmp_path / "out", basin_points=0, probe=False,
                       cache_dir=tmp_path / "cache")
    assert (out / "report.md").is_file()


def test_s5_commit_and_matrix_names_reach_the_report_as_inert_text(tmp_path):
    """A stored commit and a matrix name carrying HTML, a heading, an image line and
    control characters: report.md holds them escaped, on one line each."""
    name = "K\n\n![x](mine.png)\n# INJECTED HEADING\x1b[31m"
    records = [{**r, "git_commit": "<img src=x onerror=alert(1)>\n# INJECTED COMMIT\x00",
                "matrices": {name: r["matrices"]["K"]}}
               for r in rows()]
    src = write(tmp_path / "received", records)
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.png").write_bytes(b"the user's own file")
    build_report(src, out, basin_points=0, probe=False)
    text = (out / "report.md").read_text(encoding="utf-8")
    assert not re.search(r"(?<!\\)<img", text) and "![x](mine.png)" not in text
    assert not any(line.startswith("# INJECTED") for line in text.splitlines())
    assert "\x1b" not in text and "\x00" not in text
    build_report(src, out, basin_points=0, probe=False)  # a second report into the folder
    assert (out / "mine.png").read_bytes() == b"the user's own file"


def test_s5_names_in_a_fenced_matrix_block_cannot_close_the_fence():
    from penaltyrun.report.controllers import matrix_block

    lines = matrix_block("gain", np.eye(2), ("u```", "v\n# h"), ("x", "y`"))
    assert [line for line in lines if line.startswith("```")] == ["```", "```"]
    assert not any(line.startswith("#") for line in lines)


def test_a_stored_error_of_megabytes_is_one_short_line_in_the_report():
    from penaltyrun.report.build import ERROR_LINE_CHARS, _first_line

    assert _first_line("ValueError: bad\nTraceback ...") == "ValueError: bad"
    long = _first_line("x" * 40_000_000)
    assert len(long) == ERROR_LINE_CHARS + 2 and long.endswith(" …")


def test_s7_a_folder_named_like_an_output_file_leaves_the_earlier_report_whole(tmp_path):
    src = write(tmp_path / "received", rows())
    out = tmp_path / "out"
    build_report(src, out, basin_points=0, probe=False)
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    (out / "report.html").unlink()
    (out / "report.html").mkdir()
    with pytest.raises(ConfigError, match="report.html is a folder where the output"):
        build_report(write(tmp_path / "other", rows(case="second")), out, basin_points=0,
                     probe=False)
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == {k: v for k, v in before.items() if k != "report.html"}
