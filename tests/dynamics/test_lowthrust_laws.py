"""The production Q-law (analytic one-pass gradient, fast effectivity search) against the
complex-step reference law, the reference kernel mode, and the no-progress stop rule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.dynamics.lowthrust import qlaw as qlaw_kernel
from penaltyrun.errors import ConfigError
from penaltyrun.problems.lowthrust import lyapunov_transfer, qlaw

CASES = qlaw.CASES


def _random_state(rng: np.random.Generator) -> np.ndarray:
    return np.array([rng.uniform(6600.0, 80000.0), rng.uniform(0.0, 0.95),
                     rng.uniform(0.0, np.pi), rng.uniform(-np.pi, np.pi),
                     rng.uniform(-np.pi, np.pi)])


def _random_spd(rng: np.random.Generator) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(5, 5)))
    return q @ np.diag(10.0 ** rng.uniform(-3.0, 2.0, 5)) @ q.T


def _assert_close(grad: np.ndarray, ref: np.ndarray, a: float) -> None:
    """Relative agreement 1e-9 per component (components below 1e-9 of the largest, in the
    scaled units a → a·∂/∂a, are compared against that largest one)."""
    scale = np.array([a, 1.0, 1.0, 1.0, 1.0])
    big = np.max(np.abs(ref * scale))
    floor = 1e-9 * big
    assert np.all(np.abs(grad - ref) * scale <= 1e-9 * np.maximum(np.abs(ref) * scale, floor))


@pytest.mark.parametrize("case", CASES)
def test_analytic_gradient_matches_complex_step_on_random_states(case: str) -> None:
    rng = np.random.default_rng(CASES.index(case))
    prob = qlaw.make_problem(case, {})
    g = np.empty(5)
    g_ref = np.empty(5)
    for sides in (2, 1):
        for a_cap in (0.0, 60000.0):
            prm = prob._prm.copy()
            prm[lt.I_SIDES] = sides
            prm[lt.I_ACAP] = a_cap
            for _ in range(60):
                oe = _random_state(rng)
                K = _random_spd(rng)
                F = rng.uniform(1e-7, 1e-5)
                q = lt.qlaw_gradient(oe, F, prob._oeT, prob._sel, K, prm, g)
                q_ref = lt.qlaw_gradient_cs(oe, F, prob._oeT, prob._sel, K, prm, g_ref)
                assert q == pytest.approx(q_ref, rel=1e-12)
                _assert_close(g, g_ref, oe[0])


def test_analytic_gradient_at_floors_and_cusps() -> None:
    """e and i at or below their floors, i at π, ω where |sin ω| or |cos ω| has its cusp."""
    prob = qlaw.make_problem("E", {})
    g = np.empty(5)
    g_ref = np.empty(5)
    rng = np.random.default_rng(5)
    for e in (0.0, 1e-5, 1e-4, 0.3, 0.95):
        for inc in (0.0, 1e-5, 0.5, np.pi - 1e-5, np.pi):
            for argp in (0.0, 0.5 * np.pi, np.pi, -0.5 * np.pi, 1.0):
                oe = np.array([30000.0, e, inc, 1.0, argp])
                K = _random_spd(rng)
                q = lt.qlaw_gradient(oe, 1e-6, prob._oeT, prob._sel, K, prob._prm, g)
                q_ref = lt.qlaw_gradient_cs(oe, 1e-6, prob._oeT, prob._sel, K, prob._prm, g_ref)
                assert np.all(np.isfinite(g))
                assert q == pytest.approx(q_ref, rel=1e-12)
                _assert_close(g, g_ref, oe[0])


def test_selector_drops_untargeted_elements() -> None:
    """Two-sided selector: K entries on untargeted elements change neither Q nor ∇Q."""
    prob = qlaw.make_problem("A", {})
    rng = np.random.default_rng(2)
    oe = _random_state(rng)
    K = _random_spd(rng)
    K2 = K.copy()
    K2[2:, :] *= 3.0
    K2[:, 2:] *= 3.0
    g, g2 = np.empty(5), np.empty(5)
    q = lt.qlaw_gradient(oe, 1e-6, prob._oeT, prob._sel, K, prob._prm, g)
    q2 = lt.qlaw_gradient(oe, 1e-6, prob._oeT, prob._sel, K2, prob._prm, g2)
    assert q == q2 and np.array_equal(g, g2)
    assert np.all(g[2:] == 0.0)


@pytest.mark.parametrize("case", CASES)
def test_effectivity_extremes_match_golden_reference(case: str) -> None:
    rng = np.random.default_rng(10 + CASES.index(case))
    prob = qlaw.make_problem(case, {})
    B = np.empty((5, 3))
    g = np.empty(5)
    for _ in range(100):
        oe = _random_state(rng)
        oe[1] = max(oe[1], 1e-4)
        oe[2] = min(max(oe[2], 1e-4), np.pi - 1e-4)
        lt.qlaw_gradient(oe, 1e-6, prob._oeT, prob._sel, _random_spd(rng), prob._prm, g)
        gmax, gmin = lt.effectivity_extremes(oe[0], oe[1], oe[2], oe[4], g, 36, B)
        rmax, rmin = lt.effectivity_extremes_golden(oe[0], oe[1], oe[2], oe[4], g, 36, B)
        assert abs(gmax - rmax) <= 1e-9 * rmax
        assert abs(gmin - rmin) <= 1e-9 * rmax


def test_effectivity_finds_shallow_extreme_between_grid_points() -> None:
    """Two shallow minima between neighbouring grid points: the search still finds the lower."""
    g = np.array([-1.0653170585779974e10, -2.7425008335764819e14, 0.0, 0.0, 0.0])
    B = np.empty((5, 3))
    a, e, inc, argp = 21425.764093765116, 0.34556046077103819, 2.1916231557485637, -0.3927082
    nus = np.linspace(0.0, 2.0 * np.pi, 200001)
    dense = np.array([np.linalg.norm(B.T @ g) for nu in nus
                      if lt.gauss_matrix(a, e, inc, argp, nu, B) is None])
    gmax, gmin = lt.effectivity_extremes(a, e, inc, argp, g, 36, B)
    assert gmax == pytest.approx(dense.max(), rel=1e-9)
    assert gmin == pytest.approx(dense.min(), rel=1e-8)


def test_reference_kernel_mode_gives_the_same_transfer() -> None:
    """prm[I_GRAD] = GRAD_COMPLEX runs the complex-step law through the same loop."""
    for objective in ("min_time", "min_fuel"):
        prob = qlaw.make_problem("C", {"objective": objective, "eta_cut": 0.3})
        fast = prob.evaluate({"K": np.eye(5)})
        prob._prm[lt.I_GRAD] = lt.GRAD_COMPLEX
        ref = prob.evaluate({"K": np.eye(5)})
        assert fast["status"] == ref["status"] == "converged"
        assert abs(fast["tof_days"] - ref["tof_days"]) <= 0.01
        assert fast["final_mass_kg"] == pytest.approx(ref["final_mass_kg"], abs=0.05)


@pytest.mark.parametrize("module", [qlaw, lyapunov_transfer])
def test_no_progress_status_and_off_switch(module) -> None:
    strict = {"no_progress_revs": 1.0, "no_progress_frac": 0.9}
    prob = module.make_problem("A", strict)
    res = prob.evaluate({"K": np.eye(5)})
    assert res["status"] == "no_progress" and not res["converged"]
    assert res["revolutions"] == pytest.approx(1.0, abs=0.1)
    assert res["cost"] > prob.params.tof_cap_days
    batch = prob.evaluate_batch({"K": np.eye(5)[None]})
    assert batch.status[0] == "no_progress"
    off = module.make_problem("A", {**strict, "no_progress_revs": 0.0})
    assert off.evaluate({"K": np.eye(5)})["status"] == "converged"


@pytest.mark.parametrize(("key", "value"), [("no_progress_revs", -1.0),
                                            ("no_progress_frac", 1.0),
                                            ("no_progress_frac", -0.1)])
def test_no_progress_config_errors(key: str, value: float) -> None:
    for module in (qlaw, lyapunov_transfer):
        with pytest.raises(ConfigError) as exc:
            module.make_problem("A", {key: value})
        assert exc.value.key == f"problem.params.{key}"


def _rounding_bounds(prob, oe, F, K) -> tuple[float, np.ndarray]:
    """Bounds on |Q − Q_cs| and |∇Q − ∇Q_cs| (complex step) from rounding alone.

    Both kernels evaluate the same closed form, each exact up to rounding (the complex step
    has no truncation error at h = 1e-30 and no subtractive cancellation in its derivative),
    so they may differ by the rounding errors of the two, which depend on the magnitudes of
    the terms summed, not on the result:

    * each scaled error nd_j is a product / quotient / root of ≤ ~30 correctly rounded
      operations (libm functions within 1 ulp) of the inputs, except 1 − e², whose relative
      error is amplified by κ_e = e² / (1 − e²): |δnd_j| ≤ (30 + κ_e) u |nd_j| per kernel;
    * Q = fac · Σ_jm nd_j M_jm nd_m: each term's relative error is at most twice that, plus
      ~27 u for the products and the sum of 25 terms, so with both kernels
      |Q − Q_cs| ≤ 2 (2 (30 + κ_e) + 27) u · fac · Σ_jm |nd_j| |M_jm| |nd_m|.
      The sum of magnitudes, not Q, sets the scale: a full K with eigenvalues over five
      decades makes Σ |terms| up to ~1e5 times Q (why a fixed rel=1e-12 failed);
    * ∇Q_k = fac · Σ_j G_j J_jk + (penalty term), G = (M + Mᵀ) nd, J_jk = ∂nd_j/∂x_k: the
      same argument with twice the operations (the derivative chain), on the magnitudes
      fac · Σ_j (Σ_m |M_jm + M_mj| |nd_m|) |J_jk| + |penalty term|;

    Underflow is outside this model: the complex step carries each derivative as an
    imaginary part h · ∂f (h = CS_STEP = 1e-30), so for an angle of, say, 1e-284 rad the
    products of h, sin ω and the small rates fall below the smallest normal number and the
    reference's ∂Q/∂ω becomes 0 (the law's is ~1e-274): a limit of the reference, not of the
    law. The property test therefore draws angles of 0 or of magnitude ≥ 1e-100.

    (Measured on 20 000 random draws of this test's ranges: at most 10 u · scale for Q and
    32 u · scale for ∇Q, against bounds of ≥ 174 u and ≥ 348 u.)
    """
    u = np.finfo(float).eps
    M = np.empty((5, 5))
    qlaw_kernel.selector_matrix(prob._sel, K, prob._prm[lt.I_SIDES] > 1.5, M)
    work = np.empty(qlaw_kernel.N_WORK)
    grad = np.empty(5)
    val = qlaw_kernel.qlaw_grad(oe, F, prob._oeT, prob._sel, M, prob._prm, work, grad)
    nd, jac = work[:5], work[5:30].reshape(5, 5)
    quad = float(nd @ M @ nd)
    fac = val / quad if quad != 0.0 else 1.0  # 1 + W_p P
    e2 = min(oe[1], 0.999) ** 2
    per_nd = 30.0 + e2 / (1.0 - e2)
    scale_q = fac * float(np.abs(nd) @ np.abs(M) @ np.abs(nd))
    chain = fac * (((np.abs(M) + np.abs(M.T)) @ np.abs(nd)) @ np.abs(jac))
    penalty = np.abs(grad - fac * (((M + M.T) @ nd) @ jac))
    ops_q = 2.0 * (2.0 * per_nd + 27.0)
    return ops_q * u * scale_q, 2.0 * ops_q * u * (chain + penalty)


def _angles(lo: float, hi: float) -> st.SearchStrategy[float]:
    """Angles in [lo, hi], 0 or of magnitude ≥ 1e-100 (see :func:`_rounding_bounds`)."""
    return st.floats(lo, hi).filter(lambda x: x == 0.0 or abs(x) >= 1e-100)


@settings(max_examples=200)
@given(a=st.floats(6600.0, 2e5), e=st.floats(0.0, 0.97), inc=_angles(0.0, np.pi),
       raan=_angles(-np.pi, np.pi), argp=_angles(-np.pi, np.pi),
       eig=st.lists(st.floats(-3.0, 2.0), min_size=5, max_size=5),
       seed=st.integers(0, 2**31), case=st.sampled_from(CASES), sides=st.sampled_from([1, 2]))
def test_gradient_property_matches_complex_step(a, e, inc, raan, argp, eig, seed, case, sides):
    prob = qlaw.make_problem(case, {"selector_sides": sides})
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(5, 5)))
    K = q @ np.diag(10.0 ** np.array(eig)) @ q.T
    oe = np.array([a, e, inc, raan, argp])
    g, g_ref = np.empty(5), np.empty(5)
    val = lt.qlaw_gradient(oe, 1e-6, prob._oeT, prob._sel, K, prob._prm, g)
    ref = lt.qlaw_gradient_cs(oe, 1e-6, prob._oeT, prob._sel, K, prob._prm, g_ref)
    tol_q, tol_g = _rounding_bounds(prob, oe, 1e-6, K)
    assert abs(val - ref) <= tol_q, (val, ref, tol_q)
    assert np.all(np.abs(g - g_ref) <= tol_g), (g, g_ref, tol_g)
