"""Constants, kernel settings indices, status codes and history columns of the low-thrust kernels.

Units: km, s, kg, N (thrust), s (Isp); angles in rad.
"""

from __future__ import annotations

import numpy as np

MU = 398600.4418
"""Earth's gravitational parameter, km³/s²."""
G0 = 9.80665
"""Standard gravity, m/s²."""
R_E = 6378.137
"""Earth's equatorial radius, km."""

TWO_PI = 2.0 * np.pi

# Indices into the float64 parameter vector ``prm`` (length N_PRM).
I_THRUST = 0  # thrust, N
I_ISP = 1  # specific impulse, s
I_DT = 2  # control step, s
I_NSUB = 3  # RK4 substeps per control step
I_TMAX = 4  # time-of-flight cap, s
I_REVMAX = 5  # revolution cap
I_MFLOOR = 6  # mass floor, kg
I_RPMIN = 7  # Q-law minimum periapsis radius, km
I_KP = 8  # Q-law penalty sharpness k_p
I_WP = 9  # Q-law penalty weight W_p
I_MS = 10  # S_a parameter m_s
I_N = 11  # S_a parameter n
I_R = 12  # S_a parameter r
I_B = 13  # ω̇_xx blending b
I_LAW = 14  # LAW_QLAW or LAW_GENERIC
I_SIDES = 15  # 2: selector on both factors, 1: left factor only
I_COAST = 16  # COAST_NONE, COAST_ETA_A, COAST_ETA_R
I_ETACUT = 17  # effectivity threshold η_cut
I_NGRID = 18  # true-anomaly grid points for the effectivity search
I_STALLREVS = 19  # stall window, revolutions (0 disables the check)
I_STALLREL = 20  # relative decrease of min(Q) required per window
I_MAXSTEPS = 21  # evaluation cap (control steps)
I_ACAP = 22  # semi-major-axis cap for the Q-law penalty, km (0 disables)
I_EFLOOR = 23  # eccentricity floor inside the law
I_IFLOOR = 24  # inclination floor inside the law, rad
I_RIMPACT = 25  # impact radius (periapsis floor), km
I_GRAD = 26  # GRAD_ANALYTIC (production) or GRAD_COMPLEX (complex-step reference law)
I_NPREVS = 27  # no-progress window, revolutions (0 disables the rule)
I_NPFRAC = 28  # fraction by which min(Q) must fall per no-progress window
I_CUTKIND = 29  # CUT_NONE, CUT_TIME (elapsed days) or CUT_PROPELLANT (propellant used, kg)
I_CUTOFF = 30  # exact cutoff: stop once the accumulated cost exceeds this value
I_CUTCAP = 31  # cut only while the accumulated cost is ≤ this (the failure penalty's base)
N_PRM = 32

LAW_QLAW = 0
LAW_GENERIC = 1
COAST_NONE = 0
COAST_ETA_A = 1
COAST_ETA_R = 2
GRAD_ANALYTIC = 0
GRAD_COMPLEX = 1
CUT_NONE = 0
CUT_TIME = 1
CUT_PROPELLANT = 2

ST_CONVERGED = 0
ST_TOF = 1
ST_REV = 2
ST_IMPACT = 3
ST_PROPELLANT = 4
ST_STALL = 5
ST_ESCAPE = 6
ST_NO_PROGRESS = 7
ST_CUTOFF = 8
STATUS_NAMES = ("converged", "tof_cap", "rev_cap", "impact", "propellant", "stall", "escape",
                "no_progress", "cutoff")
"""Kernel status code → name."""

HIST_COLS = ("t", "a", "e", "i", "Omega", "omega", "mass", "thrust_on", "x", "y", "z", "Q")
"""Columns of the history array filled by :func:`penaltyrun.dynamics.lowthrust.propagate`."""
N_HIST = 12
