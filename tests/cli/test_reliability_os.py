"""Every OS error a user can cause is one line and a documented exit code (subprocess
tests): bad run and output paths, a full disk, a non-UTF-8 locale, an unwritable stdout."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from cli_subprocess import FAST_JOBS, cli, one_error_line, report

from penaltyrun.cli import EXIT_CODES, EXIT_ENVIRONMENT
from penaltyrun.io import RESULTS_FILE


def test_environment_exit_code_is_documented():
    assert EXIT_ENVIRONMENT == 5 and "disk full" in EXIT_CODES[EXIT_ENVIRONMENT]


def test_dangling_symlink_run_dir_is_refused(tmp_path):
    (tmp_path / "link").symlink_to(tmp_path / "gone")
    proc = cli(*FAST_JOBS, f"hydra.run.dir={tmp_path / 'link'}", cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "symbolic link" in line and "does not exist" in line


def test_results_parquet_directory_is_refused(tmp_path):
    run = tmp_path / "run"
    (run / RESULTS_FILE).mkdir(parents=True)
    proc = cli(*FAST_JOBS, f"hydra.run.dir={run}", cwd=tmp_path, timeout=120)
    assert proc.returncode == 2
    assert "results.parquet exists and is not a file" in one_error_line(proc)


def test_report_output_on_a_file_is_refused(tmp_path):
    run = tmp_path / "run"
    assert cli(*FAST_JOBS, "runner.n_starts=1", f"hydra.run.dir={run}",
               cwd=tmp_path).returncode == 0
    (tmp_path / "afile").write_text("")
    rep = report(str(run), "-o", str(tmp_path / "afile"), timeout=300)
    assert rep.returncode == 2
    assert "is a file" in one_error_line(rep)
    proc = cli("mode=report", f"report.input={run}", f"report.output={tmp_path / 'afile'}",
               cwd=tmp_path, timeout=120)
    assert proc.returncode == 2 and "report.output" in one_error_line(proc)


def test_a_non_utf8_locale_writes_utf8(tmp_path):
    run = tmp_path / "run"
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0"}
    env.pop("PYTHONIOENCODING", None)
    proc = cli("problem=zermelo", "optimizer=baseline", "runner.n_starts=1",
               f"hydra.run.dir={run}", cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert "Logging error" not in proc.stderr + proc.stdout
    assert (run / "report").is_dir()
    for path in (run / "report").rglob("*.md"):
        path.read_text(encoding="utf-8")


def test_stdout_on_dev_full_is_one_line(tmp_path):
    if not Path("/dev/full").exists():
        pytest.skip("no /dev/full")
    with open("/dev/full", "w") as full:
        proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                               "problem=zermelo", "matrices.K=[[1,0],[0,1]]"], cwd=tmp_path,
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=300)
    assert proc.returncode == EXIT_ENVIRONMENT, proc.stderr
    assert "standard output" in one_error_line(proc)


@pytest.fixture
def small_tmpfs(tmp_path):
    mnt = tmp_path / "tmpfs"
    mnt.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                        capture_output=True)
    if ok.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {ok.stderr.decode(errors='replace').strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def _fill(folder: Path, leave: int) -> Path:
    """Fill the file system of ``folder`` but ``leave`` bytes."""
    filler = folder / "filler"
    free = shutil.disk_usage(folder).free
    with open(filler, "wb") as fh:
        fh.write(b"\0" * max(0, free - leave))
    return filler


@pytest.mark.slow  # about 13 s: a tmpfs, a bind mount and two runs
def test_disk_full_while_writing_records_is_one_line_and_resume_finishes(tmp_path, small_tmpfs):
    run = tmp_path / "run"
    (run / "jobs").mkdir(parents=True)
    (small_tmpfs / "jobs").mkdir()
    # records on the small disk: a bind mount (a run refuses a symlinked jobs/ folder)
    bound = subprocess.run(["mount", "--bind", str(small_tmpfs / "jobs"), str(run / "jobs")],
                           capture_output=True)
    if bound.returncode != 0:
        pytest.skip(f"cannot bind-mount: {bound.stderr.decode(errors='replace').strip()}")
    try:
        _disk_full_records(run, small_tmpfs)
    finally:
        subprocess.run(["umount", "-l", str(run / "jobs")], capture_output=True)


def _disk_full_records(run: Path, small_tmpfs: Path) -> None:
    tmp_path = run.parent
    args = [*FAST_JOBS, "runner.n_starts=4", f"hydra.run.dir={run}"]
    filler = _fill(small_tmpfs, 12_000)  # room for about one record
    proc = cli(*args, cwd=tmp_path)
    assert proc.returncode == EXIT_ENVIRONMENT, proc.stderr
    line = one_error_line(proc)
    assert "No space left on device" in line and str(run / "jobs") in line and "free" in line
    assert not [p for p in (small_tmpfs / "jobs").iterdir() if p.name.endswith(".tmp")]
    kept = len(list((small_tmpfs / "jobs").glob("*.json")))
    filler.unlink()
    resumed = cli(*args, "runner.resume=true", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{kept} of 4 jobs already finished" in resumed.stderr + resumed.stdout
    assert len(pd.read_parquet(run / RESULTS_FILE)) == 4
    assert all(json.loads(p.read_text())["status"] == "ok"
               for p in (small_tmpfs / "jobs").glob("*.json"))


@pytest.mark.slow  # about 6 s (the record-writing case stays in the default suite)
def test_disk_full_while_writing_the_parquet_is_one_line(tmp_path, small_tmpfs):
    run = small_tmpfs / "run"
    args = [*FAST_JOBS, "runner.n_starts=2", f"hydra.run.dir={run}"]
    assert cli(*args, cwd=tmp_path).returncode == 0
    (run / RESULTS_FILE).unlink()
    filler = _fill(small_tmpfs, 0)
    proc = cli(*args, "runner.resume=true", cwd=tmp_path)
    assert proc.returncode == EXIT_ENVIRONMENT, proc.stderr
    assert "No space left on device" in one_error_line(proc)
    assert not [p for p in run.rglob("*.tmp")]
    filler.unlink()


def _mount_tmpfs(mnt: Path, options: str) -> None:
    mnt.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(mnt)],
                        capture_output=True)
    if ok.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {ok.stderr.decode(errors='replace').strip()}")


def test_a_read_only_run_dir_is_one_line_before_any_job(tmp_path):
    """A folder on a read-only file system is refused with the other bad run folders: one
    line naming it and the fix, exit code 2, before any job runs."""
    mnt = tmp_path / "ro"
    _mount_tmpfs(mnt, "ro,size=64k")
    try:
        proc = cli(*FAST_JOBS, f"hydra.run.dir={mnt / 'run'}", cwd=tmp_path, timeout=120)
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)
    assert proc.returncode == 2
    line = one_error_line(proc)
    assert "hydra.run.dir" in line and str(mnt / "run") in line
    assert "Read-only file system" in line and "choose a folder you can write to" in line


def test_out_of_inodes_is_said_so_not_as_megabytes_free(tmp_path):
    """A file system with room but no free inodes fails with ENOSPC too; the line says
    there are no free inodes instead of pointing at the megabytes left."""
    import errno

    from penaltyrun.errors import describe_os_error, free_space

    mnt = tmp_path / "few_inodes"
    _mount_tmpfs(mnt, "size=4m,nr_inodes=16")
    try:
        with pytest.raises(OSError) as full:
            for k in range(100):
                (mnt / f"f{k}").write_bytes(b"")
        assert full.value.errno == errno.ENOSPC
        assert free_space(mnt).startswith("no free inodes (")
        line = describe_os_error(full.value)
        assert str(mnt) in line and "no free inodes" in line
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


def test_a_disk_full_error_without_a_path_names_no_other_disk():
    """An ENOSPC of a write to an open file carries no path: the line gives no free space
    (the current folder may be on another disk) rather than a wrong one."""
    import errno

    from penaltyrun.errors import describe_os_error

    line = describe_os_error(OSError(errno.ENOSPC, "No space left on device"))
    assert line.startswith("cannot write a file: No space left on device;")
    assert " free)" not in line and "runner.resume=true" in line


@pytest.mark.slow  # about 10 s: a run, its report and an export onto a full disk
def test_an_export_onto_a_full_disk_is_one_line_and_leaves_no_file(tmp_path, small_tmpfs):
    run = tmp_path / "run"
    assert cli(*FAST_JOBS, "runner.n_starts=2", f"hydra.run.dir={run}",
               cwd=tmp_path).returncode == 0
    exported = small_tmpfs / "export"
    exported.mkdir()
    filler = _fill(small_tmpfs, 0)
    proc = report(str(run), "-o", str(tmp_path / "rep"), "--export", str(exported))
    filler.unlink()
    assert proc.returncode == EXIT_ENVIRONMENT, proc.stderr
    line = one_error_line(proc)
    assert "No space left on device" in line and str(exported) in line
    assert list(exported.iterdir()) == []  # no empty JSON, no temporary folder
