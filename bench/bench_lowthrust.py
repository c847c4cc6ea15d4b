"""Benchmark: penaltyrun's compiled Q-law against pyqlaw (or a scipy reference).

Runs the Petropoulos cases (default A and B), minimum time, K = I (standard weights), with the
thrust direction held over 80.7 s steps, in

* penaltyrun (``qlaw`` problem, compiled; timed after JIT warm-up, best of ``--repeat``);
* pyqlaw (PyPI, bench-only dependency: Keplerian Q-law, fixed-step RK4, control held per step,
  law not compiled), configured with the same constants, weights and tolerances;
* if pyqlaw cannot be imported (or with ``--reference scipy``): a scipy ``solve_ivp`` (DOP853,
  rtol 1e-11) integration of each held step, with the control from penaltyrun's law.

Prints both times of flight and the wall-time ratio reference / penaltyrun.

Usage::

    python bench/bench_lowthrust.py [--cases A B] [--reference auto|pyqlaw|scipy] [--repeat 3]
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
from penaltyrun.problems import qlaw

EYE = {"K": np.eye(5)}
#: Target wall time of one Case A minimum-time evaluation (s, one core, after warm-up).
CASE_A_TARGET_S = 0.3
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


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["A", "B"])
    ap.add_argument("--reference", choices=("auto", "pyqlaw", "scipy"), default="auto")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    reference = args.reference
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
    print(f"machine: {machine()}")
    print(f"reference: {reference}; min time, K = I, control step 80.7 s (zero-order hold)")
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
