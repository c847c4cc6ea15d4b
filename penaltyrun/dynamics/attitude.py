"""Compiled closed loop of rigid-body attitude control (quaternion + body rates + cost).

State ``y = (q0, q1, q2, q3, ω1, ω2, ω3, J)`` (quaternion scalar first, Hamilton convention;
body rates in rad/s; running cost J in N²·m²·s). Dynamics:

* kinematics q̇ = ½ Ω(ω) q;
* Euler's equation ω̇ = I⁻¹ (u − ω × (I ω)) with a full 3×3 inertia I (kg·m²);
* linear feedback u = −G x, x = (q1, q2, q3, ω1, ω2, ω3), G of shape (3, 6) (N·m per unit
  of x); the PD law u = −K_p q_v − K_d ω is G = [K_p, K_d], the LQR law is G = R⁻¹BᵀP;
* optional per-axis saturation |u_i| ≤ u_max (``u_max = inf`` turns it off);
* cost rate J̇ = ½ uᵀu.

Terminal event: ‖(w_q0·(q0 − 1), w_qv·q_v, w_ω·ω)‖ − tol ≤ 0 (the first time). The
default weights (1, 1, 1) give the main set-up's ‖(q0 − 1, q_v, ω)‖; the companion study's
‖(10·q_v, ω)‖ is (0, 10, 1) (w_q0 = 0 accepts q0 = ±1).

Kernel parameter vector ``p`` (length :data:`N_PRM`): ``p[0:9]`` I row-major, ``p[9:18]``
I⁻¹ row-major, ``p[18:36]`` G row-major, ``p[36]`` u_max, ``p[37]`` tol, ``p[38:41]``
event weights (w_q0, w_qv, w_ω), ``p[41:44]`` the saturation mode of each axis, ``p[44]``
the divergence bound on ‖ω‖ (rad/s).

Divergence guard: a run whose body rates leave the ball ‖ω‖ ≤ ω_b with
ω_b = max(:data:`OMEGA_GUARD_MIN`, :data:`OMEGA_GUARD_FACTOR` · ‖ω(0)‖) (100 rad/s, or 100
times the initial rate) stops at the end of that integration step with status ``DIVERGED``
(:mod:`penaltyrun.dynamics.integrate`). Large gains (LQR with R at its lower eigenvalue
bound) can make the nonlinear loop blow up (gyroscopic term and unwinding) although its
linearization is stable; without the guard such a run spent the whole step budget while ω
grew to 1e8 rad/s. A run inside the ball is unchanged by the guard.

Stiff runs: without saturation, a run whose gain makes the loop stiff — the bound
:func:`stiffness` on the spectral radius of its linearization at the target exceeds
:data:`STIFF_RATE` — is integrated by the L-stable Rosenbrock method RODAS4
(:mod:`penaltyrun.dynamics.rosenbrock`, exact Jacobian :func:`jacobian`), whose step follows
the slow dynamics; the explicit method would need thousands of stability-limited steps
(LQR gains near the eigenvalue bounds give closed-loop poles down to ≈ −1 800 1/s). Both
methods keep the first-crossing event, the exact cutoff and the guard, and agree with
``solve_ivp`` (Radau, tight tolerances) to the integration tolerance.

Integration: Dormand–Prince 8(5,3) (:mod:`penaltyrun.dynamics.dop853`). With saturation the
torque has kinks where an axis enters or leaves the limit; the integrator locates them as
switch points and integrates each smooth piece with the axis modes frozen (−1: at −u_max,
0: linear, +1: at +u_max), so the method keeps its order across the kinks. The mode value
:data:`AUTO` (what :func:`pack_params` writes) clamps instead: the plain saturated law,
for evaluating the right-hand side outside the integrator.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from penaltyrun.dynamics.dop853 import make_dop853
from penaltyrun.dynamics.rosenbrock import make_rodas

#: Number of states (quaternion 4, rates 3, cost 1).
N_STATE = 8
#: Length of the kernel parameter vector.
N_PRM = 45
#: Mode value of an axis whose torque is clamped on every evaluation (not frozen).
AUTO = 2.0
#: Smallest divergence bound on ‖ω‖ (rad/s); see the module docstring.
OMEGA_GUARD_MIN = 100.0
#: Divergence bound as a multiple of the initial ‖ω‖.
OMEGA_GUARD_FACTOR = 100.0
#: Runs without saturation whose stiffness bound (:func:`stiffness`) exceeds this rate
#: (1/s) are integrated by RODAS4 instead of DOP853 (see the module docstring). Below about
#: 1 000 1/s the two cost about the same; every best candidate of the committed attitude
#: studies is below this rate, so their evaluations are the DOP853 ones.
STIFF_RATE = 1200.0
_I = 0
_IINV = 9
_G = 18
_UMAX = 36
_TOL = 37
_W = 38
_MODE = 41
_WB = 44


@njit(cache=True)
def _linear(y, p, i):
    """Component i of the unsaturated torque −G (q_v, ω) (N·m)."""
    acc = 0.0
    for j in range(3):
        acc += p[_G + 6 * i + j] * y[1 + j] + p[_G + 6 * i + 3 + j] * y[4 + j]
    return -acc


@njit(cache=True)
def _torque(y, p, i):
    """Component i of the torque in the axis's mode (see the module docstring) (N·m)."""
    mode = p[_MODE + i]
    if mode == 0.0:
        return _linear(y, p, i)
    if mode == 1.0:
        return p[_UMAX]
    if mode == -1.0:
        return -p[_UMAX]
    return min(max(_linear(y, p, i), -p[_UMAX]), p[_UMAX])


