"""Exact gradient of the rendezvous MPC cost where the QP's active set is fixed: against
complex-step derivatives of an independent complex-analytic closed loop (own prediction
matrices, DARE by Hewer iterations with Kronecker solves, KKT solves on the active sets the
solver found), against central differences of the problem's own cost (Q directions, and z
through the maps), on runs that arrive and on runs that do not (graded penalty), and the
points where no gradient exists (an active-set switch, an arrival about to change, the
Keplerian plant), reported with a reason, never as a number."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from penaltyrun.optim.gradient import z_gradient
from penaltyrun.problems import criteria
from penaltyrun.problems.mpc import criteria as mpc_criteria
from penaltyrun.problems.mpc import rendezvous as rv
from penaltyrun.runner.setup import build_layout

H_CS = 1e-30
Q0 = np.diag([1.0, 1.0, 1.0, 100.0, 100.0, 100.0])
R0 = 1e4 * np.eye(3)


def _weights(seed):
    rng = np.random.default_rng(seed)
    M = rng.normal(size=(6, 6))
    N = rng.normal(size=(3, 3))
    return Q0 + 0.05 * M @ M.T, R0 + 500.0 * N @ N.T


def _sym_dir(rng, n):
    E = rng.normal(size=(n, n))
    return E + E.T


def _active_sets(prob, Q, R):
    """Recorded states, inputs and (free mask, signs) of each step's QP at real (Q, R)."""
    from penaltyrun.problems.mpc.gradient import _qp_solutions

    H, F, _, ok = prob.controllers(Q[None], R[None])
    assert ok[0]
    res = prob.run(H[0], F[0], record=True)
    steps = res.inputs.shape[0]
    X = _qp_solutions(prob, H[0], F[0], res.states[:steps])
    return res, [(np.abs(x) < 1 - 1e-7, np.sign(x)) for x in X]


def _reference_cost(prob, Q, R, sets, steps, arrived=True):
    """Closed-loop cost with the per-step active sets fixed (complex-analytic); a run that
    does not arrive adds the graded penalty."""
    p = prob.params
    ds, du = prob.state_weight_scale, prob.input_weight_scale
    Qp = Q * ds[:, None] * ds[None, :]
    Rp = R * du[:, None] * du[None, :]
    A, B = prob.Ad, prob.Bd
    P = solve_discrete_are(A, B, Qp.real, Rp.real).astype(complex)
    for _ in range(6):  # Hewer: P of the gain of P, to round-off (complex-analytic)
        K = np.linalg.solve(Rp + B.T @ P @ B, B.T @ P @ A)
        Acl = A - B @ K
        rhs = (Qp + K.T @ Rp @ K).reshape(-1)
        P = np.linalg.solve(np.eye(36) - np.kron(Acl.T, Acl.T), rhs).reshape(6, 6)
    N = int(p.horizon)
    Phi = [np.eye(6)]
    Gam = [np.zeros((6, 3 * N))]
    for i in range(N):
        Phi.append(A @ Phi[-1])
        G = A @ Gam[-1]
        G[:, 3 * i:3 * i + 3] = B
        Gam.append(G)
    H = sum(Gam[i].T @ Qp @ Gam[i] for i in range(1, N)) + Gam[N].T @ P @ Gam[N]
    F = sum(Gam[i].T @ Qp @ Phi[i] for i in range(1, N)) + Gam[N].T @ P @ Phi[N]
    H = H + np.kron(np.eye(N), Rp)
    d = np.tile(prob.u_max, N)
    H = d[:, None] * H * d[None, :]
    F = d[:, None] * F
    s = np.asarray(p.s0, dtype=complex)
    dt = float(p.sample_time_s)
    total = 0.0
    for k in range(steps):
        free, sign = sets[k]
        x = sign.astype(complex)
        if np.any(free):
            x[free] = -np.linalg.solve(H[np.ix_(free, free)],
                                       H[np.ix_(free, ~free)] @ x[~free] + F[free] @ s)
        u = prob.u_max * x[:3]
        uu = u @ u
        total = total + (dt * np.sqrt(uu) if p.criterion == criteria.DEADLINE
                         else 0.5 * dt * uu)
        s = A @ s + B @ u
    if p.criterion == criteria.TERMINAL:
        total = total + s @ mpc_criteria.terminal_weight(p) @ s
    if p.criterion == criteria.TIME_ENERGY:
        total = total + p.rho * steps * dt
    if not arrived and p.criterion != criteria.TERMINAL:
        a = np.sqrt(s[:3] @ s[:3]) / p.pos_tol_m
        b = np.sqrt(s[3:] @ s[3:]) / p.vel_tol_m_s
        e = a if a.real > b.real else b
        total = total + p.failure_penalty * (1.0 + e / max(prob.error(p.s0), 1.0))
    return total


