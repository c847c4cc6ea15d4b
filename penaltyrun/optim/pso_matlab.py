"""MATLAB-faithful particle swarm (``optimizer=pso_matlab``): the paper's own optimizer.

A self-contained numpy re-implementation of MATLAB's ``particleswarm`` with its documented
default options, written from MathWorks' published algorithm description ("Particle Swarm
Optimization Algorithm", Global Optimization Toolbox) and checked against the shipped
``particleswarm.m`` where the two differ (no MATLAB code is reproduced):

* initial positions uniform in the box (``x0``, if given, replaces particle 0), initial
  velocities uniform in [−r, r] per component with r = min(ub − lb, ``initial_swarm_span``);
* random adaptive neighbourhoods of N particles: each iteration every particle draws its
  neighbourhood and is attracted by the best personal best in it; N starts at
  minNeighborhoodSize = max(2, ⌊S · ``min_neighbors_fraction``⌋), grows by that amount after
  every iteration without improvement and is reset after an improvement;
* adaptive inertia W in ``inertia_range``, starting at its upper end and driven by the stall
  counter c: after an improvement of the swarm's best c = max(0, c − 1), else c = c + 1;
  then W doubles if c < 2 and halves if c > 5, and is clamped to the range;
* v ← W v + y1 u1 ∘ (p_i − x) + y2 u2 ∘ (g − x), x ← x + v (u1, u2 uniform per component);
  a component that leaves the box is set to the bound and its outward velocity to 0;
* personal bests are replaced only by strictly better costs (so each particle's personal
  best is its exact-cutoff threshold, see :mod:`penaltyrun.optim.base`);
* stall rule on the relative change of the best value (to max(1, |best|)) over the last
  ``max_stall_iterations`` iterations; else stop at ``max_iterations`` (200 · nvars by
  default) or when ``max_evals`` is spent.

Three places where MathWorks' algorithm page and the shipped
``particleswarm.m`` read differently, each a setting whose default is the shipped code:

* ``neighbourhood``: the page draws N particles *other than* i (N ≤ S − 1); the code puts
  the particle itself first and draws N − 1 others (N ≤ S), so a particle that is the best
  of its neighbourhood is guided by its own best (ties go to itself). Default ``with_self``.
* ``stall_test``: the code keeps the bests of the last W iterations and stops, from
  iteration W + 1, when they differ by ≤ tol (relative); the page reads "over the last W
  iterations", i.e. W + 1 values and < tol. Default ``code``.
* ``inertia_update``: the page lists the doubling/halving under "the best value improved";
  the code applies it after every iteration. Read literally, W never falls during a stall,
  stays near 1.1 and the swarm never contracts (``bench/pso_matlab_inertia.py``, 10 seeds,
  median best / median evaluations, literal reading vs every iteration: sphere 3-D 5e-3 / 870
  vs 1e-10 / 1 395, sphere 12-D 0.30 / 3 900 vs 1e-8 / 9 600). Default ``every_iteration``.

On the standard test functions of that bench, the code's neighbourhood and stall test
change little: sphere 12-D 2e-8 / 9 600, Rastrigin 6-D 2 / 7 800. On the authors' companion
attitude set-up they change a lot. There, the page's rule ran
16 of 20 diagonal starts to the 1 200-iteration cap, and every one of them beat the authors'
best published run. The code's rule stopped 118 of 120 starts by the stall test, after
5 000–184 300 evaluations. Five of its six cells match the authors' medians (README,
"Attitude fidelity study").

Two properties of the authors' objective, not of the optimizer, account for the rest of the
difference in the unconstrained diagonal cell (``studies/fidelity_gap/README.md``): they
minimize −1/J, whose scale the stall test sees (the problem setting ``objective_form``,
default in the companion presets; the optimizer sees the problem's ``objective`` values,
see :mod:`penaltyrun.optim.base`), and MATLAB's ``ode113`` checks the terminal event only
at step ends, which misses the brief dips under the threshold that our best gains reach.

The whole swarm is one batch evaluation per iteration (initial swarm included), so a run
stopped by the stall rule or the iteration limit spends funccount = S · (iterations + 1)
evaluations. Every random number comes from one ``numpy.random.Generator`` seeded with the
job seed, so a seed gives one run whatever the global numpy state.

Why not pyswarms' backend primitives (checked against pyswarms 1.3): ``compute_velocity`` and
``generate_velocity`` draw from the *global* ``np.random`` state (no Generator) and the latter
draws velocities in [clamp_min, clamp_max), not [−r, r] per component; the ``Random`` topology
keeps a fixed k, builds a connected graph with Python loops over all S² pairs and Dijkstra
(slow at S = 500 and a different neighbourhood rule); no topology adapts N or the inertia; the
``zero`` velocity handler zeroes the whole velocity row of an out-of-bound particle instead of
the outward component. Only ``compute_pbest`` (strictly-better update) would fit, and it is
one line. The rules are therefore small pure functions below, each unit-tested on hand-made
swarms (tests/optim/test_pso_matlab.py).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.optim.base import (
    BatchObjective,
    BudgetExhaustedError,
    CommonSettings,
    OptimResult,
    as_counting,
    main_budget,
    require_int,
    uniform_box,
)
from penaltyrun.typed import is_number

logger = logging.getLogger(__name__)

INERTIA_UPDATES = ("every_iteration", "on_improvement")
NEIGHBOURHOODS = ("with_self", "others")
STALL_TESTS = ("code", "page")


@dataclass(frozen=True)
class PSOMatlabSettings(CommonSettings):
    """Settings of MATLAB's ``particleswarm`` (defaults = MATLAB's), plus
    :class:`CommonSettings` (``max_evals``, ``polish``, ``polish_share``).

    Attributes
    ----------
    swarm_size : int or None
        SwarmSize S (≥ 2); ``None`` → min(100, 10 · nvars).
    max_iterations : int or None
        MaxIterations; ``None`` → 200 · nvars.
    inertia_range : tuple of float
        InertiaRange [W_min, W_max], 0 ≤ W_min ≤ W_max; W starts at W_max.
    self_adjustment_weight : float
        y1, weight of the particle's own best (MATLAB 1.49).
    social_adjustment_weight : float
        y2, weight of the neighbourhood best (MATLAB 1.49).
    min_neighbors_fraction : float
        MinNeighborsFraction in (0, 1]: minNeighborhoodSize = max(2, ⌊S · fraction⌋).
    function_tolerance : float
        FunctionTolerance (≥ 0): stall when the best value changed by less than this,
        relative to max(1, |best|), over ``max_stall_iterations`` iterations (0: never
        under ``stall_test="page"``; under ``"code"``, only on an exactly flat window).
    max_stall_iterations : int
        MaxStallIterations (the stall window), ≥ 1.
    initial_swarm_span : float
        InitialSwarmSpan > 0: initial velocities uniform in ±min(ub − lb, span).
    inertia_update : str
        When the doubling/halving rule runs: ``every_iteration`` (default; W falls during a
        stall, as MATLAB's runs behave) or ``on_improvement`` (the literal reading of the
        algorithm page; see the module docstring for the measured difference).
    neighbourhood : str
        ``with_self`` (default, as ``particleswarm.m`` runs): the particle itself plus N − 1
        random others, N ≤ S; ``others`` (the algorithm page): N random others, N ≤ S − 1.
    stall_test : str
        ``code`` (default, as ``particleswarm.m`` runs): from iteration W + 1 on, stop when
        |best_k − best_(k−W+1)| / max(1, |best_k|) ≤ tol (the last W stored bests);
        ``page``: from iteration W on, stop when |best_k − best_(k−W)| / max(1, |best_k|)
        < tol. W = ``max_stall_iterations``.
    """

    swarm_size: int | None = None
    max_iterations: int | None = None
    inertia_range: tuple[float, float] = (0.1, 1.1)
    self_adjustment_weight: float = 1.49
    social_adjustment_weight: float = 1.49
    min_neighbors_fraction: float = 0.25
    function_tolerance: float = 1e-6
    max_stall_iterations: int = 20
    initial_swarm_span: float = 2000.0
    inertia_update: str = "every_iteration"
    neighbourhood: str = "with_self"
    stall_test: str = "code"

    def batch_size(self, dim: int) -> int:
        """Candidates the optimizer passes to the objective per call on ``dim`` variables
        (what the forecast times one evaluation of): the swarm, ``swarm_size`` (default
        :func:`default_swarm_size`)."""
        return int(self.swarm_size or default_swarm_size(dim))

    def validate(self) -> None:
        """Check ranges (and the shared fields).

        Raises
        ------
        ConfigError
            Naming the key, e.g. ``optimizer.inertia_range``.
        """
        super().validate()
        require_int("swarm_size", self.swarm_size, 2, allow_none=True)
        require_int("max_iterations", self.max_iterations, 1, allow_none=True)
        wr = self.inertia_range
        if (not isinstance(wr, tuple | list) or len(wr) != 2
                or not all(is_number(w) and math.isfinite(w) for w in wr)):
            raise ConfigError("optimizer.inertia_range", f"must be [low, high] (two finite "
                              f"numbers), got {wr!r}")
        if wr[0] < 0:
            raise ConfigError("optimizer.inertia_range", f"must lie in [0, inf), got "
                              f"{list(wr)!r}")
        if wr[0] > wr[1]:
            raise ConfigError("optimizer.inertia_range", f"reversed: low > high in "
                              f"{list(wr)!r}")
        if not 0.0 < self.min_neighbors_fraction <= 1.0:
            raise ConfigError("optimizer.min_neighbors_fraction", f"must be in (0, 1], got "
                              f"{self.min_neighbors_fraction!r}")
        for key in ("self_adjustment_weight", "social_adjustment_weight"):
            value = getattr(self, key)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"optimizer.{key}", f"must be a finite number ≥ 0, got "
                                  f"{value!r}")
        if not (math.isfinite(self.function_tolerance) and self.function_tolerance >= 0):
            raise ConfigError("optimizer.function_tolerance", f"must be ≥ 0, got "
                              f"{self.function_tolerance!r}")
        require_int("max_stall_iterations", self.max_stall_iterations, 1)
        if self.inertia_update not in INERTIA_UPDATES:
            raise ConfigError("optimizer.inertia_update", f"unknown rule "
                              f"{self.inertia_update!r}", allowed=INERTIA_UPDATES)
        if self.neighbourhood not in NEIGHBOURHOODS:
            raise ConfigError("optimizer.neighbourhood", f"unknown rule "
                              f"{self.neighbourhood!r}", allowed=NEIGHBOURHOODS)
        if self.stall_test not in STALL_TESTS:
            raise ConfigError("optimizer.stall_test", f"unknown rule {self.stall_test!r}",
                              allowed=STALL_TESTS)
        if not self.initial_swarm_span > 0:
            raise ConfigError("optimizer.initial_swarm_span", f"must be positive, got "
                              f"{self.initial_swarm_span!r}")

    def search_evals(self, dim: int) -> int:
        """At most S · (MaxIterations + 1): the initial swarm, then one per iteration."""
        swarm = self.swarm_size or default_swarm_size(dim)
        return swarm * ((self.max_iterations or default_max_iterations(dim)) + 1)


class Adaptive(NamedTuple):
    """Adaptive state between iterations: stall counter c, neighbourhood size N, inertia W."""

    counter: int
    size: int
    inertia: float


def default_swarm_size(nvars: int) -> int:
    """MATLAB's default SwarmSize min(100, 10 · nvars)."""
    return min(100, 10 * nvars)


