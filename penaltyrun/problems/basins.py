"""Basin-of-attraction maps: from which starts a tuned gain brings the system home, how
long it takes and what it costs.

A problem that offers maps implements :class:`BasinProblem`: it names two axes of initial
conditions (for the attitude problems two Euler angles, for Zermelo the start position, for
an LQR plant two state components) and runs one gain from a batch of points of that plane
at its held-out horizon (:mod:`penaltyrun.problems.horizon`), where a slow but stable gain
has time to arrive. :func:`basin_map` lays a regular grid over the plane and returns a
:class:`BasinMap` of ``converged``, ``arrival_time`` and ``cost`` per grid point; the report
draws the diagonal and the full matrix side by side.

A basin map is a sampled picture, not a proof: a point counts as converged when the run
from it reached the problem's target by the horizon.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

#: Default grid points per axis (even: no point at the centre of a symmetric plane, where
#: a start at the target has no distance to scale a failure by).
DEFAULT_POINTS = 24


@dataclass(frozen=True)
class BasinAxes:
    """The plane of initial conditions a problem maps.

    Attributes
    ----------
    labels : tuple of str
        Axis labels with units, e.g. ``("yaw (deg)", "pitch (deg)")``.
    lo, hi : tuple of float
        Lower and upper ends of each axis.
    time_unit : str
        Unit of the arrival times (e.g. ``"s"``).
    marker : tuple of float or None
        The training start in this plane (drawn on the map), if it lies in it.
    """

    labels: tuple[str, str]
    lo: tuple[float, float]
    hi: tuple[float, float]
    time_unit: str = "s"
    marker: tuple[float, float] | None = None


@runtime_checkable
class BasinProblem(Protocol):
    """The two members a problem needs for basin maps."""

    def basin_axes(self) -> BasinAxes | None:
        """The plane of initial conditions (:class:`BasinAxes`; None when the problem, as
        configured, has none)."""

    def basin_runs(self, mats: Mapping[str, Any], scalars: Mapping[str, float] | None,
                   points: np.ndarray) -> dict[str, np.ndarray]:
        """Run one gain from ``points`` (P, 2) of the plane at the held-out horizon.

        Returns ``converged`` (P,) bool, ``arrival_time`` (P,) (NaN where the run did not
        arrive), ``cost`` (P,) (the graded cost where it did not) and ``horizon`` (float,
        the horizon judged at)."""


@dataclass(frozen=True)
class BasinMap:
    """One gain's map over a grid of the plane.

    Attributes
    ----------
    axes : BasinAxes
    x : ndarray, shape (n,)
        Grid values of the first axis.
    y : ndarray, shape (m,)
        Grid values of the second axis.
    converged : ndarray of bool, shape (m, n)
        Whether the run from (x[j], y[i]) arrived by the horizon.
    arrival_time : ndarray, shape (m, n)
        Its arrival time (``axes.time_unit``; NaN where it did not arrive).
    cost : ndarray, shape (m, n)
        Its cost (graded where it did not arrive).
    horizon : float
        The horizon judged at (``axes.time_unit``).
    region : dict or None
        A problem's estimate of the region of attraction in this plane (a problem with a
        ``basin_region`` member, e.g. a Lyapunov sub-level set): ``inside`` (m, n) bool,
        ``level``, ``certified`` and ``label``; None without one.
    """

    axes: BasinAxes
    x: np.ndarray
    y: np.ndarray
    converged: np.ndarray
    arrival_time: np.ndarray
    cost: np.ndarray
    horizon: float
    region: dict[str, Any] | None = None

    def region_check(self) -> tuple[int, int]:
        """(grid points inside the region estimate that converged, grid points inside it);
        (0, 0) without an estimate."""
        if self.region is None:
            return 0, 0
        inside = self.region["inside"]
        return int(np.sum(self.converged & inside)), int(np.sum(inside))

    @property
    def share_converged(self) -> float:
        """Share of grid points whose run arrived by the horizon."""
        return float(np.mean(self.converged))

    def rows(self) -> list[dict[str, Any]]:
        """One dict per grid point: the two axis values, ``converged``, ``arrival_time``,
        ``cost`` (for a CSV file)."""
        xs, ys = np.meshgrid(self.x, self.y)
        a, b = self.axes.labels
        return [{a: float(u), b: float(v), "converged": bool(c), "arrival_time": float(t),
                 "cost": float(j)}
                for u, v, c, t, j in zip(xs.ravel(), ys.ravel(), self.converged.ravel(),
                                         self.arrival_time.ravel(), self.cost.ravel())]


def grid(axes: BasinAxes, n: int = DEFAULT_POINTS) -> tuple[np.ndarray, np.ndarray,
                                                             np.ndarray]:
    """The grid of :func:`basin_map`: ``x`` (n,), ``y`` (n,) and the points (n², 2), the
    first axis varying fastest."""
    if n < 2:
        raise ValueError(f"a basin map needs at least 2 points per axis, got {n}")
    x = np.linspace(axes.lo[0], axes.hi[0], n)
    y = np.linspace(axes.lo[1], axes.hi[1], n)
    xs, ys = np.meshgrid(x, y)
    return x, y, np.column_stack([xs.ravel(), ys.ravel()])


def basin_map(problem: Any, mats: Mapping[str, Any],
              scalars: Mapping[str, float] | None = None,
              n: int = DEFAULT_POINTS) -> BasinMap | None:
    """The basin map of one gain on an n × n grid (None when the problem offers none).

    Parameters
    ----------
    problem : object
        A problem; maps need :class:`BasinProblem`.
    mats : mapping
        The gain's matrices, each (N, N).
    scalars : mapping, optional
        Its scalar variables.
    n : int
        Grid points per axis (≥ 2).
    """
    if not isinstance(problem, BasinProblem):
        return None
    axes = problem.basin_axes()
    if axes is None:
        return None
    x, y, points = grid(axes, n)
    res = problem.basin_runs(mats, scalars, points)
    shape = (y.size, x.size)
    converged = np.asarray(res["converged"], dtype=bool).reshape(shape)
    arrival = np.asarray(res["arrival_time"], dtype=float).reshape(shape)
    region_of = getattr(problem, "basin_region", None)
    region = region_of(mats, scalars, points) if callable(region_of) else None
    if region is not None:
        region = {**region, "inside": np.asarray(region["inside"], bool).reshape(shape)}
    return BasinMap(axes, x, y, converged, np.where(converged, arrival, np.nan),
                    np.asarray(res["cost"], dtype=float).reshape(shape),
                    float(res["horizon"]), region)


def arrival_times(converged: np.ndarray, t_final: np.ndarray) -> np.ndarray:
    """Arrival times from runs that stop at the target: ``t_final`` where converged, NaN
    elsewhere."""
    return np.where(np.asarray(converged, bool), np.asarray(t_final, float), np.nan)


__all__ = ["DEFAULT_POINTS", "BasinAxes", "BasinMap", "BasinProblem", "arrival_times",
           "basin_map", "grid"]
