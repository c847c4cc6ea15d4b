"""Forward sensitivities of the attitude closed loop with respect to its gain (scipy).

The closed loop of :mod:`penaltyrun.dynamics.attitude` (not modified here), written again
(a compiled right-hand side of its own, integrated by scipy): y = (q, ω) (quaternion scalar
first, body rates in rad/s), running energy E (N²·m²·s),

    q̇ = ½ Ω(ω) q,   I ω̇ = u − ω × (I ω),   u = −G x,   x = (q_v, ω),   Ė = ½ uᵀu,

and, beside it, the sensitivities Y = ∂y/∂g (7 × 18) and e = ∂E/∂g (18,) with respect to the
gain entries g = vec(G) (row-major: g[6 i + j] = G[i, j], N·m per unit of x_j):

    Ẏ = F_y Y + F_g,   ė = uᵀ (∂u/∂y Y + ∂u/∂g),

F_y = ∂f/∂y the Jacobian of the right-hand side (exact: ½Ω(ω) and ½Ξ(q) for the kinematics,
I⁻¹(∂u/∂ω − [ω]×I + [Iω]×) for Euler's equation), ∂u/∂g = −I₃ ⊗ xᵀ and F_g = [0; I⁻¹∂u/∂g].
The 8 + 8·18 = 152 equations are integrated together by the compiled DOP853 of
:mod:`penaltyrun.dynamics.attitude_sens_kernel` (the default) or by
:func:`scipy.integrate.solve_ivp` (DOP853, ``compiled=False``: the reference the compiled
run is tested against; BDF with the block Jacobian of :func:`augmented_jacobian` for the
stiff gains that the compiled kernel integrates by RODAS4: of scipy's implicit methods the
cheapest on these 152 equations), with the step bounded so that a dip of the weighted event
distance d under ``tol`` is not stepped over, as in the kernel's reference runs.

Events located on the way (``sensitivity_run``):

* ``arrival``: d(y) = tol, decreasing (terminal; free-final-time runs only);
* ``dip``: ḋ = ∂d/∂y · f = 0 from below (the local minima of d, non-terminal; free-final-time
  runs only): an earlier minimum just above ``tol`` is where the arrival time jumps;
* ``limit``: max_i |u_i| = u_max (terminal; only with a torque limit): the unsaturated
  equations no longer hold, the cost has a kink there.

No torque limit is applied: a run that reaches the limit stops with status ``saturated``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit

#: Sensitivity parameters: the 18 entries of G (3 × 6), row-major.
N_GAIN = 18
#: Stiffness bound (1/s) above which an implicit method is used (the kernel's
#: ``STIFF_RATE``: above it the kernel switches to its implicit method as well).
STIFF_RATE = 1200.0


def stiffness(G: np.ndarray, inertia_inv: np.ndarray) -> float:
    """Row-sum bound on the spectral radius of the loop linearized at the target (1/s):
    max(½, max_i Σ_j |(I⁻¹G)_ij|)."""
    return float(max(0.5, np.max(np.sum(np.abs(inertia_inv @ G), axis=1))))


@njit(cache=True)
def rhs_parts(y, G, inertia, inertia_inv):
    """Right-hand side of (y, E) and its derivatives at one state (compiled).

    Parameters
    ----------
    y : ndarray, shape (≥7,)
        (q, ω, ...).
    G : ndarray, shape (3, 6)
    inertia, inertia_inv : ndarray, shape (3, 3)

    Returns
    -------
    f : ndarray, shape (8,)
        (q̇, ω̇, Ė).
    F_y : ndarray, shape (8, 7)
        ∂f/∂y (the last row ∂Ė/∂y).
    F_g : ndarray, shape (8, 18)
        ∂f/∂g.
    """
    q = y[:4].copy()
    w = y[4:7].copy()
    x = y[1:7].copy()
    u = -(G @ x)
    h = inertia @ w
    om = np.zeros((4, 4))
    om[0, 1], om[0, 2], om[0, 3] = -w[0], -w[1], -w[2]
    om[1, 0], om[1, 2], om[1, 3] = w[0], w[2], -w[1]
    om[2, 0], om[2, 1], om[2, 3] = w[1], -w[2], w[0]
    om[3, 0], om[3, 1], om[3, 2] = w[2], w[1], -w[0]
    xq = np.zeros((4, 3))
    xq[0, 0], xq[0, 1], xq[0, 2] = -q[1], -q[2], -q[3]
    xq[1, 0], xq[1, 1], xq[1, 2] = q[0], -q[3], q[2]
    xq[2, 0], xq[2, 1], xq[2, 2] = q[3], q[0], -q[1]
    xq[3, 0], xq[3, 1], xq[3, 2] = -q[2], q[1], q[0]
    gyro = np.empty(3)
    gyro[0] = w[1] * h[2] - w[2] * h[1]
    gyro[1] = w[2] * h[0] - w[0] * h[2]
    gyro[2] = w[0] * h[1] - w[1] * h[0]
    f = np.empty(8)
    f[:4] = 0.5 * (om @ q)
    f[4:7] = inertia_inv @ (u - gyro)
    f[7] = 0.5 * (u @ u)
    # d(ω × Iω)/dω = [ω]× I − [Iω]×
    dgyro = np.zeros((3, 3))
    for j in range(3):
        c = inertia[:, j]
        dgyro[0, j] = w[1] * c[2] - w[2] * c[1]
        dgyro[1, j] = w[2] * c[0] - w[0] * c[2]
        dgyro[2, j] = w[0] * c[1] - w[1] * c[0]
    dgyro[0, 1] += h[2]
    dgyro[0, 2] -= h[1]
    dgyro[1, 0] -= h[2]
    dgyro[1, 2] += h[0]
    dgyro[2, 0] += h[1]
    dgyro[2, 1] -= h[0]
    du_dy = np.zeros((3, 7))
    du_dy[:, 1:7] = -G
    F_y = np.zeros((8, 7))
    F_y[:4, :4] = 0.5 * om
    F_y[:4, 4:7] = 0.5 * xq
    F_y[4:7, :] = inertia_inv @ du_dy
    F_y[4:7, 4:7] -= inertia_inv @ dgyro
    F_y[7, :] = u @ du_dy
    F_g = np.zeros((8, N_GAIN))
    for i in range(3):
        for j in range(6):
            for k in range(3):
                F_g[4 + k, 6 * i + j] = -inertia_inv[k, i] * x[j]
            F_g[7, 6 * i + j] = -u[i] * x[j]
    return f, F_y, F_g


@njit(cache=True)
def augmented(z, G, inertia, inertia_inv):
    """Right-hand side of the 152 augmented equations (compiled): z = (y, E, vec(Y), e),
    Y (7 × 18) row-major."""
    f, F_y, F_g = rhs_parts(z, G, inertia, inertia_inv)
    Y = z[8:8 + 7 * N_GAIN].copy().reshape(7, N_GAIN)
    dS = F_y @ Y + F_g
    out = np.empty_like(z)
    out[:8] = f
    out[8:8 + 7 * N_GAIN] = dS[:7].copy().reshape(7 * N_GAIN)
    out[8 + 7 * N_GAIN:] = dS[7]
    return out


def augmented_rhs(G: np.ndarray, inertia: np.ndarray,
                  inertia_inv: np.ndarray) -> Callable[[float, np.ndarray], np.ndarray]:
    """``rhs(t, z)`` of the augmented equations for :func:`scipy.integrate.solve_ivp`."""
    G, inertia, inertia_inv = (np.ascontiguousarray(a, dtype=float)
                               for a in (G, inertia, inertia_inv))

    def rhs(t: float, z: np.ndarray) -> np.ndarray:
        return augmented(z, G, inertia, inertia_inv)

    return rhs


def augmented_jacobian(G: np.ndarray, inertia: np.ndarray, inertia_inv: np.ndarray
                       ) -> Callable[[float, np.ndarray], np.ndarray]:
    """``jac(t, z)`` (152 × 152) for the implicit method (BDF): the exact blocks ∂ẏ/∂y and
    ∂(Ẏ, ė)/∂(Y, e) = F_y ⊗ I₁₈; the block ∂Ẏ/∂y (second derivatives of f) is left out.
    Only the Newton iteration of the implicit method sees it: its convergence slows a
    little, the solution is the same (the coupling is one-way, y does not depend on Y)."""
    G, inertia, inertia_inv = (np.ascontiguousarray(a, dtype=float)
                               for a in (G, inertia, inertia_inv))
    eye = np.eye(N_GAIN)

    def jac(t: float, z: np.ndarray) -> np.ndarray:
        _, F_y, _ = rhs_parts(z, G, inertia, inertia_inv)
        out = np.zeros((z.size, z.size))
        out[:8, :7] = F_y
        out[8:, 8:8 + 7 * N_GAIN] = np.kron(F_y, eye)
        return out

    return jac


def distance(y: np.ndarray, weights: tuple[float, float, float]) -> float:
    """Weighted event distance ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ of one state."""
    w0, wq, ww = weights
    return float(np.sqrt((w0 * (y[0] - 1.0)) ** 2 + wq ** 2 * np.sum(y[1:4] ** 2)
                         + ww ** 2 * np.sum(y[4:7] ** 2)))


def distance_gradient(y: np.ndarray, weights: tuple[float, float, float]) -> np.ndarray:
    """∂d/∂y (7,) of the weighted event distance (d > 0)."""
    w0, wq, ww = weights
    g = np.concatenate([[w0 ** 2 * (y[0] - 1.0)], wq ** 2 * y[1:4], ww ** 2 * y[4:7]])
    return g / distance(y, weights)


@dataclass(frozen=True)
class SensitivityRun:
    """End of one augmented run.

    Attributes
    ----------
    status : str
        ``"arrived"`` (the event fired), ``"horizon"`` (ran to the end), ``"saturated"``
        (the torque reached the limit) or ``"failed"`` (the integrator stopped).
    t_end : float
        End time (s).
    y : ndarray, shape (7,)
        (q, ω) at ``t_end``.
    energy : float
        E at ``t_end`` (N²·m²·s).
    Y : ndarray, shape (7, 18)
        ∂y/∂g at ``t_end`` (the end time held fixed).
    e : ndarray, shape (18,)
        ∂E/∂g at ``t_end`` (the end time held fixed).
    f : ndarray, shape (8,)
        (q̇, ω̇, Ė) at ``t_end``.
    dips : ndarray, shape (k,)
        The weighted distance at its local minima before ``t_end``.
    message : str
        The integrator's message.
    """

    status: str
    t_end: float
    y: np.ndarray
    energy: float
    Y: np.ndarray
    e: np.ndarray
    f: np.ndarray
    dips: np.ndarray
    message: str


def sensitivity_run(G: np.ndarray, y0: np.ndarray, inertia: np.ndarray, t_end: float,
                    weights: tuple[float, float, float], tol: float | None,
                    u_max: float = np.inf, rtol: float = 1e-10, atol: float = 1e-10,
                    max_step: float = 0.2, *, compiled: bool = True,
                    event_spacing: float = 0.05, n_samples: int = 4,
                    max_steps: int = 10**6) -> SensitivityRun:
    """Integrate the closed loop and its gain sensitivities from ``y0``.

    A loop that is not stiff is integrated by the compiled DOP853 of
    :mod:`penaltyrun.dynamics.attitude_sens_kernel` (``compiled``, the default) or by
    scipy's (``compiled=False``, the reference it is checked against); a stiff one by scipy's
    BDF.

    Parameters
    ----------
    G : ndarray, shape (3, 6)
        Gain of u = −G x (N·m per unit of x).
    y0 : ndarray, shape (7,)
        Initial (q, ω) (unit quaternion).
    inertia : ndarray, shape (3, 3)
        Inertia (kg·m²).
    t_end : float
        Last time of the run (s).
    weights : tuple of float
        Event weights (w_q0, w_qv, w_ω).
    tol : float or None
        Event tolerance on the weighted distance; None: no arrival event (fixed horizon).
    u_max : float
        Per-axis torque limit (N·m); ``inf``: none.
    rtol, atol : float
        solve_ivp tolerances (applied to the states and their sensitivities).
    max_step : float
        Largest step (s).
    compiled : bool
        The compiled integrator for a loop that is not stiff.
    event_spacing, n_samples, max_steps
        The compiled integrator's probe spacing of the events (s), probes per step near
        them and step cap (:func:`penaltyrun.dynamics.dop853.make_dop853`).

    Returns
    -------
    SensitivityRun
    """
    from scipy.integrate import solve_ivp

    G = np.ascontiguousarray(G, dtype=float)
    inertia = np.ascontiguousarray(inertia, dtype=float)
    inertia_inv = np.linalg.inv(inertia)
    stiff = stiffness(G, inertia_inv) > STIFF_RATE
    if compiled and not stiff:
        return _compiled_run(G, y0, inertia, inertia_inv, t_end, weights, tol, u_max, rtol,
                             atol, max_step, event_spacing, n_samples, max_steps)
    rhs = augmented_rhs(G, inertia, inertia_inv)

    def dip(t: float, z: np.ndarray) -> float:
        y = z[:7]
        f = rhs_parts(y, G, inertia, inertia_inv)[0]
        return float(distance_gradient(y, weights) @ f[:7])

    dip.direction = 1.0
    events = []
    if tol is not None:
        events.append(dip)

        def arrival(t: float, z: np.ndarray) -> float:
            return distance(z[:7], weights) - tol

        arrival.terminal = True
        arrival.direction = -1.0
        events.append(arrival)
    if np.isfinite(u_max):
        def limit(t: float, z: np.ndarray) -> float:
            return float(u_max - np.max(np.abs(G @ z[1:7])))

        limit.terminal = True
        limit.direction = -1.0
        events.append(limit)
    z0 = np.zeros(8 + 8 * N_GAIN)
    z0[:7] = y0
    implicit = {"jac": augmented_jacobian(G, inertia, inertia_inv)} if stiff else {}
    sol = solve_ivp(rhs, (0.0, float(t_end)), z0, method="BDF" if stiff else "DOP853",
                    rtol=rtol, atol=atol, max_step=max_step, events=events or None,
                    **implicit)
    z = sol.y[:, -1]
    status = "horizon" if sol.status == 0 else "failed"
    if sol.status == 1:
        named = dict(zip(("dip", "arrival", "limit") if tol is not None else ("limit",),
                         sol.t_events))
        status = "arrived" if named.get("arrival", np.empty(0)).size else "saturated"
    dips = np.asarray([distance(v[:7], weights) for v in sol.y_events[0]]) \
        if tol is not None and sol.y_events[0].size else np.empty(0)
    return _run_end(status, float(sol.t[-1]), z, G, y0, inertia, inertia_inv, u_max, dips,
                    str(sol.message))


def _run_end(status: str, t: float, z: np.ndarray, G: np.ndarray, y0: np.ndarray,
             inertia: np.ndarray, inertia_inv: np.ndarray, u_max: float, dips: np.ndarray,
             message: str) -> SensitivityRun:
    """The :class:`SensitivityRun` of an augmented state ``z`` at the end time ``t`` (either
    integrator); a torque over ``u_max`` at the start is ``saturated`` whatever the run."""
    if np.isfinite(u_max) and np.max(np.abs(G @ np.asarray(y0, float)[1:7])) >= u_max:
        status = "saturated"
    f = rhs_parts(z[:7], G, inertia, inertia_inv)[0]
    return SensitivityRun(status, t, z[:7].copy(), float(z[7]),
                          z[8:8 + 7 * N_GAIN].reshape(7, N_GAIN).copy(),
                          z[8 + 7 * N_GAIN:].copy(), f, dips, message)


def _compiled_run(G: np.ndarray, y0: np.ndarray, inertia: np.ndarray,
                  inertia_inv: np.ndarray, t_end: float, weights: tuple[float, float, float],
                  tol: float | None, u_max: float, rtol: float, atol: float, max_step: float,
                  event_spacing: float, n_samples: int, max_steps: int) -> SensitivityRun:
    """:func:`sensitivity_run` by the compiled integrator."""
    from penaltyrun.dynamics import attitude_sens_kernel as kernel
    from penaltyrun.dynamics.integrate import EVENT, HORIZON, STATUS_NAMES

    y0 = np.asarray(y0, dtype=float)
    t, z, code, steps, dips = kernel.integrate(
        G, y0, inertia, inertia_inv, t_end, weights, tol, u_max, rtol, atol, max_step,
        event_spacing, n_samples, max_steps)
    if code == EVENT:
        arrived = tol is not None and distance(z[:7], weights) <= tol * (1.0 + 1e-9)
        status = "arrived" if arrived else "saturated"
    else:
        status = "horizon" if code == HORIZON else "failed"
    return _run_end(status, t, z, G, y0, inertia, inertia_inv, u_max, dips,
                    f"compiled DOP853: {STATUS_NAMES[code]} after {steps} steps")


def adjoint_gradient(G: np.ndarray, y0: np.ndarray, inertia: np.ndarray, t_end: float,
                     weights: tuple[float, float, float], tol: float | None,
                     S: np.ndarray | None = None, rho: float = 0.0, rtol: float = 1e-10,
                     atol: float = 1e-10, max_step: float = 0.2) -> tuple[np.ndarray, float]:
    """∂J/∂g (18,) by the adjoint method: the second way to the same derivative as
    :func:`sensitivity_run` (for the cross-check and the cost comparison; no saturation
    and no event checks).

    A forward run of (y, E) with dense output, then the costate λ (7) and the running
    integral μ (18) backwards from the end time:

        λ̇ = −(F_y[:7]ᵀ λ + F_y[7]),   μ̇ = −(λᵀ F_g[:7] + F_g[7]),   μ(t_end) = 0,

    and ∂J/∂g = μ(0). Fixed horizon (``tol`` None): J = E(T) + x(T)ᵀ S x(T),
    λ(T) = (0, 2 S x(T)). Free final time: J = E(t_f) + ρ t_f, and the implicit function
    theorem on d(y(t_f)) = tol gives λ(t_f) = −(Ė(t_f) + ρ) / ḋ(t_f) · ∂d/∂y.

    Returns
    -------
    grad : ndarray, shape (18,)
    cost : float
        J of the forward run (N²·m²·s).
    """
    from scipy.integrate import solve_ivp

    G = np.ascontiguousarray(G, dtype=float)
    inertia = np.ascontiguousarray(inertia, dtype=float)
    inertia_inv = np.linalg.inv(inertia)

    def forward(t: float, y: np.ndarray) -> np.ndarray:
        return rhs_parts(y, G, inertia, inertia_inv)[0]

    events = []
    if tol is not None:
        def arrival(t: float, y: np.ndarray) -> float:
            return distance(y, weights) - tol

        arrival.terminal = True
        arrival.direction = -1.0
        events.append(arrival)
    stiff = stiffness(G, inertia_inv) > STIFF_RATE
    method = "Radau" if stiff else "DOP853"
    fwd = solve_ivp(forward, (0.0, float(t_end)), np.concatenate([y0, [0.0]]), method=method,
                    rtol=rtol, atol=atol, max_step=max_step, events=events or None,
                    dense_output=True)
    t_f = float(fwd.t[-1])
    y_f = fwd.y[:, -1]
    lam = np.zeros(7)
    if tol is None:
        lam[1:7] = 2.0 * (np.asarray(S, dtype=float) @ y_f[1:7])
        cost = float(y_f[7] + y_f[1:7] @ np.asarray(S, dtype=float) @ y_f[1:7])
    else:
        f = forward(t_f, y_f)
        d_y = distance_gradient(y_f, weights)
        lam = -(f[7] + rho) / float(d_y @ f[:7]) * d_y
        cost = float(y_f[7] + rho * t_f)

    def backward(t: float, w: np.ndarray) -> np.ndarray:
        _, F_y, F_g = rhs_parts(fwd.sol(t), G, inertia, inertia_inv)
        lam_t = w[:7]
        out = np.empty(7 + N_GAIN)
        out[:7] = -(F_y[:7].T @ lam_t + F_y[7])
        out[7:] = -(lam_t @ F_g[:7] + F_g[7])
        return out

    bwd = solve_ivp(backward, (t_f, 0.0), np.concatenate([lam, np.zeros(N_GAIN)]),
                    method=method, rtol=rtol, atol=atol, max_step=max_step)
    return bwd.y[7:, -1].copy(), cost


__all__ = ["N_GAIN", "STIFF_RATE", "SensitivityRun", "adjoint_gradient", "augmented",
           "augmented_jacobian", "augmented_rhs", "distance", "distance_gradient", "rhs_parts",
           "sensitivity_run", "stiffness"]
