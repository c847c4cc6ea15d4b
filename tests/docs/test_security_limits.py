"""The limits stated in docs/explanation/security.md are the code's."""

from pathlib import Path

from penaltyrun import yamlsafe
from penaltyrun.cli import overrides, userconf
from penaltyrun.io import filecheck
from penaltyrun.problems.lqr import plant

PAGE = Path(__file__).resolve().parents[2] / "docs" / "explanation" / "security.md"


def test_the_page_states_the_limits_of_the_code():
    text = PAGE.read_text(encoding="utf-8")
    assert f"1 MiB ({yamlsafe.MAX_BYTES} bytes)" in text and yamlsafe.MAX_BYTES == 1 << 20
    assert f"| {yamlsafe.MAX_DEPTH} levels |" in text
    assert f"| {yamlsafe.MAX_ALIAS_VALUES} values added when expanded |" in text
    assert (f"| {overrides.MAX_CHARS} characters, {overrides.MAX_VALUES} comma-separated "
            f"values, {yamlsafe.MAX_DEPTH} levels of brackets |") in text
    assert f"| {filecheck.MAX_FILE_ROWS} rows, 4 GiB ({filecheck.MAX_FILE_BYTES} bytes) |" in text
    assert filecheck.MAX_FILE_BYTES == 4 << 30
    assert f"| one `-m` command | {overrides.MAX_RUNS} runs |" in text
    assert f"| 64 MiB ({plant.MAX_PLANT_BYTES} bytes) of arrays once read |" in text
    assert plant.MAX_PLANT_BYTES == 64 << 20
    assert userconf.SCAN_DEPTH == 3 and "`DIR/a/b/x.yaml`" in text


def test_the_sweeps_page_states_the_override_limits():
    text = (PAGE.parents[1] / "how-to" / "sweeps.md").read_text(encoding="utf-8")
    assert f"at most {overrides.MAX_VALUES} comma-separated values" in text
    assert f"and {overrides.MAX_CHARS} characters" in text
    assert f"together make at most {overrides.MAX_RUNS} runs" in text
    assert "(../explanation/security.md#limits-on-what-is-read)" in text
