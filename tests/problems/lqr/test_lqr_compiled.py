"""The compiled Riccati candidate loop of small plants (riccati.hamiltonian_compiled,
dynamics/riccati.py and dynamics/small_linear.py) against the batched numpy path it replaces
there: the same statuses and gains to 1e-12, failures included."""

from __future__ import annotations

import numpy as np
import pytest

from penaltyrun.dynamics import riccati


def _spd(rng, count, size, floor=1e-3):
    L = rng.normal(size=(count, size, size))
    return L @ np.swapaxes(L, 1, 2) / size + floor * np.eye(size)


def _both(A, B, Q, R, monkeypatch):
    monkeypatch.setattr(riccati, "COMPILED_MAX_STATES", 8)
    compiled = riccati.lqr_gains(A, B, Q, R)
    monkeypatch.setattr(riccati, "COMPILED_MAX_STATES", 0)
    batched = riccati.lqr_gains(A, B, Q, R)
    return compiled, batched


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6, 8])
def test_gains_match_the_batched_path(n, monkeypatch):
    rng = np.random.default_rng(10 + n)
    for m in (1, 2, 3):
        A = rng.normal(size=(n, n)) / np.sqrt(n)
        B = rng.normal(size=(n, m))
        Q, R = _spd(rng, 16, n), _spd(rng, 16, m, 0.1)
        (K1, ok1, f1), (K0, ok0, f0) = _both(A, B, Q, R, monkeypatch)
        assert np.array_equal(ok1, ok0) and ok1.all()
        assert np.max(np.abs(K1 - K0)) <= 1e-12 * max(1.0, np.max(np.abs(K0)))
        assert np.array_equal(f1, f0)


def test_same_direct_solutions_and_failures(monkeypatch):
    """P and verdict of the Hamiltonian step itself agree; candidates without a
    stabilizing solution (an undamped mode left unpenalized: eigenvalues of H on the
    imaginary axis), an unstabilizable plant and a non-finite candidate fail in both."""
    rng = np.random.default_rng(3)
    A = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    B = np.array([[0.0], [1.0], [1.0]])
    Q, R = _spd(rng, 6, 3), _spd(rng, 6, 1, 0.1)
    Q[1] = 0.0
    Q[2] = np.diag([0.0, 0.0, 1.0])
    S = B @ np.linalg.inv(R) @ B.T
    P1, res1, ok1 = riccati.hamiltonian_compiled(A, S, Q)
    P0, res0, ok0 = riccati.hamiltonian_solutions(A, S, Q)
    assert ok1.tolist() == ok0.tolist() == [True, False, False, True, True, True]
    assert np.array_equal(np.isfinite(res1), np.isfinite(res0))
    np.testing.assert_allclose(P1, P0, rtol=0, atol=1e-12 * np.max(np.abs(P0)))
    (K1, okK1, f1), (K0, okK0, f0) = _both(A, B, Q, R, monkeypatch)
    assert np.array_equal(okK1, okK0)
    np.testing.assert_allclose(K1, K0, rtol=0, atol=1e-12 * np.max(np.abs(K0)))
    np.testing.assert_allclose(f1, f0, rtol=1e-6, atol=1e-12)
    A_bad = np.diag([1.0, 2.0])  # the unstable mode 2 is not reachable: unstabilizable
    B_bad = np.array([[1.0], [0.0]])
    (_, okb1, _), (_, okb0, _) = _both(A_bad, B_bad, _spd(rng, 4, 2), _spd(rng, 4, 1),
                                       monkeypatch)
    assert not okb1.any() and not okb0.any()
    Q_nan = _spd(rng, 3, 3)
    Q_nan[2, 0, 0] = np.nan
    P1, res1, ok1 = riccati.hamiltonian_compiled(A, np.broadcast_to(B @ B.T, (3, 3, 3)),
                                                 Q_nan)
    assert ok1.tolist() == [True, True, False] and res1[2] == np.inf


def test_problem_costs_and_statuses_unchanged(monkeypatch):
    """problem=lqr evaluate_batch through the compiled loop and through the numpy batch."""
    from penaltyrun import problems

    rng = np.random.default_rng(5)
    n, m = 4, 2
    A, B = rng.normal(size=(n, n)) / 2.0, rng.normal(size=(n, m))
    prob = problems.make("lqr", None, {"A": A.tolist(), "B": B.tolist(),
                                       "x0": rng.normal(size=(3, n)).tolist(),
                                       "t_max": 10.0, "settle_tol": 1e-2})
    Q, R = _spd(rng, 12, n), _spd(rng, 12, m, 0.1)
    Q[3] *= 1e-9  # weak penalties: slow loops that do not settle
    R[4] *= 1e6
    monkeypatch.setattr(riccati, "COMPILED_MAX_STATES", 8)
    new = prob.evaluate_batch({"Q": Q, "R": R})
    monkeypatch.setattr(riccati, "COMPILED_MAX_STATES", 0)
    old = prob.evaluate_batch({"Q": Q, "R": R})
    assert new.status.tolist() == old.status.tolist()
    assert len(set(old.status)) > 1
    np.testing.assert_allclose(new.cost, old.cost, rtol=1e-12, atol=0)


# ---------------------------------------------------- grading of the runs (rows' tail)


