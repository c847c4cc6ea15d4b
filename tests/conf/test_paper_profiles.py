"""The low-thrust paper-budget profiles: both laws, every case, both maps, 10 starts, the
paper's PSO budgets; expanded as Hydra's multirun would (``mode=plan``'s cells)."""

import pytest

from penaltyrun import optim
from penaltyrun.cli import planmode


@pytest.mark.parametrize(("name", "swarm", "iters"), [("lowthrust_paper_50x50", 50, 50),
                                                       ("lowthrust_paper_200x300", 200, 300)])
def test_paper_profile_cells(name, swarm, iters):
    cfgs, multirun = planmode.expand_cells(["-m", "mode=plan", f"+experiment={name}"])
    assert multirun
    cells = {(c.problem.name, c.case, c.param.name) for c in cfgs}
    assert cells == {(p, case, k) for p in ("qlaw", "lyapunov_transfer")
                     for case in ("A", "B", "C", "D", "E", "Estar")
                     for k in ("diagonal", "full")}
    for cfg in cfgs:
        assert cfg.runner.n_starts == 10 and cfg.optimizer.name == "pso"
        assert (cfg.optimizer.n_particles, cfg.optimizer.iters) == (swarm, iters)
        settings = optim.make_settings("pso", {k: v for k, v in cfg.optimizer.items()
                                               if k != "name"})
        assert optim.planned_evals(settings, 15) == swarm * iters
    single, multirun = planmode.expand_cells([f"+experiment={name}", "case=Estar"])
    assert not multirun and len(single) == 1
    assert (single[0].problem.name, single[0].case) == ("qlaw", "Estar")
