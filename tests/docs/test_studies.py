"""Every study the docs cite can be regenerated: its definition loads, names profiles that
exist, and its command runs end to end in a reduced form (few starts, tiny budgets) into a
merged zstd Parquet with the report's tables and a provenance file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from penaltyrun.docsgen import provenance, resultpages, studies, studydata

ROOT = Path(__file__).resolve().parents[2]
CONF = ROOT / "penaltyrun" / "conf"
NAMES = studies.list_studies(ROOT)
#: Studies whose reduced run takes a few seconds of CPU (two Zermelo cells).
FAST = ("pso_matlab_zermelo",)
#: Total size of the committed study data (results, tables, provenance).
DATA_LIMIT_MB = 50


def test_every_study_is_defined():
    assert len(NAMES) >= 10
    for name in NAMES:
        study = studies.load_study(ROOT, name)
        assert study.commands and study.question and (study.folder / "README.md").is_file()
        readme = (study.folder / "README.md").read_text()
        assert f"make study-{name}" in readme and "RESUME=true" in readme
        for command in study.commands:
            for arg in command.args:
                if arg.startswith("+experiment="):
                    assert (CONF / "experiment" / f"{arg.split('=', 1)[1]}.yaml").is_file()
            if command.budget_from:
                assert command.budget_from["subdir"] in {c.subdir for c in study.commands}


def test_committed_study_data_fits_the_budget():
    total = sum(p.stat().st_size for p in (ROOT / "studies").rglob("*") if p.is_file())
    assert total <= DATA_LIMIT_MB * 1e6


def test_committed_reports_name_their_source_inside_the_repository():
    for report in sorted((ROOT / "studies").glob("*/tables/report.md")):
        source = report.read_text(encoding="utf-8").splitlines()[2]
        study = report.parent.parent.name
        assert source.startswith(f"Source: `studies/{study}/results.parquet`"), report


def test_display_path_is_repository_relative_inside_and_unchanged_outside(tmp_path):
    inside = ROOT / "studies" / "x" / "results.parquet"
    assert provenance.display_path(inside, ROOT) == "studies/x/results.parquet"
    outside = tmp_path / "results.parquet"
    assert provenance.display_path(outside, ROOT) == str(outside)


def test_unknown_study_is_one_clear_error():
    with pytest.raises(studies.StudyError, match="no study 'nope'"):
        studies.load_study(ROOT, "nope")


def run_reduced(name: str, tmp_path: Path) -> Path:
    dest = tmp_path / "dest"
    merged = studies.run_study(ROOT, name, run_dir=tmp_path / "run", workers=1, reduced=True,
                               dest=dest, extra=["runner.forecast_samples=0"])
    frame = pq.read_table(merged).to_pandas()
    study = studies.load_study(ROOT, name)
    assert len(frame) >= len(study.commands)
    assert set(frame["status"]) <= {"ok", "diverged"}
    meta = pq.ParquetFile(merged).metadata
    assert meta.row_group(0).column(0).compression == "ZSTD"
    assert (dest / "tables" / "summary.csv").is_file()
    info = json.loads((dest / "provenance.json").read_text())
    assert info["jobs"] == len(frame) and "numpy" in info["packages"]
    assert len(info["commands"]) == len(study.commands)
    render_pages_with(name, dest, tmp_path / "root")
    return merged


def render_pages_with(name: str | list[str], dest: Path, root: Path) -> str:
    """Render the real templates with the (reduced) data of ``dest`` in the place of study
    ``name`` (or of each study of a list): its place on every page is filled from the data,
    no longer pending. Returns the rendered text of every page."""
    names = [name] if isinstance(name, str) else name
    for other in NAMES:
        folder = root / "studies" / other
        folder.mkdir(parents=True)
        shutil.copy2(ROOT / "studies" / other / "study.yaml", folder)
    for other in names:
        shutil.copytree(dest, root / "studies" / other, dirs_exist_ok=True)
    for folder in (ROOT / "studies").iterdir():  # experiments' CSV files (no study.yaml)
        if folder.is_dir() and folder.name not in NAMES and folder.name != "templates":
            shutil.copytree(folder, root / "studies" / folder.name)
    shutil.copytree(ROOT / "studies" / "templates", root / "studies" / "templates")
    shutil.copy2(ROOT / "README.md", root)
    (root / "docs").mkdir(exist_ok=True)
    shutil.copy2(ROOT / "docs" / "index.md", root / "docs")
    text = "\n".join(resultpages.render(root, reference=False).values())
    for other in names:
        assert f"study-{other}`" not in text.replace(f"regenerate it with `make study-{other}`", "")
        assert f"`{other}` | " in text
    return text


@pytest.fixture(scope="module")
def zermelo_study(tmp_path_factory) -> Path:
    """A tiny real Zermelo study merged by the study machinery: diagonal against GEAGSP
    with `pso` and the certifying grid, every job on the held-out set, and the same cells
    tuned on two training starts (multi-scenario), so its report writes the verdict,
    held-out, comparison, best-known, shortfall, target, paper-matrix and tuning-mode
    tables."""
    from penaltyrun import io, runner
    tmp = tmp_path_factory.mktemp("zermelo_study")
    pso = {"max_evals": 60, "n_particles": 6, "iters": 10}
    grid = {"points_per_dim": 5, "n_local": 1, "local_max_evals": 30}
    multi = {"train_scenarios": [{"x0": [-6.0, 8.0]}]}
    jobs = []
    for param in ("diagonal", "geagsp"):
        jobs += runner.plan_jobs("zermelo", "default", param, "pso", n_starts=3, root_seed=7,
                                 optimizer_options=pso)
        jobs += runner.plan_jobs("zermelo", "default", param, "pso", n_starts=2, root_seed=7,
                                 problem_params=multi, optimizer_options=pso)
        jobs += runner.plan_jobs("zermelo", "default", param, "grid", n_starts=1, root_seed=7,
                                 optimizer_options=grid)
    runner.execute(jobs, tmp / "run")
    io.collect(tmp / "run")
    studies.merge_study(ROOT, "referee_zermelo", run_dir=tmp / "run", dest=tmp / "dest")
    return tmp / "dest"


def test_a_report_names_its_source_by_the_label_given(zermelo_study, tmp_path):
    studies.write_tables(zermelo_study / "results.parquet", tmp_path / "report",
                         tmp_path / "tables", label="studies/tiny/results.parquet")
    lines = (tmp_path / "tables" / "report.md").read_text(encoding="utf-8").splitlines()
    assert lines[2].startswith("Source: `studies/tiny/results.parquet` — ")


#: Tables the tiny Zermelo study's report must write (Zermelo declares no published
#: means and no discretization re-runs, so `paper` and `discretization` stay absent).
ZERMELO_TABLES = {"verdict", "summary", "comparison", "holdout", "best_known", "shortfall",
                  "targets", "paper_matrices", "holdout_tuning_modes"}


def test_templates_use_only_tables_the_report_writes(zermelo_study, tmp_path):
    written = {p.stem for p in (zermelo_study / "tables").glob("*.csv")}
    assert ZERMELO_TABLES <= written
    from penaltyrun.report.build import TABLES
    assert written <= set(TABLES)
    # every study's place filled with the same data: each template's table queries run
    text = render_pages_with(NAMES, zermelo_study, tmp_path / "root")
    for stem in written:
        assert f"has no `{stem}` table" not in text
    assert "has no held-out table" not in text
    assert "**Held-out scenarios, zermelo / default:**" in text
    assert "ratio_median" in text and "full_conv_deadline" in text


def test_a_template_naming_a_table_the_report_never_writes_fails(zermelo_study):
    with pytest.raises(ValueError, match="not a table of the report"):
        studydata.report_table("holdout_zermelo")


@pytest.mark.slow  # about 45 s on 2 cores (the slow suite regenerates every study)
@pytest.mark.parametrize("name", FAST)
def test_fast_study_regenerates(name, tmp_path):
    merged = run_reduced(name, tmp_path)
    frame = pq.read_table(merged).to_pandas()
    assert set(frame["param"]) == {"diagonal", "full"}
    again = studies.run_study(ROOT, name, run_dir=tmp_path / "run", workers=1, reduced=True,
                              resume=True, dest=tmp_path / "dest2",
                              extra=["runner.forecast_samples=0"])
    assert len(pq.read_table(again)) == len(frame)


@pytest.mark.slow
@pytest.mark.parametrize("name", [n for n in NAMES if n not in FAST])
def test_study_regenerates(name, tmp_path):
    run_reduced(name, tmp_path)


def test_budget_from_selects_on_a_problem_parameter(tmp_path):
    """The equal-budget cells read the median evaluations of one objective form's cell."""
    from penaltyrun.io.schema import to_table
    rows = []
    for k, (form, evals) in enumerate([("neg_reciprocal", 100), ("neg_reciprocal", 120),
                                       ("cost", 900), ("cost", 1000)]):
        rows.append({"job_id": f"a-schaub_detumble-diagonal-pso_matlab-x-s{k:03d}",
                     "problem": "attitude_lyapunov", "case": "schaub_detumble",
                     "param": "diagonal", "optimizer": "pso_matlab", "start": k, "seed": k,
                     "status": "ok", "best_cost": 80.0 + k, "best_converged": True,
                     "n_evals": evals, "git_commit": "abc",
                     "problem_params": json.dumps({"objective_form": form})})
    (tmp_path / "defaults").mkdir()
    pq.write_table(to_table(rows, run_id="r"), tmp_path / "defaults" / "results.parquet")
    where = {"case": "schaub_detumble", "optimizer": "pso_matlab"}
    command = studies.Command(subdir="eq", args=[], budget_from={
        "subdir": "defaults", "where": {**where, "problem_params.objective_form":
                                        "neg_reciprocal"}})
    assert studies.budget_override(command, tmp_path) == ["optimizer.max_evals=110"]
    command.budget_from["where"] = where
    assert studies.budget_override(command, tmp_path) == ["optimizer.max_evals=510"]


