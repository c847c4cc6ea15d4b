"""What a report folder owns: only plain names inside it, whatever an old report lists."""

import os

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.report import outdir


def test_an_old_report_owns_only_plain_png_names_inside_the_folder(tmp_path):
    (tmp_path / "report.md").write_text(
        "# r\n\n![a](fig.png)\n![b](../outside.png)\n![c](/abs/x.png)\n![d](.hidden.png)\n"
        "![e](notes.txt)\n![f](sub/x.png)\n", encoding="utf-8")
    owned = outdir.report_files(tmp_path, ["summary"])
    assert owned == {"report.md", "report.html", "summary.csv", "summary.md", "fig.png"}


def test_an_old_export_owns_only_the_json_and_mat_files_its_index_lists(tmp_path):
    (tmp_path / "index.csv").write_text(
        "problem,json,mat\na,a.json,a.mat\nb,../b.json,/abs/b.mat\nc,c.csv,c.py\n",
        encoding="utf-8")
    assert outdir.export_files(tmp_path) == {"index.csv", "a.json", "a.mat"}


def test_a_linked_or_fifo_report_md_owns_nothing(tmp_path):
    elsewhere = tmp_path / "elsewhere.md"
    elsewhere.write_text("![a](fig.png)\n", encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").symlink_to(elsewhere)
    assert outdir.report_files(out, []) == set()
    (out / "report.md").unlink()
    os.mkfifo(out / "report.md")
    assert outdir.report_files(out, []) == set()  # and it did not block


def test_the_output_folder_may_not_be_a_link_or_a_file(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    (tmp_path / "file").write_text("x", encoding="utf-8")
    with pytest.raises(ConfigError, match="symbolic link"):
        outdir.prepare(tmp_path / "link", "-o")
    with pytest.raises(ConfigError, match="is a file"):
        outdir.prepare(tmp_path / "file", "-o")
    assert outdir.prepare(tmp_path / "new" / "folder", "-o").is_dir()


def test_report_html_embeds_only_regular_png_files_of_its_folder(tmp_path):
    from penaltyrun.report.html import to_html

    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG SECRET")
    folder = tmp_path / "report"
    folder.mkdir()
    (folder / "own.png").write_bytes(b"\x89PNG OWN")
    (folder / "link.png").symlink_to(secret)
    (folder / "secret.txt").write_bytes(b"SECRET TEXT")
    page = to_html(f"![a]({secret})\n\n![b](../secret.png)\n\n![c](link.png)\n\n"
                   "![d](secret.txt)\n\n![e](own.png)\n", folder)
    assert page.count("data:image/png;base64,") == 1 and page.count("missing figure") == 4


def test_temporary_folders_of_killed_reports_are_removed_by_the_next_one(tmp_path):
    """A report killed with SIGKILL leaves its ``.report-<pid>-XXXX`` folder; the next report
    into the folder removes the folders of processes that no longer run, and only those."""
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead_pid = int(dead.stdout)
    abandoned = tmp_path / f".report-{dead_pid}-k1ll3d"
    abandoned.mkdir()
    (abandoned / "summary.csv").write_text("half written", encoding="utf-8")
    running = tmp_path / f".report-{os.getpid()}-busy"  # a report still writing
    running.mkdir()
    mine = tmp_path / ".report-notes"  # not a report's temporary folder
    mine.mkdir()
    other_prefix = tmp_path / f".export-{dead_pid}-k1ll3d"
    other_prefix.mkdir()

    def write(tmp):
        (tmp / "report.md").write_text("# r\n", encoding="utf-8")

    outdir.write_into(tmp_path, "report.output", write, lambda out: set())
    assert not abandoned.exists()
    assert running.is_dir() and mine.is_dir() and other_prefix.is_dir()
    assert (tmp_path / "report.md").is_file()
    assert not [p for p in tmp_path.iterdir()
                if p.name.startswith(f".report-{os.getpid()}-") and p != running]


@pytest.mark.parametrize("given", ["received/report/v2", "received/lnk/../out",
                                   "{abs}/received/report/v2"])
def test_s8_an_output_path_through_a_link_inside_the_results_folder_is_refused(
        tmp_path, monkeypatch, given):
    """A received folder may hold links pointing anywhere: ``-o`` through one of them
    (also followed by ``..``) is refused before anything is written."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    received = tmp_path / "received"
    received.mkdir()
    (received / "report").symlink_to(elsewhere, target_is_directory=True)
    (received / "lnk").symlink_to(elsewhere / "deep", target_is_directory=True)
    (elsewhere / "deep").mkdir()
    monkeypatch.chdir(tmp_path)
    out = given.format(abs=tmp_path)
    with pytest.raises(ConfigError, match="symbolic link inside the results folder"):
        outdir.write_into(out, "report.output", lambda tmp: None, lambda folder: set(),
                          source=received)
    assert sorted(p.name for p in elsewhere.rglob("*")) == ["deep"]


def test_links_outside_the_results_folder_are_the_users_own(tmp_path, monkeypatch):
    """A link on the way to the output that is not inside the results folder (a home
    folder linked elsewhere) is followed as usual."""
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "home").symlink_to(real, target_is_directory=True)
    (tmp_path / "received").mkdir()
    monkeypatch.chdir(tmp_path)
    outdir.write_into("home/report", "report.output",
                      lambda tmp: (tmp / "a.md").write_text("x"), lambda folder: set(),
                      source=tmp_path / "received")
    assert (real / "report" / "a.md").read_text() == "x"
