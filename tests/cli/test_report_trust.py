"""The report of a run (and mode=report) may import the modules the user's own config
names; nothing else is trusted."""

from omegaconf import OmegaConf

from penaltyrun import problems
from penaltyrun.cli.app import _trust_config_modules


def test_the_modules_of_the_users_config_are_trusted_for_its_report():
    cfg = OmegaConf.create({"problem": {"name": "cartpole_user", "module": "mylab.cartpole",
                                        "params": {"dynamics": "mylab.plants:f",
                                                   "plant": None}}})
    try:
        _trust_config_modules(cfg)
        assert problems.trust.named()["cartpole_user"] == "mylab.cartpole"
        assert problems.trust.allowed("mylab.plants")
        assert not problems.trust.allowed("mylab")
    finally:
        problems.trust.forget_named()


def test_a_config_without_modules_trusts_nothing():
    before = problems.trust.named()
    cfg = OmegaConf.create({"problem": {"name": "zermelo", "params": {}}})
    _trust_config_modules(cfg)
    assert problems.trust.named() == before and not problems.trust.allowed("zermelo")
