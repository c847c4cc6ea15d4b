"""CPU-time measurements shared by the benchmarks that compare a gradient with an evaluation.

* :func:`cpu_seconds`: the CPU time of one call;
* :func:`interleaved`: several calls timed in turn at each of a set of points (a change of
  the machine's load hits all of them alike);
* :func:`gradient_vs_evaluation`: one single-candidate evaluation (as L-BFGS-B asks for it)
  against one exact gradient d cost / d z at each point: the measure behind every problem's
  declared ``gradient_cost``;
* :func:`cpu_to_target`: the CPU time and evaluations one optimizer start needs until its
  best cost first reaches a target.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from penaltyrun import optim
from penaltyrun.optim.gradient import z_gradient


def cpu_seconds(func: Callable[..., Any], *args: Any) -> float:
    """CPU seconds (``time.process_time``) of one call ``func(*args)``."""
    t0 = time.process_time()
    func(*args)
    return time.process_time() - t0


def interleaved(calls: Sequence[Callable[[np.ndarray], Any]], Z: np.ndarray,
                warmup: bool = True) -> np.ndarray:
    """CPU seconds of each call at each point, the calls in turn at one point before the
    next point.

    Parameters
    ----------
    calls : sequence of callable
        Each takes one point z, shape (dim,).
    Z : ndarray, shape (k, dim)
        The points.
    warmup : bool
        Call each once at ``Z[0]`` first, untimed (imports, compiled kernels, caches).

    Returns
    -------
    ndarray, shape (k, len(calls))
        CPU seconds.
    """
    if warmup:
        for call in calls:
            call(Z[0])
    return np.asarray([[cpu_seconds(call, z) for call in calls] for z in Z], dtype=float)


@dataclass(frozen=True)
class GradientTiming:
    """CPU seconds of one evaluation and one gradient at each of k points.

    Attributes
    ----------
    evaluation, gradient : ndarray, shape (k,)
        Seconds of one single-candidate evaluation and of one gradient d cost / d z.
    extra : ndarray, shape (k, e)
        Seconds of the extra calls given to :func:`gradient_vs_evaluation`.
    """

    evaluation: np.ndarray
    gradient: np.ndarray
    extra: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        """Gradient over evaluation per point, shape (k,)."""
        return self.gradient / np.maximum(self.evaluation, 1e-9)

    def row(self) -> str:
        """``eval ms, grad ms, ratio min, ratio median`` as one aligned text row."""
        return (f"{1e3 * np.median(self.evaluation):8.3f} {1e3 * np.median(self.gradient):8.3f} "
                f"{self.ratio.min():9.2f} {np.median(self.ratio):12.2f}")


def gradient_vs_evaluation(prob: Any, layout: Any, Z: np.ndarray,
                           extra: Sequence[Callable[[np.ndarray], Any]] = ()
                           ) -> GradientTiming:
    """One single-candidate evaluation (``evaluate_batch`` of one candidate, as L-BFGS-B
    asks for it) and one gradient (:func:`penaltyrun.optim.gradient.z_gradient`: the
    problem's gradient hook and the map's VJP), interleaved at each point of ``Z`` (k, dim)
    after one untimed warm-up of each; ``extra`` calls (z → anything) are timed beside them.
    """

    def evaluate(z: np.ndarray) -> None:
        prob.evaluate_batch(layout.split(z[None])[0])

    def gradient(z: np.ndarray) -> None:
        z_gradient(prob, layout, z)

    seconds = interleaved([evaluate, gradient, *extra], np.atleast_2d(Z))
    return GradientTiming(seconds[:, 0], seconds[:, 1], seconds[:, 2:])


def cpu_to_target(name: str, prob: Any, layout: Any, options: Mapping[str, Any], seed: int,
                  target: float) -> tuple[float, float, float]:
    """One start of optimizer ``name`` on ``prob`` over ``layout``'s box, with the exact
    gradient for ``lbfgs`` (each charged what the problem declares).

    Returns
    -------
    cpu : float
        CPU seconds until the best cost first came to ``target`` or below (inf: never).
    evals : float
        The run's evaluations (evaluation-equivalents for lbfgs) at that point (inf: never).
    total : float
        CPU seconds of the whole run.
    """
    lb, ub = layout.bounds()
    hit: list[float] = []
    t0 = time.process_time()

    def objective(Z: np.ndarray):
        out = prob.evaluate_batch(layout.split(Z)[0])
        if not hit and np.min(out.cost) <= target:
            hit.append(time.process_time() - t0)
        return out

    settings = optim.with_gradient_cost(optim.make_settings(name, dict(options)), prob)
    res = optim.minimize(name, objective, lb, ub, settings, seed,
                         gradient=lambda z: z_gradient(prob, layout, z))
    total = time.process_time() - t0
    if not hit:
        return float("inf"), float("inf"), total
    evals = next(e for e, b in zip(res.trace_evals, res.trace_best) if b <= target)
    return hit[0], float(evals), total
