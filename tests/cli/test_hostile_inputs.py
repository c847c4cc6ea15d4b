"""Hostile inputs on the command line: YAML files beyond the limits (deep, alias bombs,
oversized) in a user's config directory and oversized command-line lists each end in one
line on stderr naming the file or key and the limit, and exit code 2, in seconds; a report
on a folder holding adversarial Parquet files warns once per file and reports the rest."""

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from penaltyrun.cli.overrides import MAX_CHARS, MAX_VALUES
from penaltyrun.io import collect
from penaltyrun.yamlsafe import MAX_ALIAS_VALUES, MAX_BYTES, MAX_DEPTH


def cli(*args: str, cwd: Path) -> tuple[subprocess.CompletedProcess, float]:
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)
    return proc, time.perf_counter() - start


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr + proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr[-2000:]
    assert lines[0].startswith("penaltyrun: error: ")
    return lines[0]


def bomb(levels: int = 9) -> str:
    lines = ["name: zermelo", "params:", f"  l0: &l0 [{', '.join(['lol'] * 10)}]"]
    lines += [f"  l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


DEEP = "name: zermelo\nparams: {x: " + "[" * 3000 + "]" * 3000 + "}\n"
BIG = "name: zermelo\nparams:\n  x: [" + "0," * (MAX_BYTES // 2) + "0]\n"
LIMITS = {"deep": (DEEP, f"nesting deeper than {MAX_DEPTH} levels"),
          "bomb": (bomb(), f"aliases expand to more than {MAX_ALIAS_VALUES} values"),
          "big": (BIG, f"larger than {MAX_BYTES} bytes")}


@pytest.mark.parametrize("name", sorted(LIMITS))
@pytest.mark.parametrize("how", ["chosen", "through an experiment's defaults"])
def test_b3_b4_a_yaml_file_beyond_a_limit_is_one_line(tmp_path, name, how):
    text, words = LIMITS[name]
    (tmp_path / "myconf" / "problem").mkdir(parents=True)
    (tmp_path / "myconf" / "problem" / f"{name}.yaml").write_text(text)
    if how == "chosen":
        args = [f"problem={name}"]
    else:
        (tmp_path / "myconf" / "experiment").mkdir()
        (tmp_path / "myconf" / "experiment" / "x.yaml").write_text(
            f"# @package _global_\ndefaults:\n  - /problem: {name}\n")
        args = ["+experiment=x"]
    proc, seconds = cli("--config-dir", "myconf", *args, "mode=plan", cwd=tmp_path)
    line = one_error_line(proc)
    assert f"problem: {tmp_path / 'myconf' / 'problem' / name}.yaml: {words}" in line
    assert seconds < 60


def test_b3_b4_a_primary_config_or_a_searchpath_file_beyond_a_limit_is_one_line(tmp_path):
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "config.yaml").write_text("defaults:\n  - _self_\n" + DEEP)
    proc, _ = cli("--config-path", "cfg", "mode=plan", cwd=tmp_path)
    line = one_error_line(proc)
    assert f"--config-path: {tmp_path / 'cfg' / 'config.yaml'}: nesting deeper" in line
    (tmp_path / "sp" / "problem").mkdir(parents=True)
    (tmp_path / "sp" / "problem" / "mine.yaml").write_text(bomb())
    proc, _ = cli(f"hydra.searchpath=[file://{tmp_path / 'sp'}]", "mode=plan", cwd=tmp_path)
    line = one_error_line(proc)
    assert f"problem: {tmp_path / 'sp' / 'problem' / 'mine.yaml'}: aliases expand" in line


@pytest.mark.parametrize(("arg", "words"), [
    ("+foo=[" + ",".join(map(str, range(20_000))) + "]",
     f"characters (the limit is {MAX_CHARS})"),
    ("+foo=[" + ",".join(["1"] * (MAX_VALUES + 1)) + "]",
     f"{MAX_VALUES + 1} comma-separated values (the limit is {MAX_VALUES} per override)"),
    ("runner.seed=" + ",".join(map(str, range(MAX_VALUES + 1))),
     f"{MAX_VALUES + 1} comma-separated values (the limit is {MAX_VALUES} per override)"),
    ("runner.seed=range(0,1000000)", f"sweep of 1000000 values (the limit is {MAX_VALUES}"),
    ("problem.params.x0=" + "[" * 3000 + "]" * 3000,
     "override nested 3000 levels deep (the limit is 50)"),
])
def test_minor_an_oversized_command_line_list_is_one_line(tmp_path, arg, words):
    proc, seconds = cli("-m", "mode=plan", arg, cwd=tmp_path)
    line = one_error_line(proc)
    assert words in line
    assert seconds < 30


def test_b8_a_report_on_a_folder_with_adversarial_parquet_files_reports_the_rest(tmp_path):
    run = tmp_path / "good"
    (run / "jobs").mkdir(parents=True)
    for i in range(3):
        (run / "jobs" / f"j{i}.json").write_text(json.dumps({
            "job_id": f"j{i}", "problem": "zermelo", "case": "default", "param": "diagonal",
            "optimizer": "pso", "seed": i, "status": "ok", "best_cost": 1.0 + i, "start": i}))
    collect(run)
    n = 5000  # one 1 MB text behind every row: 5 GB once decoded
    bomb = pa.DictionaryArray.from_arrays(pa.array(np.zeros(n, dtype=np.int32)),
                                          pa.array(["x" * 1_000_000]))
    (tmp_path / "bomb").mkdir()
    pq.write_table(pa.table({"job_id": bomb, **{c: pa.array(["a"] * n) for c in
                                                ("problem", "case", "param", "optimizer",
                                                 "status")}}),
                   tmp_path / "bomb" / "results.parquet")
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "results.parquet").write_bytes(
        b"PAR1" + np.random.default_rng(1).bytes(999) + b"PAR1")
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.report_cli", "."], cwd=tmp_path,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    warnings = [ln for ln in proc.stderr.splitlines() if ln.startswith("WARNING")]
    assert len(warnings) == 2
    assert any("bomb/results.parquet" in w and "the limit is" in w for w in warnings)
    assert any("junk/results.parquet" in w for w in warnings)
    assert "zermelo" in (tmp_path / "report" / "report.md").read_text()
