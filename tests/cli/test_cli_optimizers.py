"""Command-line errors of the budget, CMA-ES, grid and warm-start settings (one line, exit 2)."""

import pytest
from cli_subprocess import bad_command_lines

#: Bad optimizer settings and the fragments their one error line must name.
BAD_SETTINGS = [
    (["optimizer=cmaes", "optimizer.sigma0=3"], ["optimizer.sigma0", "(0, 1]"]),
    (["optimizer=cmaes", "optimizer.restarts=-2"], ["optimizer.restarts"]),
    (["optimizer=cmaes", "optimizer.popsize=1"], ["optimizer.popsize"]),
    (["optimizer.max_evals=0"], ["optimizer.max_evals", "positive"]),
    (["optimizer.polish=newton"], ["optimizer.polish", "L-BFGS-B"]),
    (["optimizer=grid", "problem=attitude_lyapunov", "param=diagonal"],
     ["optimizer", "at most 4", "6"]),
    (["optimizer=grid", "optimizer.max_evals=100"], ["optimizer.max_evals", "grid needs"]),
    (["runner.warm_start=true"], ["runner.warm_start", "optimizer.max_evals"]),
    (["runner.warm_start=true", "optimizer.max_evals=100", "runner.warm_start_share=1.5"],
     ["runner.warm_start_share", "(0, 1)"]),
]


@pytest.fixture(scope="module")
def bad_setting_runs(tmp_path_factory):
    """Every bad setting run at once, each in a process of its own (see ``cli_forked``)."""
    return bad_command_lines(BAD_SETTINGS, tmp_path_factory)


@pytest.mark.parametrize("case", range(len(BAD_SETTINGS)),
                         ids=[" ".join(args) for args, _ in BAD_SETTINGS])
def test_bad_optimizer_settings_are_one_line(bad_setting_runs, case):
    proc, cwd = bad_setting_runs[case]
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    for fragment in BAD_SETTINGS[case][1]:
        assert fragment in proc.stderr, proc.stderr
    assert not (cwd / "run" / "jobs").exists()