@pytest.mark.parametrize(("crit", "extra"), [
    ("deadline", {}), ("terminal", {}), ("time_energy", {}),
    ("deadline", {"t_max": 400.0}),                              # no arrival: penalty
    ("time_energy", {"free_time_cap": 400.0})])
@pytest.mark.parametrize("seed", [0, 1])
def test_gradient_matches_complex_step_of_an_independent_closed_loop(crit, extra, seed):
    prob = rv.make_problem("default", {"criterion": crit, **extra})
    Q, R = _weights(seed)
    out = prob.gradient({"Q": Q, "R": R})
    assert out.exists, out.reason
    assert out.status == ("horizon" if extra else "converged")
    assert out.cost == prob.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]
    res, sets = _active_sets(prob, Q, R)
    steps = res.inputs.shape[0]
    arrived = not extra
    assert any(not np.all(f) for f, _ in sets)  # the input bounds are active somewhere
    assert _reference_cost(prob, Q.astype(complex), R.astype(complex), sets, steps,
                           arrived).real == pytest.approx(out.cost, rel=1e-9)
    rng = np.random.default_rng(seed + 10)
    for name, n in (("Q", 6), ("R", 3)):
        for _ in range(2):
            E = _sym_dir(rng, n)
            Qc = Q + 1j * H_CS * E if name == "Q" else Q.astype(complex)
            Rc = R + 1j * H_CS * E if name == "R" else R.astype(complex)
            cs = _reference_cost(prob, Qc, Rc, sets, steps, arrived).imag / H_CS
            ours = float(np.sum(out.matrices[name] * E))
            assert ours == pytest.approx(cs, rel=1e-7, abs=1e-12 * abs(out.cost)), name


def _cd(f, h):
    return (4.0 * (f(h / 2) - f(-h / 2)) / h - (f(h) - f(-h)) / (2 * h)) / 3.0


def test_gradient_matches_central_differences_of_the_problems_cost():
    prob = rv.make_problem("default", {"criterion": "terminal"})
    Q, R = _weights(0)
    out = prob.gradient({"Q": Q, "R": R})
    rng = np.random.default_rng(3)
    for _ in range(3):
        E = _sym_dir(rng, 6)

        def f(s, E=E):
            return prob.evaluate_batch({"Q": (Q + s * E)[None], "R": R[None]}).cost[0]

        assert float(np.sum(out.matrices["Q"] * E)) == pytest.approx(_cd(f, 1e-4), rel=1e-6)


@pytest.mark.parametrize("param", ["diagonal", "givens", "cayley", "full"])
def test_z_gradient_matches_central_differences_through_the_maps(param):
    """The scaled case (weights of order one): d cost / d z through each map against
    central differences of the problem's cost, where the active sets stay fixed."""
    prob = rv.make_problem("scaled", {"criterion": "terminal"})
    layout = build_layout(prob, param, {})
    lb, ub = layout.bounds()
    rng = np.random.default_rng(7)
    z = lb + (ub - lb) * rng.uniform(0.3, 0.6, lb.size)
    out = z_gradient(prob, layout, z)
    assert out.exists, out.reason
    for i in rng.choice(z.size, size=min(z.size, 6), replace=False):
        def f(s, i=i):
            zz = z.copy()
            zz[i] += s
            return prob.evaluate_batch(layout.split(zz[None])[0]).cost[0]

        h = 1e-5 * max(1.0, abs(z[i]))
        assert out.grad[i] == pytest.approx(_cd(f, h), rel=1e-5, abs=1e-7 * out.cost), \
            layout.names()[i]