def test_a_study_file_beyond_the_yaml_limits_is_a_study_error(tmp_path):
    folder = tmp_path / "studies" / "bomb"
    folder.mkdir(parents=True)
    (folder / "study.yaml").write_text("title: &t [a, a, a, a, a, a, a, a, a, a]\n" + "".join(
        f"c{i}: &c{i} [{', '.join([f'*c{i - 1}' if i else '*t'] * 10)}]\n" for i in range(8)))
    with pytest.raises(studies.StudyError, match="study.yaml: aliases expand to more than"):
        studies.load_study(tmp_path, "bomb")


def _tiny_study(root: Path) -> None:
    folder = root / "studies" / "tiny"
    folder.mkdir(parents=True)
    (folder / "study.yaml").write_text(
        "title: tiny\nquestion: q\ncommands:\n"
        "- subdir: first\n  args: [problem=zermelo]\n"
        "- subdir: added\n  args: [problem=zermelo, param=geagsp]\n")


def _zermelo_jobs(run_dir: Path, param: str) -> list[str]:
    from penaltyrun import io, runner
    jobs = runner.plan_jobs("zermelo", "default", param, "pso", n_starts=2, root_seed=7,
                            optimizer_options={"max_evals": 24, "n_particles": 4, "iters": 6})
    runner.execute(jobs, run_dir)
    io.collect(run_dir)
    return ["-m", f"param={param}", f"hydra.sweep.dir={run_dir}"]