@njit(cache=True)
def rhs(t, y, p, out):
    """Closed-loop right-hand side dy/dt for ``y = (q, ω, J)`` (shape (8,)); no allocation."""
    u0 = _torque(y, p, 0)
    u1 = _torque(y, p, 1)
    u2 = _torque(y, p, 2)
    q0, q1, q2, q3 = y[0], y[1], y[2], y[3]
    w0, w1, w2 = y[4], y[5], y[6]
    out[0] = 0.5 * (-w0 * q1 - w1 * q2 - w2 * q3)
    out[1] = 0.5 * (w0 * q0 + w2 * q2 - w1 * q3)
    out[2] = 0.5 * (w1 * q0 - w2 * q1 + w0 * q3)
    out[3] = 0.5 * (w2 * q0 + w1 * q1 - w0 * q2)
    h0 = p[_I + 0] * w0 + p[_I + 1] * w1 + p[_I + 2] * w2
    h1 = p[_I + 3] * w0 + p[_I + 4] * w1 + p[_I + 5] * w2
    h2 = p[_I + 6] * w0 + p[_I + 7] * w1 + p[_I + 8] * w2
    m0 = u0 - (w1 * h2 - w2 * h1)
    m1 = u1 - (w2 * h0 - w0 * h2)
    m2 = u2 - (w0 * h1 - w1 * h0)
    for i in range(3):
        out[4 + i] = (p[_IINV + 3 * i] * m0 + p[_IINV + 3 * i + 1] * m1
                      + p[_IINV + 3 * i + 2] * m2)
    out[7] = 0.5 * (u0 * u0 + u1 * u1 + u2 * u2)


@njit(cache=True)
def distance(y):
    """Distance to the target ‖(q0 − 1, q1, q2, q3, ω1, ω2, ω3)‖ of a state (shape (≥7,))."""
    d = (y[0] - 1.0) ** 2
    for i in range(1, 7):
        d += y[i] * y[i]
    return np.sqrt(d)


@njit(cache=True)
def weighted_distance(y, p):
    """Event distance ‖(w_q0 (q0 − 1), w_qv q_v, w_ω ω)‖ with the weights in ``p[38:41]``."""
    d = (p[_W] * (y[0] - 1.0)) ** 2
    for i in range(1, 4):
        d += (p[_W + 1] * y[i]) ** 2
    for i in range(4, 7):
        d += (p[_W + 2] * y[i]) ** 2
    return np.sqrt(d)


@njit(cache=True)
def event(t, y, p):
    """Terminal event: weighted distance − tol (fires when ≤ 0)."""
    return weighted_distance(y, p) - p[_TOL]


@njit(cache=True)
def event_slope(v, p):
    """Bound on |d event/dt| from bounds ``v`` (≥ |dy_i/dt|): ‖W v‖ (triangle inequality)."""
    d = (p[_W] * v[0]) ** 2
    for i in range(1, 4):
        d += (p[_W + 1] * v[i]) ** 2
    for i in range(4, 7):
        d += (p[_W + 2] * v[i]) ** 2
    return np.sqrt(d)


@njit(cache=True)
def set_mode(t, y, p):
    """Store the saturation mode of every axis at state ``y`` in ``p[41:44]``."""
    for i in range(3):
        s = _linear(y, p, i)
        if s > p[_UMAX]:
            p[_MODE + i] = 1.0
        elif s < -p[_UMAX]:
            p[_MODE + i] = -1.0
        else:
            p[_MODE + i] = 0.0


