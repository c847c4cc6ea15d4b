"""Training scenario and held-out set of the rendezvous MPC.

A scenario is a start s0 and a plant (the CW model, or the Keplerian plant with an
eccentricity, and a thrust scale); the controller (CW model, weights, horizon) is the same in
all of them. The held-out set, disjoint from the training scenario:

* ``sphere:k``: ``holdout_n_sphere`` starts at rest, uniform on the sphere of radius
  ``holdout_sphere_radius_m`` around the target (seeded by ``holdout_seed``), training plant;
* ``e=<e>:<start>``: every eccentricity of ``holdout_eccentricities`` (Keplerian plant),
  from the training start (``s0``) and from every sphere start;
* ``thrust=<c>:<start>``: every thrust scale of ``holdout_thrust_scales`` (training plant
  otherwise), from the same starts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems.mpc.params import Params

#: Scenario kinds, in the order they are listed.
KINDS = ("start", "eccentric", "thrust")


@dataclass(frozen=True)
class Scenario:
    """One closed-loop set-up of the same controller.

    Attributes
    ----------
    label : str
        Unique name, e.g. ``sphere:3``, ``e=0.01:s0``, ``thrust=0.95:sphere:3``.
    kind : str
        One of :data:`KINDS` (``start`` also for the training scenario).
    s0 : tuple of 6 float
        Initial relative state (m, m/s).
    plant : str
        ``cw`` or ``keplerian``.
    eccentricity : float
        Target-orbit eccentricity (``keplerian``).
    thrust_scale : float
        Applied / commanded acceleration.
    """

    label: str
    kind: str
    s0: tuple[float, ...]
    plant: str
    eccentricity: float
    thrust_scale: float

    def key(self) -> tuple:
        """Hashable key: start rounded to 1e-9, plant, eccentricity, thrust scale."""
        return tuple(np.round(np.asarray(self.s0, float), 9).tolist()) + (
            self.plant, float(self.eccentricity), float(self.thrust_scale))


def training(p: Params) -> Scenario:
    """The scenario the weights are tuned on."""
    return Scenario("s0", "start", tuple(float(v) for v in p.s0), p.plant,
                    float(p.plant_eccentricity), float(p.thrust_scale))


def sphere_starts(n: int, radius: float, seed: int) -> np.ndarray:
    """``n`` seeded starts at rest, uniform on the sphere of ``radius`` (m), shape (n, 6)."""
    rng = np.random.default_rng(int(seed))
    d = rng.standard_normal((int(n), 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.concatenate([radius * d, np.zeros((int(n), 3))], axis=1)


def holdout(p: Params) -> list[Scenario]:
    """The held-out set (see the module docstring).

    Raises
    ------
    ConfigError
        A mismatch value equal to the training plant's (it would not be a mismatch).
    """
    base = training(p)
    starts = [("s0", base.s0)] + [
        (f"sphere:{k}", tuple(float(v) for v in s))
        for k, s in enumerate(sphere_starts(p.holdout_n_sphere, p.holdout_sphere_radius_m,
                                            p.holdout_seed))]
    out = [Scenario(label, "start", s0, base.plant, base.eccentricity, base.thrust_scale)
           for label, s0 in starts[1:]]
    for e in p.holdout_eccentricities:
        if p.plant == "keplerian" and float(e) == base.eccentricity:
            raise ConfigError("problem.params.holdout_eccentricities",
                              f"{e:g} is the training plant's eccentricity")
        out += [Scenario(f"e={float(e):g}:{label}", "eccentric", s0, "keplerian", float(e),
                         base.thrust_scale) for label, s0 in starts]
    for c in p.holdout_thrust_scales:
        if float(c) == base.thrust_scale:
            raise ConfigError("problem.params.holdout_thrust_scales",
                              f"{c:g} is the training plant's thrust scale")
        out += [Scenario(f"thrust={float(c):g}:{label}", "thrust", s0, base.plant,
                         base.eccentricity, float(c)) for label, s0 in starts]
    train_key = base.key()
    out = [s for s in out if s.key() != train_key]
    return out


def sample_training(p: Params, n: int, seed: int) -> list[dict[str, Any]]:
    """``n`` seeded training starts at rest on the held-out sphere (a different seed).

    Returns
    -------
    list of dict
        Overrides ``{"s0": (x, y, z, 0, 0, 0)}``.
    """
    return [{"s0": tuple(float(v) for v in s)}
            for s in sphere_starts(n, p.holdout_sphere_radius_m, seed)]


__all__ = ["KINDS", "Scenario", "holdout", "sample_training", "sphere_starts", "training"]
