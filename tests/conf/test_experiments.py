"""Experiment profiles compose, and ``acc_attitude`` is the companion study's design."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from penaltyrun import problems

CONF = Path(__file__).resolve().parents[2] / "penaltyrun" / "conf"


@pytest.mark.parametrize("name", sorted(p.stem for p in (CONF / "experiment").glob("*.yaml")))
def test_profile_composes(name):
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"+experiment={name}"])
    assert cfg.problem.name in problems.available()


#: Profiles preflighted in the default suite: the ones with lists of scenario mappings (a
#: list of mappings once failed the list-of-numbers check) and a multi-cell sweep; every
#: profile is preflighted in the slow suite (about a second each: one composition per cell).
PREFLIGHT_DEFAULT = ("attitude_multiscenario", "lowthrust_multiscenario", "robust_mpc",
                     "lqr_scaling_n4")


@pytest.mark.parametrize("name", [
    name if name in PREFLIGHT_DEFAULT else pytest.param(name, marks=pytest.mark.slow)
    for name in sorted(p.stem for p in (CONF / "experiment").glob("*.yaml"))])
def test_profile_passes_the_preflight(name):
    """The command line's checks accept every shipped profile (a profile's list of scenario
    mappings once failed the list-of-numbers check and no study of it could start)."""
    from penaltyrun.cli.preflight import preflight

    preflight(["-m", f"+experiment={name}"])


def test_acc_attitude_profile():
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="config", overrides=["+experiment=acc_attitude"],
                      return_hydra_config=True)
    assert cfg.problem.name == "attitude_lyapunov" and cfg.runner.n_starts == 20
    # MATLAB particleswarm defaults: swarm min(100, 10 nvars), stall 1e-6 over 20
    assert cfg.optimizer.name == "pso_matlab" and cfg.optimizer.swarm_size is None
    assert cfg.optimizer.max_iterations is None
    assert (cfg.optimizer.function_tolerance, cfg.optimizer.max_stall_iterations) == (1e-6, 20)
    sweep = yaml.safe_load((CONF / "experiment" / "acc_attitude.yaml").read_text())
    params = sweep["hydra"]["sweeper"]["params"]
    assert params["case"].split(",") == ["schaub_detumble", "schaub_detumble_sat"]
    assert params["param"].split(",") == ["diagonal", "givens", "cayley", "cayley_tan",
                                          "geagsp"]
    assert params["optimizer"].split(",") == ["pso_matlab", "cmaes"]
    for case in params["case"].split(","):
        prob = problems.make("attitude_lyapunov", case)
        assert all(m.eig_bounds == (1e-8, 20.0) for m in prob.matrices)


@pytest.mark.parametrize("name,kind", [("attitude_multiscenario", 8),
                                       ("lowthrust_multiscenario", 4)])
def test_multiscenario_profiles_build_disjoint_problems(name, kind):
    from penaltyrun.problems.multiscenario import MultiScenarioProblem

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"+experiment={name}"])
    params = {k: v for k, v in OmegaConf.to_container(cfg.problem.params, resolve=True).items()
              if v is not None}
    prob = problems.make(cfg.problem.name, cfg.case, params)
    assert isinstance(prob, MultiScenarioProblem) and len(prob.scenarios) == kind


@pytest.mark.parametrize("name", ["robust_attitude", "robust_mpc"])
def test_robust_profiles_follow_the_protocol(name):
    """Robust tuning: at least 8 seeded training scenarios drawn by the problem, their mean,
    a well-posed criterion, and a disjoint held-out set of at least 200 scenarios."""
    from penaltyrun.problems.multiscenario import MultiScenarioProblem

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose(config_name="config", overrides=[f"+experiment={name}"])
    params = {k: v for k, v in OmegaConf.to_container(cfg.problem.params, resolve=True).items()
              if v is not None}
    assert params["criterion"] == "time_energy" and params["train_aggregate"] == "mean"
    assert cfg.runner.n_starts >= 10
    prob = problems.make(cfg.problem.name, cfg.case, params)  # checks disjointness
    assert isinstance(prob, MultiScenarioProblem) and len(prob.scenarios) >= 8
    held = prob.holdout_keys()
    assert len(held) >= 200
    assert not held & {s.scenario_key() for s in prob.scenarios}