@njit(cache=True)
def switch(t, y, p):
    """Distance of the unsaturated torque to the next kink, ≥ 0 inside the frozen modes
    (N·m; ``inf`` without saturation)."""
    if not np.isfinite(p[_UMAX]):
        return np.inf
    g = np.inf
    for i in range(3):
        s = _linear(y, p, i)
        mode = p[_MODE + i]
        if mode == 0.0:
            gi = p[_UMAX] - abs(s)
        elif mode == 1.0:
            gi = s - p[_UMAX]
        else:
            gi = -p[_UMAX] - s
        g = min(g, gi)
    return g


@njit(cache=True)
def switch_slope(v, p):
    """Bound on |d switch/dt|: max_i Σ_j |G_ij| v_j over (q_v, ω) (0 without saturation)."""
    if not np.isfinite(p[_UMAX]):
        return 0.0
    out = 0.0
    for i in range(3):
        acc = 0.0
        for j in range(6):
            acc += abs(p[_G + 6 * i + j]) * v[1 + j]
        out = max(out, acc)
    return out


@njit(cache=True)
def diverged(y, p):
    """Divergence guard: ‖ω‖ beyond the bound ``p[44]`` (rad/s)."""
    return y[4] * y[4] + y[5] * y[5] + y[6] * y[6] > p[_WB] * p[_WB]


@njit(cache=True)
def omega_bound(y0):
    """Divergence bound on ‖ω‖ (rad/s) of a run from (q, ω) = ``y0`` (shape (≥7,))."""
    w = np.sqrt(y0[4] * y0[4] + y0[5] * y0[5] + y0[6] * y0[6])
    return max(OMEGA_GUARD_MIN, OMEGA_GUARD_FACTOR * w)


_integrate = make_dop853(rhs, event, event_slope, switch, switch_slope, set_mode, diverged)
"""Dormand–Prince 8(5,3) bound to this closed loop (callers are cacheable)."""


@njit(cache=True)
def jacobian(t, y, p, out):
    """∂f/∂y (shape (8, 8)) of the unsaturated closed loop :func:`rhs` into ``out``."""
    out[:, :] = 0.0
    q0, q1, q2, q3 = y[0], y[1], y[2], y[3]
    w0, w1, w2 = y[4], y[5], y[6]
    # kinematics: ∂q̇/∂q = ½ Ω(ω), ∂q̇/∂ω
    out[0, 1] = -0.5 * w0
    out[0, 2] = -0.5 * w1
    out[0, 3] = -0.5 * w2
    out[1, 0] = 0.5 * w0
    out[1, 2] = 0.5 * w2
    out[1, 3] = -0.5 * w1
    out[2, 0] = 0.5 * w1
    out[2, 1] = -0.5 * w2
    out[2, 3] = 0.5 * w0
    out[3, 0] = 0.5 * w2
    out[3, 1] = 0.5 * w1
    out[3, 2] = -0.5 * w0
    out[0, 4] = -0.5 * q1
    out[0, 5] = -0.5 * q2
    out[0, 6] = -0.5 * q3
    out[1, 4] = 0.5 * q0
    out[1, 5] = -0.5 * q3
    out[1, 6] = 0.5 * q2
    out[2, 4] = 0.5 * q3
    out[2, 5] = 0.5 * q0
    out[2, 6] = -0.5 * q1
    out[3, 4] = -0.5 * q2
    out[3, 5] = 0.5 * q1
    out[3, 6] = 0.5 * q0
    # dynamics: I ω̇ = −G x − ω × (I ω), with ∂(ω × h)/∂ω = [ω]× I − [h]×; the rows of
    # I ω̇'s Jacobian are stored in out[4:7, 1:7] first, then multiplied by I⁻¹ in place
    h0 = p[_I + 0] * w0 + p[_I + 1] * w1 + p[_I + 2] * w2
    h1 = p[_I + 3] * w0 + p[_I + 4] * w1 + p[_I + 5] * w2
    h2 = p[_I + 6] * w0 + p[_I + 7] * w1 + p[_I + 8] * w2
    for j in range(3):
        c0 = p[_I + j]
        c1 = p[_I + 3 + j]
        c2 = p[_I + 6 + j]
        out[4, 4 + j] = -(w1 * c2 - w2 * c1)
        out[5, 4 + j] = -(w2 * c0 - w0 * c2)
        out[6, 4 + j] = -(w0 * c1 - w1 * c0)
    out[4, 5] -= h2
    out[4, 6] += h1
    out[5, 4] += h2
    out[5, 6] -= h0
    out[6, 4] -= h1
    out[6, 5] += h0
    for i in range(3):
        for j in range(6):
            out[4 + i, 1 + j] -= p[_G + 6 * i + j]
    for j in range(1, 7):
        m0 = out[4, j]
        m1 = out[5, j]
        m2 = out[6, j]
        for i in range(3):
            out[4 + i, j] = (p[_IINV + 3 * i] * m0 + p[_IINV + 3 * i + 1] * m1
                             + p[_IINV + 3 * i + 2] * m2)
    # cost rate ½ uᵀu: ∂/∂x = −uᵀ G
    u0 = _linear(y, p, 0)
    u1 = _linear(y, p, 1)
    u2 = _linear(y, p, 2)
    for j in range(6):
        out[7, 1 + j] = -(u0 * p[_G + j] + u1 * p[_G + 6 + j] + u2 * p[_G + 12 + j])