def _pattern(prob, Q, R):
    """The active set of every step's QP (entries on a bound to 1e-9, with their sides)."""
    from penaltyrun.problems.mpc.gradient import _qp_solutions

    H, F, _, _ = prob.controllers(Q[None], R[None])
    res = prob.run(H[0], F[0], record=True)
    X = _qp_solutions(prob, H[0], F[0], res.states[:res.inputs.shape[0]])
    return tuple(np.packbits(np.abs(x) >= 1 - 1e-9).tobytes()
                 + np.packbits(x >= 1 - 1e-9).tobytes() for x in X)


def test_at_an_active_set_switch_no_gradient_and_a_kink_beside_it():
    """Along Q + c·E an input reaches its bound at some step between c = 150 and 200:
    bisected to that switch, the gradient is None with the reason; on either side it
    exists, matches one-sided differences, and the two sides differ (a kink)."""
    prob = rv.make_problem("default", {"criterion": "terminal"})
    Q, R = _weights(0)
    E = np.diag([0.0, 0.0, 0.0, 1.0, 1.0, 1.0])
    lo, hi = 150.0, 200.0
    p_lo = _pattern(prob, Q + lo * E, R)
    assert p_lo != _pattern(prob, Q + hi * E, R)
    while hi - lo > 1e-9 * hi:
        mid = 0.5 * (lo + hi)
        if _pattern(prob, Q + mid * E, R) == p_lo:
            lo = mid
        else:
            hi = mid
    for c in (lo, hi):
        at = prob.gradient({"Q": Q + c * E, "R": R})
        assert not at.exists and "switching" in at.reason

    def f(c):
        return prob.evaluate_batch({"Q": (Q + c * E)[None], "R": R[None]}).cost[0]

    sides = []
    for c, step in ((lo - 0.5, -0.05), (hi + 0.5, 0.05)):
        out = prob.gradient({"Q": Q + c * E, "R": R})
        assert out.exists, out.reason
        sides.append(float(np.sum(out.matrices["Q"] * E)))
        one_sided = (f(c + step) - f(c)) / step  # away from the switch
        assert sides[-1] == pytest.approx(one_sided, rel=1e-3)
    assert abs(sides[0] - sides[1]) > 1e-2 * abs(sides[0])


def test_no_gradient_on_the_keplerian_plant():
    Q, R = _weights(0)
    kep = rv.make_problem("default", {"plant": "keplerian"})
    out = kep.gradient({"Q": Q, "R": R})
    assert not out.exists and "Keplerian" in out.reason
    assert out.cost == kep.evaluate_batch({"Q": Q[None], "R": R[None]}).cost[0]


def test_no_gradient_next_to_an_arrival_change():
    """The convergence radius set to the final state's own error: the convergence test
    sits on its boundary at the arrival step, which is about to change: no gradient."""
    prob = rv.make_problem("default", {})
    Q, R = _weights(0)
    res, _ = _active_sets(prob, Q, R)
    s_end = res.states[-1]
    pos = float(np.linalg.norm(s_end[:3]))
    vel = float(np.linalg.norm(s_end[3:]))
    p = prob.params
    edge = {"pos_tol_m": pos} if pos / p.pos_tol_m >= vel / p.vel_tol_m_s \
        else {"vel_tol_m_s": vel}
    out = rv.make_problem("default", edge).gradient({"Q": Q, "R": R})
    assert not out.exists and "arrival step" in out.reason