def default_max_iterations(nvars: int) -> int:
    """MATLAB's default MaxIterations 200 · nvars."""
    return 200 * nvars


def max_neighbourhood_size(swarm_size: int, with_self: bool) -> int:
    """Largest neighbourhood: S with the particle itself counted, else S − 1 others."""
    return swarm_size if with_self else swarm_size - 1


def min_neighbourhood_size(swarm_size: int, fraction: float, with_self: bool = False) -> int:
    """minNeighborhoodSize = max(2, ⌊S · fraction⌋), at most
    :func:`max_neighbourhood_size`."""
    return min(max(2, math.floor(swarm_size * fraction)),
               max_neighbourhood_size(swarm_size, with_self))


def initial_velocities(rng: np.random.Generator, lb: np.ndarray, ub: np.ndarray,
                       swarm_size: int, span: float) -> np.ndarray:
    """Velocities uniform in [−r, r] per component, r = min(ub − lb, span); shape (S, dim)."""
    r = np.minimum(np.asarray(ub, float) - np.asarray(lb, float), span)
    return -r + 2.0 * r * rng.random((swarm_size, r.size))


def random_neighbours(rng: np.random.Generator, swarm_size: int, size: int,
                      with_self: bool = False) -> np.ndarray:
    """For each particle a neighbourhood of ``size`` particles: ``size`` random *other*
    particles, or with ``with_self`` the particle itself plus ``size`` − 1 random others.

    Returns
    -------
    ndarray of int, shape (S, size)
        Row i holds distinct indices; the others are the smallest of S − 1 iid uniform keys
        (uniform subsets); with ``with_self`` column 0 is i.
    """
    top = max_neighbourhood_size(swarm_size, with_self)
    if not 1 <= size <= top:
        raise ValueError(f"neighbourhood size {size} not in [1, {top}]")
    n_others = size - 1 if with_self else size
    own = np.arange(swarm_size)[:, None]
    if n_others == 0:
        return own
    keys = rng.random((swarm_size, swarm_size))
    np.fill_diagonal(keys, np.inf)
    others = np.argpartition(keys, n_others - 1, axis=1)[:, :n_others]
    return np.hstack([own, others]) if with_self else others


