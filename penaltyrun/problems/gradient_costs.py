"""What one exact gradient costs, in evaluations, for every built-in problem with a gradient.

Each number is the CPU time (``time.process_time``, one BLAS thread) of one gradient
d cost / d z (the problem's ``gradient`` hook plus the map's VJP) over the CPU time of one
single-candidate evaluation (``evaluate_batch`` of one candidate, as L-BFGS-B asks for it),
measured on interleaved pairs by the benchmarks in ``bench/`` (their shared loop is
``bench/timing.py``) and tabulated in ``bench/README.md``. The declared value is the largest
median over the maps (``diagonal``, ``givens``) of the table's rows it covers, rounded up to
the next half evaluation (on a shared machine the figures move by up to about a fifth
between runs). The problems hand them out through their ``gradient_cost()`` hook
(:class:`~penaltyrun.problems.base.PricedGradientProblem`); ``optimizer=lbfgs`` and
``optimizer.polish=gradient`` charge them per gradient unless ``optimizer.grad_cost`` is
given. After re-running a benchmark, update the number here and its table together.
"""

from __future__ import annotations

import math

from penaltyrun.problems import criteria
from penaltyrun.problems.base import GradientCost

#: ``problem=lqr``, continuous time: (largest plant size n, evaluations per gradient), in
#: increasing n. ``bench/gradient_cost.py`` (random plants, n = 2 … 16, table "Exact
#: gradient of problem=lqr vs one evaluation") and ``bench/lqr_scaling_ratio.py`` (the
#: plants of the study ``lqr_scaling``, n = 4 … 32, table "The plants of the study
#: lqr_scaling"): at n ≤ 8 one evaluation is mostly fixed per-call cost and a gradient adds
#: its Lyapunov solves (medians up to 3.8); from n = 16 the evaluation's own O(n³) work
#: takes over and the ratio falls towards 2.
LQR_CONTINUOUS = ((8, 4.0), (16, 2.5), (math.inf, 2.0))
#: ``problem=lqr``, discrete time (``dt`` given): ``bench/gradient_cost.py --discrete``
#: (n = 2 … 16, medians 1.9–2.5 with no trend in n).
LQR_DISCRETE = ((math.inf, 2.5),)
#: ``problem=zermelo``: ``bench/gradient_cost_zermelo_mpc.py``, table "Exact gradient of
#: Zermelo and the MPC rendezvous vs one evaluation" (a compiled closed-form run against a
#: numpy quadrature with the Fréchet derivative of e^{−Kt} at every node).
ZERMELO = 8.5
#: ``problem=mpc_rendezvous`` by criterion: ``bench/gradient_cost_zermelo_mpc.py``, same
#: table (case ``scaled``; the gradient re-runs the loop, re-solves each step's QP and
#: sweeps back through one KKT solve per step).
MPC = {criteria.DEADLINE: 6.0, criteria.TIME_ENERGY: 7.0, criteria.TERMINAL: 6.0}
#: The attitude problems by (law, criterion): ``bench/attitude_gradient_cost.py``, table
#: "The attitude problems" (the compiled forward-sensitivity run against the compiled
#: kernel; under ``time_energy`` the sensitivity run keeps its step bounded near the
#: arrival, hence a few times the ``terminal`` cost). ``deadline`` has no gradient.
ATTITUDE = {("attitude_lyapunov", criteria.TERMINAL): 4.5,
            ("attitude_lyapunov", criteria.TIME_ENERGY): 14.5,
            ("attitude_lqr", criteria.TERMINAL): 2.5,
            ("attitude_lqr", criteria.TIME_ENERGY): 6.0}

_README = "bench/README.md"


def lqr_cost(n: int, discrete: bool) -> GradientCost:
    """One ``problem=lqr`` gradient on a plant of ``n`` states (integrators included), in
    evaluations (:data:`LQR_CONTINUOUS`, :data:`LQR_DISCRETE`)."""
    table = LQR_DISCRETE if discrete else LQR_CONTINUOUS
    value = next(cost for largest, cost in table if n <= largest)
    bench = "gradient_cost.py --discrete" if discrete else \
        "gradient_cost.py and lqr_scaling_ratio.py"
    return GradientCost(value, f"bench/{bench} ({_README}), n = {n}")


def zermelo_cost() -> GradientCost:
    """One ``problem=zermelo`` gradient, in evaluations (:data:`ZERMELO`)."""
    return GradientCost(ZERMELO, f"bench/gradient_cost_zermelo_mpc.py ({_README})")


def mpc_cost(criterion: str) -> GradientCost:
    """One ``problem=mpc_rendezvous`` gradient under ``criterion``, in evaluations
    (:data:`MPC`)."""
    return GradientCost(MPC[criterion], f"bench/gradient_cost_zermelo_mpc.py ({_README}), "
                                        f"criterion {criterion}")


def attitude_cost(law: str, criterion: str) -> GradientCost:
    """One attitude gradient of ``law`` under ``criterion``, in evaluations
    (:data:`ATTITUDE`; ``deadline``, which has no gradient, is charged as ``terminal``)."""
    known = criterion if criterion in (criteria.TERMINAL, criteria.TIME_ENERGY) else \
        criteria.TERMINAL
    return GradientCost(ATTITUDE[law, known], f"bench/attitude_gradient_cost.py ({_README}), "
                                              f"{law}, criterion {known}")


__all__ = ["ATTITUDE", "LQR_CONTINUOUS", "LQR_DISCRETE", "MPC", "ZERMELO", "attitude_cost",
           "lqr_cost", "mpc_cost", "zermelo_cost"]