def test_a_command_added_to_a_merged_study_extends_its_data_and_provenance(tmp_path):
    """``--only`` runs one command; ``extend`` keeps the records merged before beside the
    new ones (a job in both once, from the run), and the provenance lists both commands in
    the study's order; without ``extend`` the merge holds the run directory's alone."""
    _tiny_study(tmp_path)
    dest = tmp_path / "studies" / "tiny"
    first = _zermelo_jobs(tmp_path / "run" / "first", "diagonal")
    studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "run", dest=dest,
                        commands=[first], tables=False)
    (dest / "holdout_long.parquet").write_bytes(b"re-judged the records merged before")
    added = _zermelo_jobs(tmp_path / "later" / "added", "geagsp")
    _zermelo_jobs(tmp_path / "later" / "again", "diagonal")  # the same jobs run again
    merged = studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "later", dest=dest,
                                 commands=[added], tables=False, extend=True)
    frame = pq.read_table(merged).to_pandas()
    assert sorted(frame["param"]) == ["diagonal", "diagonal", "geagsp", "geagsp"]
    assert frame["job_id"].is_unique
    info = json.loads((dest / "provenance.json").read_text())
    # sweep directories inside the repository are recorded relative to it
    first, added = ([*c[:-1], f"hydra.sweep.dir={d}"] for c, d in
                    ((first, "run/first"), (added, "later/added")))
    assert info["commands"] == [first, added] and info["jobs"] == 4
    assert not (dest / "holdout_long.parquet").exists()
    study_file = dest / "study.yaml"
    study_file.write_text(study_file.read_text() + "drop_columns: [history]\n")
    again = studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "nothing", dest=dest,
                                tables=False, extend=True)  # nothing run: written again
    table = pq.read_table(again)
    assert table.num_rows == 4 and "history" not in table.column_names
    assert json.loads((dest / "provenance.json").read_text())["commands"] == [first, added]
    with pytest.raises(FileNotFoundError):
        studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "nothing", dest=dest,
                            tables=False)
    alone = studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "later" / "added",
                                dest=tmp_path / "alone", commands=[added], tables=False)
    assert set(pq.read_table(alone).to_pandas()["param"]) == {"geagsp"}


