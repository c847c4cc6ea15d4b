"""Closed-loop diagnostics of a tuned controller, from the ``closed_loop`` hook.

For a problem whose law is linear or linearizable at the target, ``problem.closed_loop(mats,
scalars)`` returns a :class:`~penaltyrun.problems.base.ClosedLoop`. From its state matrix
this module computes

* the eigenvalues (poles) λ of the closed loop, and their continuous-time equivalents
  s = λ (continuous loop) or s = log(z) / dt (discrete loop, principal logarithm), in
  1 / (the problem's time unit);
* the slowest real part max Re(s): the decay rate of the slowest mode (negative when the
  loop is stable; for a discrete loop Re(s) = log|z| / dt);
* the smallest damping ratio min ζ, ζ = −Re(s) / |s| (python-control's ``damp``
  convention; a pole at s = 0 has no damping ratio and is left out, a discrete pole at
  z = 0 has ζ = 1);
* the 2-norm ‖K‖₂ (largest singular value) and the 2-norm condition number σ_max / σ_min
  (``inf`` for a rank-deficient gain) of the gain K, where there is one.

:func:`record_columns` turns them into the result columns the runner stores with each job
(:data:`COLUMNS`); a problem without the hook, or a candidate without a closed loop, gets
nulls. Only numpy here.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from penaltyrun.errors import raise_wrapped_exit
from penaltyrun.problems.base import ClosedLoop
from penaltyrun.problems.hooks import hooks

logger = logging.getLogger(__name__)

#: Result columns filled by :func:`record_columns` (see :mod:`penaltyrun.io.schema`).
COLUMNS = ("closed_loop", "cl_eig_real", "cl_eig_imag", "cl_slowest_real", "cl_min_damping",
           "cl_gain_norm", "cl_gain_cond")


@dataclass(frozen=True)
class Diagnostics:
    """Eigenvalue diagnostics of one closed loop (see the module docstring).

    Attributes
    ----------
    eigenvalues : ndarray of complex, shape (n,)
        Poles of the closed-loop matrix (z-plane for a discrete loop), sorted by the
        real part of their continuous equivalents, slowest first.
    poles : ndarray of complex, shape (n,)
        Continuous-time equivalents s (1 / time unit), same order.
    slowest_real : float
        max Re(s) (1 / time unit).
    min_damping : float
        Smallest damping ratio (NaN when every pole is at s = 0).
    gain_norm, gain_cond : float
        ‖K‖₂ and its condition number (NaN without a gain).
    """

    eigenvalues: np.ndarray
    poles: np.ndarray
    slowest_real: float
    min_damping: float
    gain_norm: float
    gain_cond: float


def continuous_poles(eigenvalues: Any, time: str = "continuous",
                     dt: float | None = None) -> np.ndarray:
    """Continuous-time equivalents of closed-loop eigenvalues.

    Parameters
    ----------
    eigenvalues : array_like of complex, shape (n,)
        λ (continuous) or z (discrete).
    time : str
        ``"continuous"`` or ``"discrete"``.
    dt : float, optional
        Sample time of a discrete loop.

    Returns
    -------
    ndarray of complex, shape (n,)
        s = λ, or s = log(z) / dt (z = 0 gives s = −inf).
    """
    lam = np.asarray(eigenvalues, dtype=complex)
    if time == "continuous":
        return lam
    if not (dt is not None and dt > 0):
        raise ValueError("a discrete loop needs a sample time dt > 0")
    out = np.full(lam.shape, -np.inf + 0j)
    nonzero = lam != 0
    out[nonzero] = np.log(lam[nonzero]) / float(dt)
    return out


def damping_ratios(poles: Any) -> np.ndarray:
    """ζ = −Re(s) / |s| per continuous pole s (NaN at s = 0; 1 at s = −inf).

    Parameters
    ----------
    poles : array_like of complex, shape (n,)

    Returns
    -------
    ndarray, shape (n,)
    """
    s = np.asarray(poles, dtype=complex)
    zeta = np.full(s.shape, np.nan)
    infinite = np.isinf(s.real)
    zeta[infinite] = -np.sign(s.real[infinite])
    finite = ~infinite & (np.abs(s) > 0)
    zeta[finite] = -s.real[finite] / np.abs(s[finite])
    return zeta


def gain_norm_cond(gain: Any) -> tuple[float, float]:
    """(‖K‖₂, σ_max / σ_min) of a gain K (m × n); (NaN, NaN) for None.

    The condition number is over the min(m, n) singular values; ``inf`` when the smallest
    is zero.
    """
    if gain is None:
        return float("nan"), float("nan")
    sv = np.linalg.svd(np.atleast_2d(np.asarray(gain, dtype=float)), compute_uv=False)
    if sv.size == 0:
        return float("nan"), float("nan")
    cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")
    return float(sv[0]), cond


def diagnose(loop: ClosedLoop) -> Diagnostics:
    """Eigenvalue diagnostics of a closed loop (see the module docstring)."""
    lam = np.linalg.eigvals(loop.matrix)
    s = continuous_poles(lam, loop.time, loop.dt)
    order = np.lexsort((s.imag, -s.real))
    lam, s = lam[order], s[order]
    zeta = damping_ratios(s)
    norm, cond = gain_norm_cond(loop.gain)
    return Diagnostics(
        eigenvalues=lam, poles=s,
        slowest_real=float(np.max(s.real)) if s.size else float("nan"),
        min_damping=float(np.nanmin(zeta)) if np.any(np.isfinite(zeta)) else float("nan"),
        gain_norm=norm, gain_cond=cond)


def closed_loop_of(problem: Any, mats: Mapping[str, Any],
                   scalars: Mapping[str, float] | None = None) -> ClosedLoop | None:
    """``problem.closed_loop(mats, scalars)``, or None when the problem has no such hook.

    Raises
    ------
    TypeError
        The hook returned something other than a :class:`ClosedLoop` or None.
    """
    hook = hooks(problem).closed_loop
    if hook is None:
        return None
    loop = hook({k: np.asarray(v, dtype=float) for k, v in mats.items()}, scalars or None)
    if loop is not None and not isinstance(loop, ClosedLoop):
        raise TypeError(f"closed_loop returned {type(loop).__name__}, not ClosedLoop")
    return loop


def slowest_reals(loops: Sequence[ClosedLoop | None]) -> np.ndarray:
    """max Re(s) of each closed loop (:attr:`Diagnostics.slowest_real`; NaN for None, an
    empty or non-finite state matrix, or one whose eigenvalues LAPACK cannot compute), the
    eigenvalues of loops of one shape computed as one stack.

    Parameters
    ----------
    loops : sequence of ClosedLoop or None, length L

    Returns
    -------
    ndarray, shape (L,)
        1 / time unit.
    """
    out = np.full(len(loops), np.nan)
    alike: dict[tuple[Any, ...], list[int]] = {}
    for i, loop in enumerate(loops):
        if loop is not None and loop.matrix.size and np.isfinite(loop.matrix).all():
            alike.setdefault((loop.matrix.shape, loop.time, loop.dt), []).append(i)
    for (_, time, dt), where in alike.items():
        try:
            lam = np.linalg.eigvals(np.stack([loops[i].matrix for i in where]))
            out[where] = continuous_poles(lam, time, dt).real.max(axis=1)
        except np.linalg.LinAlgError:  # one at a time: NaN where it fails
            for i in where:
                try:
                    out[i] = diagnose(loops[i]).slowest_real
                except np.linalg.LinAlgError:
                    pass
    return out


def loop_json(loop: ClosedLoop) -> dict[str, Any]:
    """A closed loop as plain JSON data (the ``closed_loop`` result column)."""
    return {"time": loop.time, "dt": loop.dt, "matrix": loop.matrix.tolist(),
            "gain": None if loop.gain is None else loop.gain.tolist(),
            "state_names": list(loop.state_names), "input_names": list(loop.input_names)}


def loop_from_json(data: Mapping[str, Any]) -> ClosedLoop:
    """The inverse of :func:`loop_json`."""
    return ClosedLoop(matrix=np.asarray(data["matrix"], dtype=float),
                      time=str(data.get("time", "continuous")), dt=data.get("dt"),
                      gain=None if data.get("gain") is None else np.asarray(data["gain"], float),
                      state_names=tuple(data.get("state_names") or ()),
                      input_names=tuple(data.get("input_names") or ()))


def columns(loop: ClosedLoop | None) -> dict[str, Any]:
    """The result columns (:data:`COLUMNS`) of one closed loop; all None for None."""
    if loop is None:
        return dict.fromkeys(COLUMNS)
    d = diagnose(loop)
    return {"closed_loop": loop_json(loop),
            "cl_eig_real": [float(v) for v in d.eigenvalues.real],
            "cl_eig_imag": [float(v) for v in d.eigenvalues.imag],
            "cl_slowest_real": d.slowest_real, "cl_min_damping": d.min_damping,
            "cl_gain_norm": d.gain_norm, "cl_gain_cond": d.gain_cond}


def record_columns(problem: Any, mats: Mapping[str, Any],
                   scalars: Mapping[str, float] | None = None) -> dict[str, Any]:
    """The result columns of one candidate of ``problem``; all None when the problem has
    no ``closed_loop`` hook, the candidate has no closed loop, or the hook fails (logged:
    a diagnostic never fails a job)."""
    try:
        return columns(closed_loop_of(problem, mats, scalars))
    except Exception as exc:  # a diagnostic must not lose the job's result
        raise_wrapped_exit(exc)
        logger.warning("closed-loop diagnostics of %s failed: %s",
                       getattr(problem, "name", "problem"), exc)
        return dict.fromkeys(COLUMNS)


__all__ = ["COLUMNS", "Diagnostics", "closed_loop_of", "columns", "continuous_poles",
           "damping_ratios", "diagnose", "gain_norm_cond", "loop_from_json", "loop_json",
           "record_columns", "slowest_reals"]
