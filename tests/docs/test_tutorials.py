"""The tutorials tested as documentation: each tutorial's commands run in reduced form (tiny
budgets, one worker) and each statement it makes about the output is checked — the report's
section names, the tables' columns, the defaults it quotes.

The statements that can be checked without running anything (defaults read from the
config and the problem's parameters, section titles from the report builder's source,
table columns from its column lists) are in the default suite; the end-to-end runs are
slow tests."""

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from penaltyrun.io import RESULTS_FILE, read_results

ROOT = Path(__file__).resolve().parents[2]
FIRST = ROOT / "docs" / "tutorials" / "first-study.md"
LQR = ROOT / "docs" / "tutorials" / "tune-your-lqr.md"
PROGRAMS = {"penaltyrun": [sys.executable, "-m", "penaltyrun.cli"],
            "penaltyrun-report": [sys.executable, "-m", "penaltyrun.report_cli"]}
#: Every reduced optimize run: one worker, small budgets (the settings a tutorial gives are
#: replaced, the rest kept).
REDUCED = {"runner.n_starts": "2", "optimizer.max_evals": "60", "runner.workers": "1"}
#: Further settings of an optimizer the tutorial leaves at its own limits.
OWN_LIMITS = {"pso": {"optimizer.n_particles": "6", "optimizer.iters": "4"},
              "grid": {"optimizer.points_per_dim": "5", "optimizer.n_local": "1",
                       "optimizer.local_max_evals": "20", "optimizer.max_evals": "null"}}


def blocks(doc: Path, lang: str) -> list[str]:
    """The fenced code blocks of ``lang`` in ``doc``, in order."""
    return re.findall(rf"```{lang}\n(.*?)```", doc.read_text(encoding="utf-8"), flags=re.S)


def commands(block: str) -> list[str]:
    """The ``penaltyrun`` and ``penaltyrun-report`` lines of a shell block (continuation
    lines joined)."""
    lines = block.replace("\\\n", " ").splitlines()
    return [ln.strip() for ln in lines if ln.strip().startswith("penaltyrun")]


def reduced(line: str) -> list[str]:
    """The argument list of ``line`` as the test runs it (see :data:`REDUCED`)."""
    words = shlex.split(line)
    args = words[1:]
    if words[0] != "penaltyrun" or any(a.startswith("mode=") for a in args):
        return PROGRAMS[words[0]] + args
    given = dict(a.split("=", 1) for a in args if "=" in a)
    settings = dict(REDUCED)
    for name in given.get("optimizer", "pso").split(","):
        settings.update(OWN_LIMITS.get(name, {}))
    if "optimizer.max_evals" not in given and "grid" not in given.get("optimizer", ""):
        settings.pop("optimizer.max_evals")
    if "-m" in args:
        settings["runner.report"] = "false"  # a report per cell: the report command follows
    kept = [a for a in args if a.split("=", 1)[0] not in settings]
    return PROGRAMS[words[0]] + kept + [f"{k}={v}" for k, v in settings.items()]


