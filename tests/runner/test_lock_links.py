"""The run lock never writes through a symbolic link, a FIFO or a folder in its place."""

import os
import threading

import pytest

from penaltyrun.errors import ConfigError
from penaltyrun.runner import lock


@pytest.fixture
def victim(tmp_path):
    path = tmp_path / "precious.txt"
    path.write_text("precious data\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("target", ["file", "missing", "dir"])
def test_s7_a_lock_file_replaced_by_a_link_is_refused_untouched(tmp_path, victim, target):
    run = tmp_path / "run"
    run.mkdir()
    dest = {"file": victim, "missing": tmp_path / "created_through_link",
            "dir": tmp_path}[target]
    (run / lock.LOCK_FILE).symlink_to(dest)
    with pytest.raises(ConfigError, match="not a regular file.*remove it"):
        lock.acquire(run)
    assert victim.read_text(encoding="utf-8") == "precious data\n"
    assert not (tmp_path / "created_through_link").exists()
    assert lock.holder(run) == {} and not lock.is_locked(run)
    lock.release(run)


def test_f19_a_fifo_as_lock_file_is_refused_without_blocking(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    os.mkfifo(run / lock.LOCK_FILE)
    result = {}

    def take():
        try:
            lock.acquire(run)
        except ConfigError as exc:
            result["error"] = str(exc)

    worker = threading.Thread(target=take, daemon=True)
    worker.start()
    worker.join(10)
    assert not worker.is_alive(), "acquire blocked on a FIFO"
    assert "not a regular file" in result["error"]
    assert lock.holder(run) == {} and not lock.is_locked(run)


def test_a_regular_lock_file_still_works(tmp_path):
    lock.acquire(tmp_path)
    try:
        assert lock.holder(tmp_path)["pid"] == os.getpid()
    finally:
        lock.release(tmp_path)


def test_a_jobs_folder_that_is_a_link_is_refused(tmp_path):
    run, elsewhere = tmp_path / "run", tmp_path / "elsewhere"
    run.mkdir()
    elsewhere.mkdir()
    (run / "jobs").symlink_to(elsewhere)
    with pytest.raises(ConfigError, match="jobs is a symbolic link.*remove the link"):
        lock.acquire(run)
    assert list(elsewhere.iterdir()) == [] and not (run / lock.LOCK_FILE).exists()


@pytest.mark.parametrize("name", [lock.LOCK_FILE, "jobs", ".hydra", ".hydra/config.yaml",
                                  ".hydra/overrides.yaml", "cli.log"])
def test_the_preflight_refuses_links_in_place_of_the_runs_own_files(tmp_path, victim, name):
    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    if name == ".hydra":
        (run / ".hydra").rmdir()
    (run / name).symlink_to(victim)
    with pytest.raises(ConfigError, match="is a symbolic link.*remove it"):
        lock.check_not_locked(run)
    assert victim.read_text(encoding="utf-8") == "precious data\n"


@pytest.mark.parametrize("name", [lock.LOCK_FILE, ".hydra/config.yaml", "cli.log"])
def test_the_preflight_refuses_a_fifo_in_place_of_the_runs_own_files(tmp_path, name):
    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    os.mkfifo(run / name)
    with pytest.raises(ConfigError, match="not a regular file.*remove it"):
        lock.check_not_locked(run)


@pytest.mark.parametrize("name", ["multirun.yaml", "0_zermelo_full/.hydra/config.yaml",
                                  "0_zermelo_full/.penaltyrun.lock", "1_zermelo_full"])
def test_s7_a_sweep_refuses_links_in_its_own_and_its_runs_files(tmp_path, victim, name):
    """A sweep's ``multirun.yaml`` and the files of the run directories already in it (a
    resumed sweep writes into them), or a run directory itself, as a link: refused."""
    sweep = tmp_path / "sweep"
    (sweep / "0_zermelo_full" / ".hydra").mkdir(parents=True)
    (sweep / name).symlink_to(victim)
    with pytest.raises(ConfigError, match="is a symbolic link.*remove it"):
        lock.check_sweep_dir(sweep)
    assert victim.read_text(encoding="utf-8") == "precious data\n"
    (sweep / name).unlink()
    lock.check_sweep_dir(sweep)  # nothing else in the way
