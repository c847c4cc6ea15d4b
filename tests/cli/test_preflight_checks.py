"""Preflight checks of a composed config (penaltyrun/cli/checks.py)."""

import pytest

from penaltyrun.cli import checks
from penaltyrun.errors import ConfigError
from penaltyrun.runner.options import check_report_options


def test_run_dir_checks(tmp_path):
    checks.check_run_dir(tmp_path / "a" / "b")
    assert list(tmp_path.iterdir()) == []  # nothing left behind
    checks.check_run_dir(tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(ConfigError, match="is a file"):
        checks.check_run_dir(tmp_path / "file" / "run")
    with pytest.raises(ConfigError, match="not a directory"):
        checks.check_run_dir(tmp_path / "file")
    with pytest.raises(ConfigError, match="hydra.run.dir: cannot create"):
        checks.check_run_dir("/proc/penaltyrun-test/run")


def test_unknown_and_deleted_keys():
    base = {"runner": {"seed": 1, "workers": 1}, "matrices": {"K": None}}
    checks.check_known_keys({"runner": {"seed": 2, "workers": 1},
                             "matrices": {"K": None, "P": [[1]]}}, base)
    with pytest.raises(ConfigError, match="runner.foo: unknown config key"):
        checks.check_known_keys({"runner": {"seed": 1, "workers": 1, "foo": 1},
                                 "matrices": {}}, base)
    with pytest.raises(ConfigError, match="runner.workers: is required"):
        checks.check_known_keys({"runner": {"seed": 1}, "matrices": {}}, base)


def test_the_charge_per_gradient_may_be_added_after_any_preset():
    base = {"optimizer": {"name": "cmaes", "polish": "gradient"}}
    checks.check_known_keys({"optimizer": {"name": "cmaes", "polish": "gradient",
                                           "grad_cost": 3.0}}, base)
    with pytest.raises(ConfigError, match="optimizer.grad_costs: unknown config key"):
        checks.check_known_keys({"optimizer": {"name": "cmaes", "polish": "gradient",
                                               "grad_costs": 3.0}}, base)


def test_report_and_param_options():
    check_report_options({"input": None, "output": "x", "paper": True})
    with pytest.raises(ConfigError, match="report.paper"):
        check_report_options({"paper": "maybe"})
    with pytest.raises(ConfigError, match="report.nope"):
        check_report_options({"nope": 1})
    checks.check_param_options({"eig_bounds": None, "cayley_bound": 100.0})
    for bad in ({"eig_bounds": [2, 1]}, {"eig_bounds": "x"}, {"cayley_bound": 0}):
        with pytest.raises(ConfigError):
            checks.check_param_options(bad)


def test_run_dir_kinds_refused(tmp_path):
    (tmp_path / "link").symlink_to(tmp_path / "gone")
    with pytest.raises(ConfigError, match="symbolic link .* does not exist"):
        checks.check_run_dir(tmp_path / "link")
    with pytest.raises(ConfigError, match="symbolic link"):
        checks.check_run_dir(tmp_path / "link" / "run")
    (tmp_path / "run" / "results.parquet").mkdir(parents=True)
    with pytest.raises(ConfigError, match="results.parquet exists and is not a file"):
        checks.check_run_dir(tmp_path / "run")
    (tmp_path / "afile").write_text("")
    with pytest.raises(ConfigError, match="-o: .* is a file"):
        checks.check_output_dir(tmp_path / "afile", "-o")
    checks.check_output_dir(None)
    checks.check_output_dir(tmp_path / "new" / "report")


def test_matrix_entries_must_be_numbers():
    checks.check_matrix_entries({"K": [[1, 0.5], [0.5, 2]], "Q": None}, "matrices")
    for bad in ([[True, False], [False, True]], [[1, "a"], [0, 1]], True):
        with pytest.raises(ConfigError, match="matrices.K: entries must be numbers"):
            checks.check_matrix_entries({"K": bad}, "matrices")


def test_command_line_values_are_checked_against_the_profiles_problems():
    """A profile that sweeps ``problem`` with a command-line ``case`` list: the cases are
    checked against the profile's problems, not against the default problem."""
    from penaltyrun.cli.preflight import preflight

    assert preflight(["-m", "+experiment=lowthrust_baseline", "case=A,C"]) == "optimize"
    with pytest.raises(ConfigError, match="case: unknown case 'Z' for problem"):
        preflight(["-m", "+experiment=lowthrust_baseline", "case=A,Z"])
    with pytest.raises(ConfigError, match="param: unknown choice 'bogus'"):
        preflight(["-m", "+experiment=referee_zermelo", "param=diagonal,bogus"])


def test_sweeper_params_on_the_command_line_are_one_line():
    from penaltyrun.cli.preflight import preflight

    with pytest.raises(ConfigError, match="bogus=a,b with -m"):
        preflight(["-m", "mode=plan", "hydra.sweeper.params.bogus=1"])


def test_the_root_folder_as_a_choice_is_one_line():
    from penaltyrun.cli.preflight import preflight

    with pytest.raises(ConfigError, match="not a path"):
        preflight(["problem=/", "mode=plan"])


def test_an_experiment_profile_sweep_beyond_the_size_limit_is_one_error(tmp_path):
    from penaltyrun.cli.overrides import MAX_VALUES
    from penaltyrun.cli.preflight import preflight

    (tmp_path / "experiment").mkdir()
    values = ",".join(map(str, range(MAX_VALUES + 1)))
    (tmp_path / "experiment" / "big.yaml").write_text(
        f"# @package _global_\nhydra:\n  sweeper:\n    params:\n      runner.seed: {values}\n")
    with pytest.raises(ConfigError, match=f"the limit is {MAX_VALUES} per override") as err:
        preflight(["--config-dir", str(tmp_path), "+experiment=big", "-m", "mode=plan"])
    assert err.value.key == "hydra.sweeper.params.runner.seed"
    (tmp_path / "experiment" / "big.yaml").write_text(
        "# @package _global_\nhydra:\n  sweeper:\n    params:\n"
        "      runner.seed: range(0,1000000)\n")
    with pytest.raises(ConfigError, match="sweep of 1000000 values"):
        preflight(["--config-dir", str(tmp_path), "+experiment=big", "-m", "mode=plan"])


def test_b4_sweeps_whose_product_is_too_large_are_refused_at_once(tmp_path):
    """Each sweep within its own limit, together a million runs: one line before Hydra
    expands anything; an experiment profile's sweeps count too."""
    from penaltyrun.cli.overrides import MAX_RUNS
    from penaltyrun.cli.preflight import preflight

    with pytest.raises(ConfigError, match=f"the sweeps make 1000000 runs .*the limit is "
                                          f"{MAX_RUNS} runs per command"):
        preflight(["-m", "mode=plan", "runner.seed=range(0,1000)",
                   "optimizer.max_evals=range(100,1100)"])
    (tmp_path / "experiment").mkdir()
    (tmp_path / "experiment" / "wide.yaml").write_text(
        "# @package _global_\nhydra:\n  sweeper:\n    params:\n"
        "      runner.seed: range(0,1000)\n")
    with pytest.raises(ConfigError, match="the sweeps make 20000 runs"):
        preflight(["--config-dir", str(tmp_path), "+experiment=wide", "-m", "mode=plan",
                   "runner.n_starts=range(1,21)"])
    (tmp_path / "experiment" / "named.yaml").write_text(  # a hydra.* key is swept too
        "# @package _global_\nhydra:\n  sweeper:\n    params:\n"
        "      runner.seed: range(0,200)\n      hydra.job.name: range(0,200)\n")
    with pytest.raises(ConfigError, match="the sweeps make 40000 runs"):
        preflight(["--config-dir", str(tmp_path), "+experiment=named", "-m", "mode=plan"])
    assert preflight(["-m", "mode=plan", "runner.seed=range(0,10)",
                      "optimizer.max_evals=range(100,110)"]) == "plan"


def test_a_sweep_cell_whose_grid_is_too_large_fails_in_the_preflight():
    """The preflight builds each cell as the runner does (with the optimizer's dimension
    check): a later cell of a sweep that the runner would refuse is refused before any
    cell runs."""
    from penaltyrun.cli.preflight import preflight

    with pytest.raises(ConfigError, match="optimizer: grid search is for at most 4 decision "
                                          "variables; this problem and map have 5"):
        preflight(["-m", "problem=zermelo,lqr", "optimizer=grid", "param=diagonal",
                   "hydra.sweep.dir=/tmp/penaltyrun-preflight-never-written"])


def test_a_warm_start_without_budget_fails_in_the_preflight():
    from penaltyrun.cli.preflight import preflight

    with pytest.raises(ConfigError, match="runner.warm_start: needs an evaluation budget"):
        preflight(["problem=zermelo", "runner.warm_start=true",
                   "hydra.run.dir=/tmp/penaltyrun-preflight-never-written"])


def test_a_folder_name_longer_than_a_file_system_takes_is_one_config_error(tmp_path):
    """300 bytes in one name: refused naming the key (the run failed later with exit 5 and
    the system's "File name too long", naming no key)."""
    with pytest.raises(ConfigError, match="at most 255 bytes a name") as err:
        checks.check_run_dir(tmp_path / ("a" * 300), "hydra.sweep.dir")
    assert err.value.key == "hydra.sweep.dir"
    checks.check_run_dir(tmp_path / ("a" * 255))
