"""A run directory whose own files are symbolic links (the lock, Hydra's config files) is
refused before Hydra writes anything: one line, exit 2, the link's target untouched."""

import pytest
from cli_subprocess import cli_forked


@pytest.mark.parametrize("name", [".penaltyrun.lock", ".hydra/config.yaml"])
def test_s7_links_in_a_run_directory_are_refused_before_anything_is_written(tmp_path, name):
    victim = tmp_path / "precious.txt"
    victim.write_text("precious data\n", encoding="utf-8")
    run = tmp_path / "run"
    (run / ".hydra").mkdir(parents=True)
    (run / name).symlink_to(victim)
    (proc,) = cli_forked([(["problem=zermelo", "runner.n_starts=1", "runner.resume=true",
                            f"hydra.run.dir={run}"], tmp_path)])
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "symbolic link" in lines[0] and "remove it" in lines[0]
    assert victim.read_text(encoding="utf-8") == "precious data\n"


def test_s8_a_report_link_in_a_run_directory_is_refused_before_any_job(tmp_path):
    """The run's report folder (``<run dir>/report``) is a link: refused in one line before
    any job runs, not after all of them."""
    victim = tmp_path / "elsewhere"
    victim.mkdir()
    run = tmp_path / "run"
    run.mkdir()
    (run / "report").symlink_to(victim)
    (proc,) = cli_forked([(["problem=zermelo", "runner.n_starts=1",
                            f"hydra.run.dir={run}"], tmp_path)])
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.strip().splitlines() if "INFO" not in line]
    assert lines[-1].startswith("penaltyrun: error: report.output:") and "symbolic link" \
        in lines[-1]
    assert not (run / "jobs").exists() and list(victim.iterdir()) == []