def test_a_merge_records_the_commands_hydra_recorded_in_the_run_directory(tmp_path):
    """Without commands given (runs made before the merge) each run subdir's
    ``multirun.yaml`` names the command that ran into it, its sweep directory relative to
    the repository; an extended merge puts it beside the commands recorded before. A
    damaged record is one study error."""
    _tiny_study(tmp_path)
    dest = tmp_path / "studies" / "tiny"
    first = _zermelo_jobs(tmp_path / "run" / "first", "diagonal")
    studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "run", dest=dest,
                        commands=[first], tables=False)
    run = tmp_path / "outputs" / "added"
    _zermelo_jobs(run / "added", "geagsp")
    (run / "added" / "multirun.yaml").write_text(
        "hydra:\n  overrides:\n    hydra: [hydra.mode=MULTIRUN]\n"
        "    task: [param=geagsp, runner.workers=2]\n")
    studies.merge_study(tmp_path, "tiny", run_dir=run, dest=dest, tables=False, extend=True)
    added = ["-m", "param=geagsp", "runner.workers=2", "hydra.sweep.dir=outputs/added/added"]
    # the command recorded before, with its absolute sweep directory, now relative too
    first = [*first[:-1], "hydra.sweep.dir=run/first"]
    assert json.loads((dest / "provenance.json").read_text())["commands"] == [first, added]
    (run / "added" / "multirun.yaml").write_text("hydra: [not, a, record]\n")
    with pytest.raises(studies.StudyError, match="not a Hydra multirun record"):
        studies.merge_study(tmp_path, "tiny", run_dir=run, dest=dest, tables=False)


def test_a_run_study_records_its_sweep_directories_relative_to_the_repository(tmp_path):
    argv = ["-m", "param=full", f"hydra.sweep.dir={tmp_path / 'outputs' / 'studies' / 'x'}"]
    assert provenance.portable(argv, tmp_path) == ["-m", "param=full",
                                                 "hydra.sweep.dir=outputs/studies/x"]
    assert provenance.portable(argv, tmp_path / "elsewhere") == argv


def test_an_extended_merge_records_the_machines_its_records_ran_on(tmp_path, monkeypatch):
    """Records merged before keep their machine beside the one an added command ran on; a
    rewrite with nothing run keeps the machines, versions, lock hash and re-judged data."""
    _tiny_study(tmp_path)
    dest = tmp_path / "studies" / "tiny"
    before = {"cpu": "cpu A", "cores": 2, "os": "os", "python": "3.11"}
    later = {"cpu": "cpu B", "cores": 4, "os": "os", "python": "3.11"}
    monkeypatch.setattr(provenance, "machine", lambda: dict(before))
    first = _zermelo_jobs(tmp_path / "run" / "first", "diagonal")
    studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "run", dest=dest,
                        commands=[first], tables=False)
    monkeypatch.setattr(provenance, "machine", lambda: dict(later))
    added = _zermelo_jobs(tmp_path / "later" / "added", "geagsp")
    studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "later", dest=dest,
                        commands=[added], tables=False, extend=True)
    info = json.loads((dest / "provenance.json").read_text())
    assert info["machines"] == [before, later] and info["machine"] == before
    info["packages"], info["lock_sha256"] = {"numpy": "0.0-recorded"}, "recorded"
    (dest / "provenance.json").write_text(json.dumps(info))
    (dest / "holdout_long.parquet").write_bytes(b"re-judged these very records")
    monkeypatch.setattr(provenance, "machine", lambda: {"cpu": "cpu C", "cores": 8})
    studies.merge_study(tmp_path, "tiny", run_dir=tmp_path / "nothing", dest=dest,
                        tables=False, extend=True)
    again = json.loads((dest / "provenance.json").read_text())
    assert again["machines"] == [before, later]
    assert again["packages"] == {"numpy": "0.0-recorded"} and again["lock_sha256"] == "recorded"
    assert (dest / "holdout_long.parquet").read_bytes() == b"re-judged these very records"


def test_only_names_a_command_of_the_study(tmp_path):
    from penaltyrun.docsgen.__main__ import main
    _tiny_study(tmp_path)
    study = studies.load_study(tmp_path, "tiny")
    assert [c.subdir for c in studies.selected_commands(study, ["added"])] == ["added"]
    assert [c.subdir for c in studies.selected_commands(study, [])] == ["first", "added"]
    with pytest.raises(studies.StudyError, match="no command 'nope' .*first, added"):
        studies.selected_commands(study, ["nope"])
    assert main(["--root", str(tmp_path), "study", "run", "tiny", "--only", "nope"]) == 2