@njit(cache=True)
def stiffness(p):
    """Bound on the spectral radius of the loop linearized at the target (1/s).

    The row-sum norm of A − B G (x = (q_v, ω), A = [[0, ½I₃], [0, 0]], B = [[0], [I⁻¹]]):
    max(½, max_i Σ_j |(I⁻¹ G)_ij|); ``inf`` with saturation (the stiff path is off).
    """
    if np.isfinite(p[_UMAX]):
        return np.inf
    out = 0.5
    for i in range(3):
        acc = 0.0
        for j in range(6):
            acc += abs(p[_IINV + 3 * i] * p[_G + j] + p[_IINV + 3 * i + 1] * p[_G + 6 + j]
                       + p[_IINV + 3 * i + 2] * p[_G + 12 + j])
        out = max(out, acc)
    return out


_integrate_stiff = make_rodas(rhs, jacobian, event, event_slope, diverged)
"""RODAS4 bound to this closed loop, for unsaturated stiff runs (callers are cacheable)."""


@njit(cache=True)
def _run(y, p, t_max, rtol, atol, max_step, event_spacing, n_event_samples, max_steps,
         cut_value, stiff_rate):
    """One run by the integrator chosen from :func:`stiffness` (see the module docstring)."""
    cut_index = -1 if cut_value == np.inf else 7
    rho = stiffness(p)
    if np.isfinite(rho) and rho > stiff_rate:
        return _integrate_stiff(y, p, t_max, rtol, atol, max_step, event_spacing,
                                n_event_samples, max_steps, cut_index, cut_value)
    return _integrate(y, p, t_max, rtol, atol, max_step, event_spacing, n_event_samples,
                      max_steps, cut_index, cut_value)


@njit(cache=True)
def pack_params(inertia, inertia_inv, G, u_max, tol, p, w_q0=1.0, w_qv=1.0, w_w=1.0,
                w_bound=np.inf):
    """Fill the kernel parameter vector ``p`` (shape (N_PRM,)).

    Parameters
    ----------
    inertia, inertia_inv : ndarray, shape (3, 3)
        Inertia (kg·m²) and its inverse.
    G : ndarray, shape (3, 6)
        Feedback gain of u = −G (q_v, ω).
    u_max : float
        Per-axis torque limit (N·m); ``inf`` turns saturation off.
    tol : float
        Terminal-event tolerance on the weighted distance.
    p : ndarray, shape (N_PRM,)
        Output.
    w_q0, w_qv, w_w : float, optional
        Event weights on (q0 − 1), q_v and ω (default 1: the unweighted distance).
    w_bound : float, optional
        Divergence bound on ‖ω‖ (rad/s; default ``inf``: no guard; the runs of this module
        use :func:`omega_bound`).
    """
    for i in range(3):
        for j in range(3):
            p[_I + 3 * i + j] = inertia[i, j]
            p[_IINV + 3 * i + j] = inertia_inv[i, j]
        for j in range(6):
            p[_G + 6 * i + j] = G[i, j]
    p[_UMAX] = u_max
    p[_TOL] = tol
    p[_W] = w_q0
    p[_W + 1] = w_qv
    p[_W + 2] = w_w
    for i in range(3):
        p[_MODE + i] = AUTO
    p[_WB] = w_bound