def best_neighbours(neighbours: np.ndarray, pbest_cost: np.ndarray) -> np.ndarray:
    """Index of the best personal best within each particle's neighbourhood, shape (S,)."""
    j = np.argmin(pbest_cost[neighbours], axis=1)
    return neighbours[np.arange(neighbours.shape[0]), j]


def velocity_update(v: np.ndarray, x: np.ndarray, pbest: np.ndarray, g: np.ndarray,
                    inertia: float, y1: float, y2: float, u1: np.ndarray, u2: np.ndarray
                    ) -> np.ndarray:
    """v' = W v + y1 u1 ∘ (p − x) + y2 u2 ∘ (g − x); all arrays (S, dim), ``g`` the
    neighbourhood bests' positions."""
    return inertia * v + y1 * u1 * (pbest - x) + y2 * u2 * (g - x)


def clamp_and_zero(x: np.ndarray, v: np.ndarray, lb: np.ndarray, ub: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Clamp components outside [lb, ub] to the bound and zero their outward velocity.

    Parameters
    ----------
    x : ndarray, shape (S, dim)
        Moved positions (possibly outside the box).
    v : ndarray, shape (S, dim)
        The velocities that moved them.

    Returns
    -------
    (x, v) : new arrays; inward velocity components and in-box components are unchanged.
    """
    below, above = x < lb, x > ub
    x = np.clip(x, lb, ub)
    v = np.where((below & (v < 0)) | (above & (v > 0)), 0.0, v)
    return x, v


def update_personal_bests(pbest: np.ndarray, pbest_cost: np.ndarray, x: np.ndarray,
                          cost: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Replace personal bests by the new positions where the cost is strictly lower."""
    better = cost < pbest_cost
    return np.where(better[:, None], x, pbest), np.where(better, cost, pbest_cost)


def adapt(state: Adaptive, improved: bool, min_size: int, max_size: int,
          inertia_range: tuple[float, float], every_iteration: bool = True) -> Adaptive:
    """Update (c, N, W) after an iteration.

    Improved: c = max(0, c − 1), N = minNeighborhoodSize. Not improved: c = c + 1,
    N = min(N + minNeighborhoodSize, ``max_size``) (S − 1 others, or S with the particle
    itself). Inertia, with the updated c: W ×2 if c < 2,
    W / 2 if c > 5, then clamped to ``inertia_range``. With ``every_iteration`` (default)
    the inertia rule runs after every iteration; otherwise only after an improvement (the
    literal reading of MathWorks' algorithm page, under which W never falls during a stall).
    """
    if improved:
        counter, size = max(0, state.counter - 1), min_size
    else:
        counter, size = state.counter + 1, min(state.size + min_size, max_size)
    inertia = state.inertia
    if improved or every_iteration:
        if counter < 2:
            inertia = 2.0 * inertia
        elif counter > 5:
            inertia = inertia / 2.0
        inertia = min(max(inertia, inertia_range[0]), inertia_range[1])
    return Adaptive(counter, size, inertia)


def stalled(best: list[float], window: int, tol: float, test: str = "page") -> bool:
    """Stall rule on the best values ``best`` (initial swarm first, one per iteration).

    ``page``: true when at least ``window`` iterations were done and
    |best[-1 - window] − best[-1]| / max(1, |best[-1]|) < ``tol`` (0 never stops).
    ``code`` (``particleswarm.m``): true when more than ``window`` iterations were done and
    |best[-window] − best[-1]| / max(1, |best[-1]|) ≤ ``tol``, i.e. over the ``window``
    bests of the last ``window`` iterations (0 stops on an exactly flat window).
    """
    iterations = len(best) - 1
    if test == "code":
        if iterations <= window:
            return False
        return abs(best[-window] - best[-1]) / max(1.0, abs(best[-1])) <= tol
    if iterations < window:
        return False
    return abs(best[-1 - window] - best[-1]) / max(1.0, abs(best[-1])) < tol


def run_pso_matlab(objective: BatchObjective, lb: np.ndarray, ub: np.ndarray,
                   settings: PSOMatlabSettings, seed: int, x0: np.ndarray | None = None
                   ) -> OptimResult:
    """Minimize ``objective`` over [lb, ub] as MATLAB's ``particleswarm`` would.

    Parameters
    ----------
    objective : callable
        Batched objective Z (S, dim) → (S,), or a
        :class:`~penaltyrun.optim.base.CountingObjective` already carrying the budget.
    lb, ub : ndarray, shape (dim,)
        Box bounds.
    settings : PSOMatlabSettings
    seed : int
        Seed of the run's own ``numpy.random.Generator``.
    x0 : ndarray, shape (dim,), optional
        Warm start: replaces particle 0 of the initial swarm (clipped to the box).

    Returns
    -------
    OptimResult
        ``stop_reason`` ``ftol`` (stall rule), ``iters`` (``max_iterations``) or
        ``max_evals``; ``n_iters`` iterations after the initial swarm, ``history`` the best
        cost after each of them; the anytime trace from the counting objective.
    """
    counted = as_counting(objective, main_budget(settings))
    lb, ub = np.asarray(lb, float), np.asarray(ub, float)
    dim = lb.size
    swarm = settings.swarm_size or default_swarm_size(dim)
    max_iter = settings.max_iterations or default_max_iterations(dim)
    w_range = (float(settings.inertia_range[0]), float(settings.inertia_range[1]))
    y1, y2 = settings.self_adjustment_weight, settings.social_adjustment_weight
    every = settings.inertia_update == "every_iteration"
    with_self = settings.neighbourhood == "with_self"
    rng = np.random.default_rng(seed)
    x = uniform_box(rng, lb, ub, swarm)
    if x0 is not None:
        x[0] = np.clip(np.asarray(x0, float), lb, ub)
    v = initial_velocities(rng, lb, ub, swarm, settings.initial_swarm_span)
    min_size = min_neighbourhood_size(swarm, settings.min_neighbors_fraction, with_self)
    max_size = max_neighbourhood_size(swarm, with_self)
    state = Adaptive(0, min_size, w_range[1])
    history: list[float] = []
    bests: list[float] = []
    n_iters = 0
    stop = "iters"
    try:
        cost = counted(x)
        pbest, pbest_cost = x.copy(), cost.copy()
        bests.append(float(pbest_cost.min()))
        while n_iters < max_iter:
            if counted.remaining <= 0:  # budget spent exactly at the end of an iteration
                raise BudgetExhaustedError
            n_iters += 1
            g = best_neighbours(random_neighbours(rng, swarm, state.size, with_self),
                                pbest_cost)
            u1, u2 = rng.random((swarm, dim)), rng.random((swarm, dim))
            v = velocity_update(v, x, pbest, pbest[g], state.inertia, y1, y2, u1, u2)
            x, v = clamp_and_zero(x + v, v, lb, ub)
            cost = counted(x, pbest_cost)
            pbest, pbest_cost = update_personal_bests(pbest, pbest_cost, x, cost)
            best = float(pbest_cost.min())
            state = adapt(state, best < bests[-1], min_size, max_size, w_range, every)
            bests.append(best)
            history.append(counted.best_cost)  # in the recorded cost (J), whatever the form
            if stalled(bests, settings.max_stall_iterations, settings.function_tolerance,
                       settings.stall_test):
                stop = "ftol"
                break
    except BudgetExhaustedError:
        stop = "max_evals"
        if len(history) < max(n_iters, 1):  # the swarm evaluated in part
            history.append(counted.best_cost)
    logger.debug("pso_matlab (S = %d) stopped after %d iterations (%s), best %.6g, W %.3g, "
                 "N %d", swarm, n_iters, stop, counted.best_cost, state.inertia, state.size)
    return counted.result(history, n_iters, stop)