def _graded_before(prob, J, t_end, x_final, X0, codes, excess, free):
    """The grading as it was computed before, every penalty on the whole batch."""
    from penaltyrun.problems.lqr.problem import HARD_FACTOR

    ratio = np.linalg.norm(x_final, axis=2) / np.linalg.norm(X0, axis=1)
    tol = prob.params.settle_tol
    if tol is not None and not free:
        codes[(codes == "converged") & ~(ratio <= tol)] = "not_settled"
    codes[(codes == "converged") & (excess > 0)] = "constraint"
    P = prob.penalty
    with np.errstate(all="ignore"):
        cost = np.where(codes == "not_settled", J + P * (1.0 + ratio / (1.0 + ratio)), J)
        graded = np.where(np.isfinite(excess), excess / (1.0 + excess), 1.0)
        cost = np.where(codes == "constraint", J + P * (1.0 + graded), cost)
        run_t = float(prob.params.free_time_cap) if free else prob.t_max
        late = (run_t - t_end) / run_t
        cost = np.where(np.isin(codes, ("diverged", "step_failure")), J + P * (2.0 + late),
                        cost)
    finite_J = np.where(np.isfinite(J), J, 0.0)
    return np.where(np.isfinite(cost) & (codes != "nonfinite"), cost,
                    HARD_FACTOR * P + finite_J)


def _aggregate_before(res):
    from penaltyrun.problems.lqr.problem import STATUSES

    rank = np.vectorize(STATUSES.index, otypes=[int])(res["status"])
    worst = np.asarray([STATUSES[r] for r in rank.max(axis=1)], dtype=object)
    return res["cost"].mean(axis=1), worst == "converged", worst


@pytest.mark.parametrize("settle_tol", [None, 0.05])
@pytest.mark.parametrize(("simulated", "free"), [(False, False), (True, False), (True, True)])
@pytest.mark.parametrize("seed", range(4))
def test_grading_is_the_one_before(settle_tol, simulated, free, seed):
    """Graded costs and statuses bit for bit as before, on runs of every status with
    finite, infinite and NaN costs and violations; ``free`` (the time_energy criterion)
    brings its own not_settled runs and its own horizon for late failures."""
    from penaltyrun import problems
    from penaltyrun.problems.lqr.problem import STATUSES, LQRProblem

    rng = np.random.default_rng(seed)
    prob = problems.make("lqr", None, {"settle_tol": settle_tol, "t_max": 5.0})
    n_c, n_k, n = 40, 3, prob.plant.n_states
    X0 = rng.normal(size=(n_k, n))
    J = rng.exponential(size=(n_c, n_k)) * 10.0 ** rng.integers(-3, 4, (n_c, n_k))
    J[rng.random(J.shape) < 0.1] = np.inf
    J[rng.random(J.shape) < 0.05] = np.nan
    t_end = rng.uniform(0.0, prob.t_max, (n_c, n_k))
    x_final = rng.normal(size=(n_c, n_k, n)) * 10.0 ** rng.integers(-4, 1, (n_c, n_k, 1))
    excess = np.where(rng.random((n_c, n_k)) < 0.7, 0.0, rng.exponential(size=(n_c, n_k)))
    excess[rng.random(excess.shape) < 0.05] = np.inf
    pool = [s for s in STATUSES if s not in ("care_failure", "constraint")
            and (free or s != "not_settled")]
    codes = np.asarray(rng.choice(pool if simulated else ["converged"], (n_c, n_k)),
                       dtype=object)
    codes_before = codes.copy()
    cost = prob._graded(J, t_end, x_final, X0, codes, excess, free)
    before = _graded_before(prob, J, t_end, x_final, X0, codes_before, excess, free)
    assert codes.tolist() == codes_before.tolist()
    np.testing.assert_array_equal(cost, before)
    res = {"cost": cost, "status": codes}
    for new, old in zip(LQRProblem._aggregate(res), _aggregate_before(res)):
        assert new.tolist() == old.tolist()


def test_a_failing_compiled_step_falls_back_to_numpy(monkeypatch):
    """An SVD or LU that does not converge inside a compiled loop (LinAlgError) costs the
    batch the numpy path, never the evaluation."""
    from penaltyrun.dynamics import linear, small_linear

    def broken(*args):
        raise np.linalg.LinAlgError("did not converge")

    rng = np.random.default_rng(2)
    A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 2))
    Q, R = _spd(rng, 5, 3), _spd(rng, 5, 2, 0.1)
    S = B @ np.linalg.inv(R) @ B.T
    expected = riccati.hamiltonian_solutions(A, S, Q)
    monkeypatch.setattr(small_linear, "care_hamiltonian", broken)
    monkeypatch.setattr(small_linear, "quadratic_eig", broken)
    for got, want in zip(riccati.hamiltonian_compiled(A, S, Q), expected):
        np.testing.assert_array_equal(got, want)
    A_cl = -np.eye(3)[None] + 0.1 * rng.normal(size=(4, 3, 3))
    W = np.broadcast_to(np.eye(3), (4, 3, 3))
    cost, _ = linear.quadratic_cost(A_cl, W, np.eye(3), 2.0)
    monkeypatch.setattr(linear, "COMPILED_MAX_STATES", 0)
    np.testing.assert_array_equal(cost, linear.quadratic_cost(A_cl, W, np.eye(3), 2.0)[0])
