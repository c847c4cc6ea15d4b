"""Benchmark: penaltyrun's compiled Q-law against its complex-step kernel and pyqlaw/scipy.

1. Kernel: the production law (analytic one-pass gradient, fast effectivity search) against
   the complex-step reference law run through the same loop (``prm[I_GRAD] = GRAD_COMPLEX``),
   Cases A and B minimum time and Case A minimum fuel, K = I; CPU time (time.process_time), best
   of ``--repeat``; times of flight of both and against the README table.
2. No-progress rule: random full K (the optimizer's GEAGSP box) on D, E and E*, mean CPU time
   per evaluation with the rule off and with its defaults, and the share of evaluations it
   shortened (``--np-sweep`` adds more aggressive window/fraction pairs).
3. Peer: the Petropoulos cases (default A and B), minimum time, K = I (standard weights), with
   the thrust direction held over 80.7 s steps, in

* penaltyrun (``qlaw`` problem, compiled; timed after JIT warm-up, best of ``--repeat``);
* pyqlaw (PyPI, bench-only dependency: Keplerian Q-law, fixed-step RK4, control held per step,
  law not compiled), configured with the same constants, weights and tolerances;
* if pyqlaw cannot be imported (or with ``--reference scipy``): a scipy ``solve_ivp`` (DOP853,
  rtol 1e-11) integration of each held step, with the control from penaltyrun's law.

Prints both times of flight and the wall-time ratio reference / penaltyrun.

Usage::

    python bench/bench_lowthrust.py [--cases A B] [--reference auto|pyqlaw|scipy|none]
                                    [--repeat 3] [--n-random 20] [--np-sweep]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import time

import numpy as np
from machine import machine
from scipy.integrate import solve_ivp

from penaltyrun.dynamics import lowthrust as lt
from penaltyrun.penalty import maps
from penaltyrun.problems.lowthrust import qlaw

EYE = {"K": np.eye(5)}
#: Target wall time of one Case A minimum-time evaluation (s, one core, after warm-up).
CASE_A_TARGET_S = 0.3
#: K = I minimum-time times of flight in the README table (days) before the analytic law.
README_TOF = {"A": 17.583, "B": 144.191, "C": 1.412}
PYQLAW_EXIT = {0: "not run", 1: "converged", 2: "converged (relaxed tolerance)",
               -1: "mass floor", -2: "time cap", -3: "NaN thrust angles (stopped)"}


def run_penaltyrun(case: str, repeat: int) -> tuple[float, float, dict]:
    """ToF (days), best wall time (s) after warm-up, and the result dict."""
    prob = qlaw.make_problem(case, {})
    res = prob.evaluate(EYE)
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = prob.evaluate(EYE)
        best = min(best, time.perf_counter() - t0)
    return res["tof_days"], best, res


def run_pyqlaw(case: str) -> tuple[float, float, str]:
    """ToF (days), wall time (s) and exit description of the same transfer in pyqlaw."""
    import pyqlaw

    pr = qlaw.make_problem(case, {}).params
    deg = math.pi / 180.0
    woe = [1.0 if el in pr.targeted else 0.0 for el in ("a", "e", "i", "Omega", "omega")]
    tol_ang = pr.tol_angle_deg * deg
    prob = pyqlaw.QLaw(
        mu=lt.MU, rpmin=pr.rp_min_km, k_petro=pr.k_p, m_petro=pr.m_s, n_petro=pr.n_exp,
        r_petro=pr.r_exp, b_petro=pr.b, wp=pr.W_p, elements_type="keplerian",
        integrator="rk4", verbosity=0, tol_oe=[pr.tol_a_km, pr.tol_e, tol_ang, tol_ang, tol_ang],
        oe_min=[1000.0, 1e-4, 1e-4, 1e-4, 1e-4, 1e-8],
        oe_max=[1e7, 0.95, math.pi, np.inf, np.inf, np.inf],
    )
    prob.exit_at_relaxed = 10**9
    oe0 = np.array([pr.a0_km, pr.e0, pr.i0_deg * deg, pr.Omega0_deg * deg,
                    pr.omega0_deg * deg, pr.nu0_deg * deg])
    oeT = np.array([pr.a_target_km, pr.e_target, pr.i_target_deg * deg,
                    pr.Omega_target_deg * deg, pr.omega_target_deg * deg])
    prob.set_problem(oe0, oeT, mass0=pr.m0_kg, tmax=pr.thrust_newton / 1000.0,
                     mdot=pr.thrust_newton / (lt.G0 * pr.isp_s),
                     tf_max=pr.tof_cap_days * 86400.0, t_step=pr.control_step_s,
                     mass_min=pr.mass_floor, woe=woe)
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        prob.solve()
    wall = time.perf_counter() - t0
    code = int(prob.exitcode)
    return prob.times[-1] / 86400.0, wall, f"exitcode {code}: {PYQLAW_EXIT.get(code, '?')}"


def _rhs(_t: float, y: np.ndarray, u: np.ndarray, thrust: float, mdot: float) -> np.ndarray:
    out = np.empty(7)
    lt.mee_rhs(y, u[0], u[1], u[2], thrust, mdot, out)
    return out


def run_scipy(case: str) -> tuple[float, float, str]:
    """ToF (days) and wall time (s) with solve_ivp (DOP853, rtol 1e-11) over each held step."""
    prob = qlaw.make_problem(case, {})
    pr = prob.params
    prm = qlaw.kernel_params(pr)
    oe0 = np.array([pr.a0_km, pr.e0, pr.i0_deg, pr.Omega0_deg, pr.omega0_deg, pr.nu0_deg])
    oe0[2:] *= math.pi / 180.0
    oeT = prob._oeT
    sel = prob._sel
    tol = prob._tol
    y = np.array([*lt.kep2mee(*oe0), pr.m0_kg])
    mdot = pr.thrust_newton / (lt.G0 * pr.isp_s)
    grad, B, err = np.empty(5), np.empty((5, 3)), np.empty(5)
    t = 0.0
    t0 = time.perf_counter()
    status = "tof_cap"
    while t < pr.tof_cap_days * 86400.0:
        oe6 = np.array(lt.mee2kep(*y[:6]))
        lt.element_errors(oe6, oeT, err)
        if np.all((np.abs(err) <= tol) | (sel == 0)):
            status = "converged"
            break
        F = pr.thrust_newton / (1000.0 * y[6])
        ur, ut, un, on, _, _ = lt.law_eval(oe6, F, oeT, sel, np.eye(5), prm, grad, B)
        sol = solve_ivp(_rhs, (0.0, pr.control_step_s), y, method="DOP853", rtol=1e-11,
                        atol=1e-12, args=(np.array([ur, ut, un]),
                                          pr.thrust_newton if on else 0.0, mdot))
        y = sol.y[:, -1]
        t += pr.control_step_s
    return t / 86400.0, time.perf_counter() - t0, status


def _cpu(prob: object, K: np.ndarray, repeat: int) -> tuple[float, dict]:
    """Best CPU time (s) of ``repeat`` evaluations after a warm-up, and the result."""
    res = prob.evaluate({"K": K})
    best = math.inf
    for _ in range(repeat):
        t0 = time.process_time()
        res = prob.evaluate({"K": K})
        best = min(best, time.process_time() - t0)
    return best, res


def kernel_comparison(cases: list[str], repeat: int) -> None:
    """Production law vs complex-step reference law, same loop, same run."""
    print("\n== Q-law kernel: analytic one-pass law vs complex-step reference law "
          f"(CPU s, best of {repeat}; K = I) ==")
    print(f"{'case':>5} {'objective':>22} {'ToF d new':>10} {'ToF d ref':>10} {'new s':>8} "
          f"{'ref s':>8} {'ratio':>6} {'us/step new':>12} {'ref':>6}")
    runs = [(c, {}) for c in cases] + [("A", {"objective": "min_fuel", "eta_cut": 0.5})]
    for case, over in runs:
        prob = qlaw.make_problem(case, over)
        new_s, new = _cpu(prob, np.eye(5), repeat)
        prob._prm[lt.I_GRAD] = lt.GRAD_COMPLEX
        ref_s, ref = _cpu(prob, np.eye(5), repeat)
        label = over.get("objective", "min_time") + (" eta_a 0.5" if over else "")
        print(f"{case:>5} {label:>22} {new['tof_days']:10.3f} {ref['tof_days']:10.3f} "
              f"{new_s:8.4f} {ref_s:8.4f} {ref_s / new_s:6.1f} "
              f"{1e6 * new_s / new['n_steps']:12.2f} {1e6 * ref_s / ref['n_steps']:6.2f}",
              flush=True)
        if not over and case in README_TOF:
            diff = abs(new["tof_days"] - README_TOF[case])
            print(f"      ToF vs README {README_TOF[case]} d: |diff| {diff:.4f} d "
                  f"({'within' if diff <= 0.01 else 'OUTSIDE'} 0.01 d)")
        if not over and case == "A":
            verdict = "meets" if ref_s / new_s >= 3.0 else "MISSES"
            print(f"      Case A speed-up {ref_s / new_s:.1f}x: {verdict} the 3x target")


def _random_full_k(n: int, seed: int) -> np.ndarray:
    par = maps.make("full", 5, (1e-8, 100.0))
    lo, hi = par.bounds()
    return par.decode(np.random.default_rng(seed).uniform(lo, hi, size=(n, lo.size)))


def no_progress_effect(n: int, sweep: bool) -> None:
    """Random full K on D, E, E*: the no-progress rule off, at its defaults (and a sweep)."""
    default = qlaw.Params()
    settings = [(default.no_progress_revs, default.no_progress_frac)]
    if sweep:
        settings += [(10.0, 0.1), (10.0, 0.2), (20.0, 0.2), (5.0, 0.2)]
    print(f"\n== No-progress rule: {n} random full K per case (GEAGSP box, eigenvalues "
          "[1e-8, 100]), Q-law min time ==")
    print(f"{'case':>5} {'window rev':>10} {'frac':>5} {'mean s off':>10} {'mean s on':>9} "
          f"{'shortened':>9} {'steps on/off':>12} {'prop-floor cut':>14} {'conv cut':>8}")
    empty = np.zeros((0, lt.N_HIST))
    for case in ("D", "E", "Estar"):
        prob = qlaw.make_problem(case, {})
        Ks = _random_full_k(n, 1000 + qlaw.CASES.index(case))
        prob._prm[lt.I_NPREVS] = 0.0
        prob._run(Ks[0], prob._prm, empty, 0)
        t0 = time.process_time()
        base = [prob._run(K, prob._prm, empty, 0) for K in Ks]
        off_s = (time.process_time() - t0) / n
        st0 = np.array([r[0] for r in base])
        steps0 = sum(r[4] for r in base)
        names, counts = np.unique([lt.STATUS_NAMES[c] for c in st0], return_counts=True)
        print(f"{case:>5} statuses without the rule: "
              + ", ".join(f"{k} {v}" for k, v in zip(names, counts)))
        for revs, frac in settings:
            prob._prm[lt.I_NPREVS] = revs
            prob._prm[lt.I_NPFRAC] = frac
            t0 = time.process_time()
            runs = [prob._run(K, prob._prm, empty, 0) for K in Ks]
            on_s = (time.process_time() - t0) / n
            st = np.array([r[0] for r in runs])
            cut = st == lt.ST_NO_PROGRESS
            prop = st0 == lt.ST_PROPELLANT
            conv = st0 == lt.ST_CONVERGED
            steps = sum(r[4] for r in runs)
            print(f"{case:>5} {revs:10.0f} {frac:5.2f} {off_s:10.3f} {on_s:9.3f} "
                  f"{cut.mean():9.0%} {steps / steps0:12.2f} "
                  f"{f'{np.sum(cut & prop)}/{prop.sum()}':>14} "
                  f"{f'{np.sum(cut & conv)}/{conv.sum()}':>8}", flush=True)


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["A", "B"])
    ap.add_argument("--reference", choices=("auto", "pyqlaw", "scipy", "none"), default="auto")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--n-random", type=int, default=20,
                    help="random full K per case for the no-progress section (0 skips it)")
    ap.add_argument("--np-sweep", action="store_true",
                    help="also try more aggressive no-progress windows/fractions")
    args = ap.parse_args(argv)
    print(f"machine: {machine()}")
    kernel_comparison(args.cases, args.repeat)
    if args.n_random > 0:
        no_progress_effect(args.n_random, args.np_sweep)
    reference = args.reference
    if reference == "none":
        return
    if reference in ("auto", "pyqlaw"):
        try:
            import pyqlaw  # noqa: F401
            reference = "pyqlaw"
        except ImportError as exc:
            if args.reference == "pyqlaw":
                raise
            print(f"pyqlaw is NOT installed ({exc}); `pip install pyqlaw` to compare with it. "
                  "Falling back to the scipy solve_ivp reference.")
            reference = "scipy"
    print(f"\n== Peer: {reference}; min time, K = I, control step 80.7 s (zero-order hold) ==")
    header = f"{'case':>5} {'penaltyrun ToF d':>17} {'wall s':>8} {reference + ' ToF d':>17} "
    print(header + f"{'wall s':>8} {'ratio':>8}  reference exit")
    for case in args.cases:
        tof, wall, res = run_penaltyrun(case, args.repeat)
        runner = run_pyqlaw if reference == "pyqlaw" else run_scipy
        ref_tof, ref_wall, exit_info = runner(case)
        print(f"{case:>5} {tof:17.3f} {wall:8.3f} {ref_tof:17.3f} {ref_wall:8.2f} "
              f"{ref_wall / wall:8.0f}  {exit_info}  (penaltyrun: {res['status']}, "
              f"{res['propellant_kg']:.2f} kg, {res['revolutions']:.1f} rev)", flush=True)
        if case == "A":
            verdict = "meets" if wall <= CASE_A_TARGET_S else "MISSES"
            print(f"      Case A evaluation {wall:.3f} s on one core: {verdict} the "
                  f"{CASE_A_TARGET_S} s target", flush=True)


if __name__ == "__main__":
    main()
