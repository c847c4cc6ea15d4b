"""Attitude representations for the attitude problems: quaternions (scalar first, q0 ≥ 0),
intrinsic Z-Y-X Euler angles, modified Rodrigues parameters, the held-out grid of initial
attitudes and seeded perturbations of an initial state. Plain numpy (no kernels)."""

from __future__ import annotations

from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError

#: Key prefix of the attitude problems' parameters in messages (``problem.params.<key>``,
#: as the command line takes them).
PREFIX = "problem.params"

#: Allowed values of ``Params.attitude_type``.
ATTITUDE_TYPES = ("euler", "quaternion", "mrp")




def normalize_quaternion(q: Any) -> np.ndarray:
    """Unit quaternion(s) with q0 ≥ 0 (q and −q are the same attitude).

    Parameters
    ----------
    q : array_like, shape (..., 4)
        Scalar-first quaternions.

    Returns
    -------
    ndarray, shape (..., 4)
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def euler_to_quaternion(angles_deg: Any) -> np.ndarray:
    """Quaternion of intrinsic Z-Y-X Euler angles, normalized to q0 ≥ 0.

    Parameters
    ----------
    angles_deg : array_like, shape (..., 3)
        (yaw, pitch, roll) in degrees; the rotation is yaw about z, then pitch about the new
        y, then roll about the newest x (q = q_z(yaw) ⊗ q_y(pitch) ⊗ q_x(roll)).

    Returns
    -------
    ndarray, shape (..., 4)
        Scalar-first unit quaternions with q0 ≥ 0.
    """
    a = np.radians(np.asarray(angles_deg, dtype=float)) / 2.0
    cy, sy = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cr, sr = np.cos(a[..., 2]), np.sin(a[..., 2])
    q = np.stack([
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ], axis=-1)
    return normalize_quaternion(q)


def quaternion_to_euler(q: Any) -> np.ndarray:
    """Intrinsic Z-Y-X Euler angles (yaw, pitch, roll) in degrees of scalar-first
    quaternions, the inverse of :func:`euler_to_quaternion` for pitch in (−90°, 90°).

    Parameters
    ----------
    q : array_like, shape (..., 4)

    Returns
    -------
    ndarray, shape (..., 3)
        Yaw and roll in (−180°, 180°], pitch in [−90°, 90°].
    """
    w, x, y, z = np.moveaxis(normalize_quaternion(q), -1, 0)
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    return np.degrees(np.stack([yaw, pitch, roll], axis=-1))


def mrp_to_quaternion(sigma: Any) -> np.ndarray:
    """Quaternion of modified Rodrigues parameters, normalized to q0 ≥ 0.

    Parameters
    ----------
    sigma : array_like, shape (..., 3)

    Returns
    -------
    ndarray, shape (..., 4)
    """
    s = np.asarray(sigma, dtype=float)
    s2 = np.sum(s * s, axis=-1, keepdims=True)
    q = np.concatenate([(1.0 - s2) / (1.0 + s2), 2.0 * s / (1.0 + s2)], axis=-1)
    return normalize_quaternion(q)


def attitude_to_quaternion(kind: str, values: Any) -> np.ndarray:
    """Unit quaternion (q0 ≥ 0) from an attitude given as ``kind`` (see :data:`ATTITUDE_TYPES`).

    Raises
    ------
    ConfigError
        Unknown ``kind``.
    """
    if kind == "euler":
        return euler_to_quaternion(values)
    if kind == "quaternion":
        return normalize_quaternion(values)
    if kind == "mrp":
        return mrp_to_quaternion(values)
    raise ConfigError(f"{PREFIX}.attitude_type", f"unknown type {kind!r}",
                      allowed=ATTITUDE_TYPES)


def robustness_grid(n: int = 6, lo: float = 10.0, hi: float = 350.0) -> np.ndarray:
    """Grid of (yaw, pitch, roll) in degrees, each in linspace(lo, hi, n); shape (n³, 3)."""
    g = np.linspace(lo, hi, n)
    Y, P, R = np.meshgrid(g, g, g, indexing="ij")
    return np.stack([Y.ravel(), P.ravel(), R.ravel()], axis=1)




def quaternion_product(p: Any, q: Any) -> np.ndarray:
    """Hamilton product p ⊗ q of scalar-first quaternions, shape (..., 4)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, pv = p[..., :1], p[..., 1:]
    q0, qv = q[..., :1], q[..., 1:]
    scalar = p0 * q0 - np.sum(pv * qv, axis=-1, keepdims=True)
    vector = p0 * qv + q0 * pv + np.cross(pv, qv)
    return np.concatenate([scalar, vector], axis=-1)


def perturbed_states(q: Any, omega: Any, n: int, max_angle_deg: float, rate_rel: float,
                     seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Seeded perturbations of one initial state (held-out scenarios).

    Each attitude is ``q`` rotated about a uniformly random axis by an angle uniform in
    [0, ``max_angle_deg``]; each rate vector is ``omega`` with every component multiplied by
    1 + ``rate_rel`` · u, u uniform in [−1, 1].

    Parameters
    ----------
    q : array_like, shape (4,)
        Nominal unit quaternion (scalar first).
    omega : array_like, shape (3,)
        Nominal body rates (rad/s).
    n : int
        Number of perturbed states.
    max_angle_deg : float
        Largest attitude perturbation (degrees).
    rate_rel : float
        Largest relative rate perturbation per component.
    seed : int
        Seed of ``numpy.random.default_rng``.

    Returns
    -------
    quaternions : ndarray, shape (n, 4)
        Unit quaternions with q0 ≥ 0.
    rates : ndarray, shape (n, 3)
        Body rates (rad/s).
    """
    rng = np.random.default_rng(int(seed))
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    half = 0.5 * np.radians(rng.uniform(0.0, max_angle_deg, size=n))
    dq = np.concatenate([np.cos(half)[:, None], np.sin(half)[:, None] * axis], axis=1)
    quats = normalize_quaternion(quaternion_product(dq, np.asarray(q, dtype=float)[None]))
    rates = np.asarray(omega, dtype=float)[None] * (
        1.0 + rate_rel * rng.uniform(-1.0, 1.0, size=(n, 3)))
    return quats, rates


__all__ = [
    "ATTITUDE_TYPES",
    "attitude_to_quaternion",
    "euler_to_quaternion",
    "mrp_to_quaternion",
    "normalize_quaternion",
    "perturbed_states",
    "quaternion_product",
    "quaternion_to_euler",
    "robustness_grid",
]
