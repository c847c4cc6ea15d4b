"""The optimizers are registered in one place; what the runner and the forecast need of an
optimizer comes from its registry entry or its settings, never from its name."""

from __future__ import annotations

import math

import pytest

from penaltyrun import optim
from penaltyrun.errors import ConfigError
from penaltyrun.runner.spec import RunnerOptions, RunSpec


def test_every_entry_builds_its_default_settings():
    for name, entry in optim.OPTIMIZERS.items():
        settings = optim.make_settings(name, {})
        assert isinstance(settings, entry.settings)
        assert settings.batch_size(6) >= 1
        assert callable(entry.run)


def test_derived_lists():
    assert optim.GRADIENT_OPTIMIZERS == ("lbfgs",)
    assert [n for n, o in optim.OPTIMIZERS.items() if not o.warm_start] == ["grid", "baseline"]


def test_batch_sizes_come_from_the_settings():
    assert optim.make_settings("cmaes", {}).batch_size(27) == 4 + int(3 * math.log(27))
    assert optim.make_settings("de", {"popsize": 5}).batch_size(3) == 15
    assert optim.make_settings("grid", {}).batch_size(3) == 1


def test_warm_start_is_refused_where_the_registry_says_so():
    spec = RunSpec("zermelo", None, "full", "baseline",
                   runner=RunnerOptions(warm_start=True), optimizer_options={"max_evals": 9})
    with pytest.raises(ConfigError, match=r"not for optimizer 'baseline' \(allowed: pso, de, "
                                          r"cmaes, pso_matlab, lbfgs\)"):
        spec.warm_start_share()
