"""The checks answered before Hydra is imported (penaltyrun/quickcheck.py): each refusal
is the preflight's own, and nothing the preflight accepts is refused."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.cli.preflight import preflight
from penaltyrun.cli.quickcheck import check_plain_values, literal
from penaltyrun.errors import ConfigError

REFUSED = [
    ["runner.n_starts=0"], ["runner.n_starts=-3"], ["runner.n_starts=1.5"],
    ["runner.n_starts=true"], ["runner.n_starts=100001"], ["runner.seed=-1"],
    ["runner.workers=0"], ["runner.workers=many"], ["runner.backend=ray"],
    ["runner.resume=1"], ["runner.job_timeout=0"], ["runner.job_timeout=-2.5e1"],
    ["runner.warm_start_share=1.0"], ["runner.warm_start_share=0"],
    ["runner.progress=sometimes"], ["runner.chunks=0"], ["runner.evaluate_on=gpu"],
    ["runner.max_retries=-1"], ["runner.stall_timeout=.0"], ["mode=optimise"],
    ["mode=1"], ["-m", "problem=zermelo", "runner.n_starts=0"],
    ["problem=zermelo", "runner.report=null"],
    ["optimizer.n_particles=0"], ["optimizer.w=abc"], ["optimizer.iters=1.5"],
    ["optimizer=cmaes", "optimizer.popsize=-2"], ["optimizer=de", "optimizer.polish=bogus"],
    ["mode=plan", "optimizer=pso_matlab", "optimizer.max_evals=0"],
    ["optimizer=pso_paper_50x50", "optimizer.polish_share=2.0"],
    ["param=bogus"], ["problem=zermelo2", "runner.n_starts=3"], ["optimizer=psoo"],
    ["+experiment=nope"], ["-m", "param=givenz"], ["optimizer=bogus", "optimizer.w=1"],
    ["runner=5"], ["report=5"], ["mode=evaluate", "problem=zermelo", "matrices=5"],
    ["problem.params=3"], ["runner.forecast_samples=100000000"],
    ["runner.forecast_samples=-1"],
]


def _full(argv: list[str], tmp_path) -> str | None:
    """The preflight's error line for ``argv`` (run directory under ``tmp_path``)."""
    run_dir = "hydra.sweep.dir" if "-m" in argv else "hydra.run.dir"
    try:
        preflight([*argv, f"{run_dir}={tmp_path / 'run'}"])
    except ConfigError as exc:
        return str(exc)
    return None


@pytest.mark.parametrize("argv", [["runner=null"], ["hydra=5"], ["-m", "runner=5,6"],
                                  ["+runner=[1]"]], ids=" ".join)
def test_one_value_for_a_group_of_settings_is_refused_first(argv):
    """``runner=5`` (or a sweep of such values): one line naming the key and the fix,
    before Hydra, which would stop with a traceback."""
    with pytest.raises(ConfigError, match="is a group of settings, not one value: set one "
                                          "of its keys, .*<key>=VALUE"):
        check_plain_values(argv)


@pytest.mark.parametrize("argv", REFUSED, ids=" ".join)
def test_refusals_are_the_preflights(argv, tmp_path):
    with pytest.raises(ConfigError) as quick:
        check_plain_values(argv)
    assert str(quick.value) == _full(argv, tmp_path)


@pytest.mark.parametrize("argv", [
    ["param=givens", "problem=lqr", "optimizer=cmaes", "+experiment=zermelo_paper"],
    ["param=diagonal,bogus"], ["hydra.searchpath=[file:///tmp]", "param=mine"],
    ["runner.n_starts=3"], ["runner.seed=0"], ["runner.workers=auto"],
    ["runner.job_timeout=null"], ["runner.warm_start_share=0.5"], ["mode=plan"],
    ["runner.progress=auto"], ["runner.chunks=auto"],
    ["runner.n_starts='0'"], ["runner.n_starts=0,1"], ["+runner.n_starts=0"],
    ["runner.n_starts=${runner.seed}"], ["runner.bogus=0"], ["--cfg", "job", "runner.n_starts=0"],
    ["runner.n_starts=007"], ["runner.job_timeout=inf"],
    ["optimizer.n_particles=40"], ["optimizer.bogus=1"],
    ["mode=evaluate", "optimizer.n_particles=0"],
    ["+experiment=zermelo_paper", "optimizer.iters=0"],
    ["optimizer=cmaes", "optimizer.n_particles=0"],
])
def test_left_to_the_preflight(argv):
    """Values that pass, and anything that is not a plain literal (or comes with options
    that change the config), are not answered here."""
    check_plain_values(argv)


def test_a_choice_misplaced_in_the_current_directory_gets_the_preflights_hint(
        tmp_path, monkeypatch):
    """``problem=mine`` with ``mine.yaml`` lying in the current directory: the hint of
    :func:`penaltyrun.cli.userconf.misplaced`, as the preflight gives it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.yaml").write_text("name: zermelo\n")
    argv = ["problem=mine"]
    with pytest.raises(ConfigError) as quick:
        check_plain_values(argv)
    assert "mine.yaml" in str(quick.value)
    assert str(quick.value) == _full(argv, tmp_path)


@settings(max_examples=80, deadline=None)
@given(st.from_regex(r"[+-]?[0-9]{0,3}(\.[0-9]{0,2})?([eE][+-]?[0-9])?", fullmatch=True))
def test_numbers_are_read_as_hydra_reads_them(text):
    """A literal read here is the value (and type) Hydra's grammar gives it; others are
    left alone (``_SKIP``)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from penaltyrun.cli.quickcheck import _SKIP

    value = literal(text)
    if value is _SKIP:
        return
    hydra_value = OverridesParser.create().parse_override(f"a={text}").value()
    assert value == hydra_value and type(value) is type(hydra_value)


@pytest.mark.parametrize("text", ["true", "False", "NULL", "auto", "local", "x_1"])
def test_words_are_read_as_hydra_reads_them(text):
    from hydra.core.override_parser.overrides_parser import OverridesParser

    hydra_value = OverridesParser.create().parse_override(f"a={text}").value()
    assert literal(text) == hydra_value and type(literal(text)) is type(hydra_value)
