"""Robustness and time-response measures of LQR closed loops, batched over candidates:
the disk margin at the plant input, and the settling time and overshoot of the outputs'
responses from the initial states.

Disk margin (balanced, skew 0; Seiler, Packard & Gahinet 2020): with the loop broken at the
plant input, L(s) = K (sI − A)⁻¹ B (discrete: s → z = e^{jω dt}) and S = (I + L)⁻¹,

    α = 1 / max_ω σ̄(S(jω) − I/2)

on a frequency grid (:func:`frequency_grid`); S is formed as I − K (sI − A + BK)⁻¹ B,
which stays finite at poles of the plant on the axis. For one input this is
python-control's ``disk_margins(L, omega)``; with several inputs σ̄ is the unstructured
bound, which is never above the loop-at-a-time (μ, diagonal) margin python-control
computes with slycot: a conservative margin. The loop tolerates simultaneous gain changes in
[(2 − α)/(2 + α), (2 + α)/(2 − α)] or phase changes up to 2 atan(α/2).

Settling time and overshoot of an output y_i = C_y x from its initial value y_i(0) ≠ 0
towards 0 — those of the step response y_i(0) − y_i(t) (final value y_i(0)) that
python-control's ``step_info`` computes: the settling time is the first sample time after
which |y_i(t)| < band·|y_i(0)| for good (``inf`` if the last sample is outside), the
overshoot 100 · max(0, max_t −y_i(t)/y_i(0)) percent. Outputs with y_i(0) = 0 have
neither.
"""

from __future__ import annotations

import numpy as np


def frequency_grid(A: np.ndarray, dt: float | None, points: int) -> np.ndarray:
    """Log-spaced frequencies (rad per time unit): eight decades around the plant's scale
    s = max(1, spectral radius of A) in continuous time, [1e-4, 1]·π/dt in discrete
    time (up to the Nyquist frequency)."""
    if dt:
        top = np.pi / dt
        return np.logspace(np.log10(top) - 4.0, np.log10(top), points)
    scale = max(1.0, float(np.max(np.abs(np.linalg.eigvals(A)))))
    return np.logspace(np.log10(scale) - 4.0, np.log10(scale) + 4.0, points)


def disk_margin_curve(A: np.ndarray, B: np.ndarray, K: np.ndarray, omega: np.ndarray,
                      dt: float | None = None) -> np.ndarray:
    """α(ω) = 1 / σ̄(S − I/2) per candidate and frequency.

    Parameters
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    K : ndarray, shape (C, m, n)
        Stabilizing gains (u = −K x).
    omega : ndarray, shape (W,)
        Frequencies (rad per time unit).
    dt : float, optional
        Sampling time (discrete time).

    Returns
    -------
    ndarray, shape (C, W)
    """
    n, m = B.shape
    s = np.exp(1j * omega * dt) if dt else 1j * omega
    A_cl = A[None] - B[None] @ K                                    # (C, n, n)
    M = s[None, :, None, None] * np.eye(n) - A_cl[:, None]          # (C, W, n, n)
    X = np.linalg.solve(M, np.broadcast_to(B.astype(complex), M.shape[:2] + (n, m)))
    S = np.eye(m) - K[:, None].astype(complex) @ X                  # (C, W, m, m)
    top = np.linalg.svd(S - 0.5 * np.eye(m), compute_uv=False)[..., 0]
    return 1.0 / top


def disk_margin(A: np.ndarray, B: np.ndarray, K: np.ndarray, omega: np.ndarray,
                dt: float | None = None) -> np.ndarray:
    """Balanced disk margin α (the minimum over ``omega`` of :func:`disk_margin_curve`),
    shape (C,)."""
    return disk_margin_curve(A, B, K, omega, dt).min(axis=1)


def disk_gain_phase(alpha: float) -> tuple[float, float]:
    """Disk-based gain margin (dB) and phase margin (degrees) of a balanced disk margin α
    (gain margin ``inf`` and phase margin 90° or more for α ≥ 2)."""
    if alpha >= 2.0:
        return float("inf"), float(np.degrees(2.0 * np.arctan(alpha / 2.0)))
    gain = (2.0 + alpha) / (2.0 - alpha)
    return float(20.0 * np.log10(gain)), float(np.degrees(2.0 * np.arctan(alpha / 2.0)))


def alpha_for(gain_margin_db: float | None = None, phase_margin_deg: float | None = None
              ) -> float:
    """The smallest balanced disk margin α whose disk-based gain margin is at least
    ``gain_margin_db`` (dB, > 0) and whose phase margin is at least ``phase_margin_deg``
    (degrees, in (0, 180)): the inverse of :func:`disk_gain_phase`, 0 when neither is
    given."""
    need = 0.0
    if gain_margin_db is not None:
        g = 10.0 ** (gain_margin_db / 20.0)
        need = max(need, 2.0 * (g - 1.0) / (g + 1.0))
    if phase_margin_deg is not None:
        need = max(need, 2.0 * float(np.tan(np.radians(phase_margin_deg) / 2.0)))
    return need


def settling_overshoot(t: np.ndarray, y: np.ndarray, band: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Settling time and overshoot of every response, worst over its outputs.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times (time unit), t[0] = 0.
    y : ndarray, shape (..., N, p)
        Output samples; y[..., 0, :] is the initial value.
    band : float
        Settling band, a fraction of |y_i(0)|.

    Returns
    -------
    settling : ndarray, shape (...)
        Largest settling time over the outputs with y_i(0) ≠ 0 (``inf``: not settled by the
        last sample; 0 when no output starts away from 0).
    overshoot : ndarray, shape (...)
        Largest overshoot over those outputs (percent).
    """
    y0 = y[..., :1, :]
    size = np.abs(y0)
    moving = size > 1e-12 * np.maximum(size.max(axis=-1, keepdims=True), 1e-300)
    with np.errstate(all="ignore"):
        outside = (np.abs(y) >= band * size) | ~np.isfinite(y)
        rel = np.where(moving, -y / np.where(moving, y0, 1.0), 0.0)
    outside &= moving
    n_t = t.shape[0]
    last = n_t - 1 - np.argmax(outside[..., ::-1, :], axis=-2)      # (..., p)
    last = np.where(outside.any(axis=-2), last, -1)
    t_ext = np.append(t, np.inf)
    settle = np.where(last < 0, 0.0, t_ext[np.minimum(last + 1, n_t)])
    over = 100.0 * np.maximum(0.0, np.nanmax(np.where(np.isfinite(rel), rel, np.inf),
                                             axis=-2))
    return settle.max(axis=-1), over.max(axis=-1)


__all__ = ["alpha_for", "disk_gain_phase", "disk_margin", "disk_margin_curve", "frequency_grid",
           "settling_overshoot"]