def run(line: str, cwd: Path, code: int = 0) -> subprocess.CompletedProcess:
    proc = subprocess.run(reduced(line), cwd=cwd, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == code, f"{line}\n{proc.stderr[-3000:]}"
    return proc


def bullets(doc: Path, after: str) -> list[str]:
    """The bold names of the bullet list that follows the line starting with ``after``."""
    text = doc.read_text(encoding="utf-8")
    start = text.index(after)
    items = re.match(r"[^\0]*?\n\n((?:[*-] [^\n]*\n(?: +[^\n]*\n)*)+)", text[start:])
    assert items, after
    return re.findall(r"^[*-] \*\*([^*]+)\*\*", items.group(1), flags=re.M)


def report_titles() -> list[str]:
    """Every fixed section title the report builder writes (from its source)."""
    src = "".join(p.read_text(encoding="utf-8")
                  for p in (ROOT / "penaltyrun" / "report").glob("*.py"))
    return re.findall(r"\"#{2,3} ([^\"{]+)\"", src)


def titled(name: str, titles: list[str]) -> bool:
    return any(t == name or t.startswith(name + ",") or t.startswith(name + ":")
               or t.startswith(name + " ") for t in titles)


# --- statements checked without running anything ---------------------------------------

#: The sections each tutorial names, by the line its bullet list follows.
SECTION_LISTS = [(FIRST, "Open `outputs/first/report/report.md`"), (LQR, "Reading `report.md`")]


@pytest.mark.parametrize("doc, after", SECTION_LISTS, ids=["first-study", "tune-your-lqr"])
def test_named_sections_are_the_report_builders(doc, after):
    from penaltyrun import problems

    titles = report_titles()
    names = [n.strip() for name in bullets(doc, after) for n in name.split("→")]
    assert len(names) >= 4
    for name in names:
        if name.endswith("section"):  # the problem case's own, e.g. "The set-up's section"
            continue
        problem = name.split(" / ")[0]
        assert titled(name, titles) or (" / " in name and problem in problems.REGISTRY), name


def test_named_columns_are_the_report_tables():
    from penaltyrun.report import build, cases, verdict

    assert {"budget", "converged", "best", "median", "median 95 % CI", "mean", "worst"} <= \
        set(cases.CELL_COLUMNS)
    assert {"median_a", "median_b", "A12 (b beats a)", "Holm p"} <= \
        set(cases.COMPARISON_COLUMNS)
    assert {"best_known", "optimizer", "param", "evidence"} <= set(build.BEST_KNOWN_COLUMNS)
    assert {"diagonal best-known", "full best-known", "gain", "equal budget", "held-out"} <= \
        set(verdict.COLUMNS)


def test_worker_default_is_as_the_tutorials_say():
    config = yaml.safe_load((ROOT / "penaltyrun" / "conf" / "config.yaml").read_text())
    assert config["runner"]["workers"] == "auto"
    for doc in (FIRST, LQR):
        text = doc.read_text(encoding="utf-8")
        assert "runner.workers=2" not in text  # the default already runs one job per core
    assert "(`runner.workers=auto`, the default)" in LQR.read_text(encoding="utf-8")


def _default(cell: str):
    """A default of the keys table as a value: None for none ("—", null), a number, a
    list, or text (a quoted string, or a description such as "identity")."""
    cell = cell.strip().strip("`")
    if cell in ("—", "null"):
        return None
    try:
        return float(cell)  # 1e-10: YAML 1.1 reads it as text
    except ValueError:
        pass
    try:
        return yaml.safe_load(cell.replace("\\|", "|"))
    except yaml.YAMLError:
        return cell


def test_lqr_keys_table_defaults_are_the_problems():
    from dataclasses import MISSING, fields

    from penaltyrun.problems.lqr.params import Params

    defaults = {f.name: f.default for f in fields(Params) if f.default is not MISSING}
    text = LQR.read_text(encoding="utf-8")
    table = text[text.index("## All keys of `problem=lqr`"):]
    rows = re.findall(r"^\| (`[^|]+`(?:, `[^|]+`)*) \| [^|]+ \| ((?:[^|\\]|\\\|)+) \|", table,
                      flags=re.M)
    assert len(rows) >= 15
    for keys_cell, default_cell in rows:
        keys = re.findall(r"`([^`]+)`", keys_cell)
        cells = [default_cell] if len(keys) == 1 or default_cell.strip().startswith("[") \
            else default_cell.split(",")
        assert len(cells) in (1, len(keys)), keys
        for key, cell in zip(keys, cells * len(keys) if len(cells) == 1 else cells):
            assert key in defaults, key
            documented, actual = _default(cell), defaults[key]
            if isinstance(documented, str) and not isinstance(actual, str):
                assert actual is None, key  # "identity", "1000 × J*": computed later
            elif isinstance(actual, tuple):
                assert list(actual) == pytest.approx(documented), key
            else:
                assert documented == (pytest.approx(actual) if isinstance(actual, float)
                                      else actual), key


def test_reduced_commands_keep_what_the_tutorial_runs():
    sweep = commands(blocks(FIRST, "bash")[-1])[0]
    args = reduced(sweep)[3:]
    for kept in ("-m", "problem=zermelo", "param=diagonal,full",
                 "optimizer=pso_budget,de_budget,cmaes",
                 "hydra.sweep.dir=outputs/first/equal_budget"):
        assert kept in args
    assert "optimizer.max_evals=60" in args and "runner.n_starts=2" in args
    grid = reduced(commands(blocks(FIRST, "bash")[-1])[1])
    assert "optimizer.points_per_dim=5" in grid and "optimizer.max_evals=null" in grid


# --- the tutorials run, in reduced form ---------------------------------------------------

def headings(report: Path) -> list[str]:
    return [ln.lstrip("#").strip() for ln in report.read_text(encoding="utf-8").splitlines()
            if ln.startswith("## ") or ln.startswith("### ")]


@pytest.mark.slow  # about 90 s: the tutorial's runs and reports at tiny budgets, one worker
def test_first_study_runs_as_written(tmp_path):
    bash = blocks(FIRST, "bash")
    # 2. evaluate: one JSON object, last line, with the cost, converged, the final time
    out = run(commands(bash[1])[0], tmp_path).stdout.strip().splitlines()[-1]
    result = json.loads(out)
    assert {"cost", "converged", "t_final"} <= set(result) and result["converged"] is True
    for bad in ("[[1,0,0],[0,1,0],[0,0,1]]", "[[1,2],[3,4]]", "[[1,2],[2,1]]"):
        proc = run(f"penaltyrun mode=evaluate problem=zermelo 'matrices.K={bad}'", tmp_path, 2)
        assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    # 3. one cell, then the other: a forecast, one line per start, a summary line
    for line in commands(bash[2]) + commands(bash[3]):
        proc = run(line, tmp_path)
        logs = proc.stdout + proc.stderr
        n = int(dict(a.split("=", 1) for a in reduced(line) if "=" in a)["runner.n_starts"])
        assert "forecast:" in logs
        assert len(re.findall(rf"\[\d+/{n}\] ", logs)) == n
        assert f"penaltyrun: {n} jobs:" in logs
    # 4. each run directory: results.parquet and report/; the Python lines run
    for cell in ("full", "diagonal"):
        assert (tmp_path / "outputs" / "first" / cell / RESULTS_FILE).is_file()
        assert (tmp_path / "outputs" / "first" / cell / "report" / "report.md").is_file()
    python = subprocess.run([sys.executable, "-c", blocks(FIRST, "python")[0]], cwd=tmp_path,
                            capture_output=True, text=True, timeout=300)
    assert python.returncode == 0, python.stderr
    assert "diagonal" in python.stdout and "full" in python.stdout
    # 5. one report over both runs, with the sections the tutorial names
    for line in commands(bash[4]):
        run(line, tmp_path)
    report = tmp_path / "outputs" / "first" / "report"
    found = headings(report / "report.md")
    names = bullets(FIRST, "Open `outputs/first/report/report.md`")
    for name in names:
        assert any(titled(name, [h]) for h in found), (name, found)
    assert "evidence" in pd.read_csv(report / "best_known.csv").columns
    # 6. equal budgets, three optimizers, the grid; the report over everything
    for line in commands(bash[5]):
        run(line, tmp_path)
    df = read_results(tmp_path / "outputs" / "first" / "equal_budget")
    assert set(df["optimizer"]) == {"pso", "de", "cmaes"} and set(df["param"]) == \
        {"diagonal", "full"}
    assert (df["n_evals"] <= 60).all()
    assert set(read_results(tmp_path / "outputs" / "first" / "grid")["optimizer"]) == {"grid"}
    comparison = pd.read_csv(report / "comparison.csv")
    assert {"pso", "de", "cmaes"} <= set(comparison["optimizer"])


@pytest.mark.slow  # about 40 s: the tuning sweep at a tiny budget, its report and export
def test_tune_your_lqr_runs_as_written(tmp_path):
    (tmp_path / "myconf" / "problem").mkdir(parents=True)
    (tmp_path / "myconf" / "problem" / "two_carts.yaml").write_text(blocks(LQR, "yaml")[0])
    for line in commands(blocks(LQR, "sh")[0]):
        run(line, tmp_path)
    out = tmp_path / "outputs" / "two_carts"
    report = out / "report"
    found = headings(report / "report.md")
    assert found[0].startswith("Verdict")  # the first table
    assert any(h.startswith("lqr / default [setup=A,B#") for h in found), found
    for name in ("Map vs map", "Held-out scenarios", "Best-known optima",
                 "Optimizer shortfall"):
        assert any(h.startswith(name) for h in found), (name, found)
    best = pd.read_csv(report / "best_known.csv")
    for matrices in best["matrices"]:
        assert {"Q", "R"} <= set(json.loads(matrices))
    assert "m^2 s" in (report / "report.md").read_text(encoding="utf-8")  # the cost unit
    assert len(list((out / "export").glob("*.json"))) >= 2
    assert len(list((out / "export").glob("*.mat"))) == 2
