"""Every optimizer profile documented as spending its whole budget does: spent == max_evals
on a rugged objective, on a plateau (all costs equal: scipy's DE convergence test and
pyswarms' stall rule see no change) and on a constant penalty, without warnings."""

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml

from penaltyrun.optim import make_settings, minimize

PROFILES = Path(__file__).resolve().parents[2] / "penaltyrun" / "conf" / "optimizer"
CLAIM = re.compile(r"spends its whole|until spent")
NO_EARLY_STOP = sorted(p.stem for p in PROFILES.glob("*.yaml") if CLAIM.search(p.read_text()))
LB, UB = -np.ones(4), np.ones(4)


def rugged(Z):
    D = Z - 0.3
    return (D**2).sum(axis=1) + 0.1 * (1 - np.cos(8 * D)).sum(axis=1)


def plateau(Z):  # the optimum region is a flat floor, as a converged swarm sees it
    return np.maximum((Z**2).sum(axis=1), 0.5)


def constant(Z):  # every candidate failed: one penalty value
    return np.full(len(Z), 1e6)


def test_the_claim_is_found_where_it_is_made():
    assert {"cmaes", "cmaes_budget", "de_budget", "pso_budget"} <= set(NO_EARLY_STOP)
    assert "pso_matlab_budget" not in NO_EARLY_STOP  # documented to stop on a flat window


@pytest.mark.parametrize("profile", NO_EARLY_STOP)
@pytest.mark.parametrize("objective", [rugged, plateau, constant])
def test_profile_spends_its_whole_budget(profile, objective):
    options = yaml.safe_load((PROFILES / f"{profile}.yaml").read_text())
    name = options.pop("name")
    options["max_evals"] = budget = 1500 if options.get("max_evals", 0) > 1500 else \
        options["max_evals"]
    settings = make_settings(name, options)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = minimize(name, objective, LB, UB, settings, seed=11)
    assert res.n_evals == budget, res.stop_reason
    assert res.stop_reason == "max_evals"