@njit(cache=True)
def simulate_batch(G, y0, inertia, inertia_inv, t_max, tol, u_max, rtol, atol, max_step,
                   event_spacing, n_event_samples, max_steps, w_q0=1.0, w_qv=1.0, w_w=1.0,
                   cutoff=None, stiff_rate=STIFF_RATE):
    """Closed-loop runs for a batch of gains and/or initial states.

    Gains and initial states are paired run by run; a batch of size 1 on either side is
    broadcast (one gain over many starts, or many gains from one start).

    Parameters
    ----------
    G : ndarray, shape (B, 3, 6)
        Gains of u = −G (q_v, ω).
    y0 : ndarray, shape (S, 7)
        Initial (q, ω); quaternions are used as given (normalize beforehand).
    inertia, inertia_inv : ndarray, shape (3, 3)
        Inertia (kg·m²) and its inverse.
    t_max : float
        Horizon cap (s).
    tol : float
        Terminal-event tolerance on the weighted distance to (1, 0, 0, 0, 0, 0, 0).
    u_max : float
        Per-axis torque limit (N·m); ``inf`` turns saturation off.
    rtol, atol, max_step : float
        Integrator tolerances and largest step (s).
    event_spacing : float
        Largest time between dense-output probes of the event (and of the switch points)
        where they come close to firing (s): dips longer than this are never stepped over.
    n_event_samples : int
        At least this many probes per step in that regime.
    max_steps : int
        Step cap per run.
    w_q0, w_qv, w_w : float, optional
        Event weights (see :func:`weighted_distance`; default 1, 1, 1).
    cutoff : ndarray, shape (R,), optional
        Exact cutoff per run (N²·m²·s; ``inf``: none): a run stops with status
        ``CUTOFF`` at the end of the first accepted step where J exceeds it (see
        :mod:`penaltyrun.dynamics.integrate`); its J is then a value above the cutoff.
    stiff_rate : float, optional
        Stiffness bound (1/s) above which an unsaturated run uses RODAS4 (default
        :data:`STIFF_RATE`; ``inf``: DOP853 for every run).

    Returns
    -------
    t_end : ndarray, shape (R,)
        Event time or where integration stopped (s); R = max(B, S).
    cost : ndarray, shape (R,)
        J at ``t_end``.
    dist : ndarray, shape (R,)
        Weighted (event) distance to the target at ``t_end``.
    status : ndarray of int64, shape (R,)
        Integrator status codes (see :mod:`penaltyrun.dynamics.integrate`; ``DIVERGED``
        from the divergence guard of the module docstring).
    """
    B = G.shape[0]
    S = y0.shape[0]
    R = max(B, S)
    t_end = np.empty(R)
    cost = np.empty(R)
    dist = np.empty(R)
    status = np.empty(R, dtype=np.int64)
    p = np.empty(N_PRM)
    y = np.zeros(N_STATE)
    for r in range(R):
        b = r if B > 1 else 0
        s = r if S > 1 else 0
        for i in range(7):
            y[i] = y0[s, i]
        pack_params(inertia, inertia_inv, G[b], u_max, tol, p, w_q0, w_qv, w_w,
                    omega_bound(y))
        y[7] = 0.0
        cut = np.inf if cutoff is None else cutoff[r]
        t, yf, st, _ = _run(y, p, t_max, rtol, atol, max_step, event_spacing,
                            n_event_samples, max_steps, cut, stiff_rate)
        t_end[r] = t
        cost[r] = yf[7]
        dist[r] = weighted_distance(yf, p)
        status[r] = st
    return t_end, cost, dist, status


@njit(cache=True)
def final_state(G, y0, inertia, inertia_inv, t_max, tol, u_max, rtol, atol, max_step,
                event_spacing, n_event_samples, max_steps, w_q0=1.0, w_qv=1.0, w_w=1.0,
                stiff_rate=STIFF_RATE):
    """One closed-loop run returning the full state at its end.

    Parameters are those of :func:`simulate_batch` for one run (``G`` shape (3, 6),
    ``y0`` shape (7,)).

    Returns
    -------
    t_end : float
        Event time or where integration stopped (s).
    y_end : ndarray, shape (8,)
        (q, ω, J) at ``t_end``.
    status : int
        Integrator status code.
    """
    p = np.empty(N_PRM)
    y = np.zeros(N_STATE)
    for i in range(7):
        y[i] = y0[i]
    pack_params(inertia, inertia_inv, G, u_max, tol, p, w_q0, w_qv, w_w, omega_bound(y))
    t, yf, st, _ = _run(y, p, t_max, rtol, atol, max_step, event_spacing, n_event_samples,
                        max_steps, np.inf, stiff_rate)
    return t, yf, st
