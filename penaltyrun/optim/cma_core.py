"""One CMA-ES run, vectorized over the population: the update of Hansen's tutorial, pycma's
box transformation and pycma's default stopping rules.

The update is the (μ/μ_w, λ)-CMA-ES with active covariance update of N. Hansen, "The CMA
Evolution Strategy: A Tutorial" (arXiv:1604.00772, 2016), Table 1 and eqs. (39)-(58): default
recombination weights with negative weights for the worse half (eq. 53), cumulative step-size
adaptation, rank-one and rank-μ covariance updates. The strategy parameters are the
tutorial's defaults, the same as those of the ``cmaes`` package (which the tests use as the
reference: the same normal samples give the same means, step sizes and covariances).

Bounds: the search runs in the genotype space R^dim and every candidate is mapped into the
unit cube by pycma's ``BoxConstraintsLinQuadTransformation`` (:func:`to_box`): the identity
inside [a, 1 - a] (a = 0.05), quadratic in the margins, mirrored and periodic outside, so
every candidate lies in the box and the distribution is adapted on the unbounded genotype,
as pycma's ``BoundTransform`` does (the tests compare both transformations).

Stopping rules (:meth:`CMARun.stop`): pycma's defaults, each named as pycma names it.

* ``tolfun``: the range of this generation's values and of the best values of the last
  10 + ⌈30 dim/λ⌉ generations below ``tolfun``; ``tolfunhist``: that history (more than 9
  generations) within 1e-12.
* ``tolx``: σ √C_ii and σ |p_c,i| below ``tolx`` in every coordinate; ``tolfacupx``: σ √C_ii
  above 1e3 σ0 in a coordinate (the step size diverges); ``tolupsigma``: σ / max √eig(C)
  above 1e20 σ0.
* ``tolconditioncov``: the condition number of C above 1e14.
* ``noeffectcoord`` / ``noeffectaxis``: adding 0.2 σ √C_ii to a coordinate, or 0.1 σ along
  one principal axis (axis g mod dim in generation g), leaves the mean unchanged.
* ``tolflatfitness``: the best and the 75 % value of a generation equal in two generations in
  a row.
* ``tolstagnation``: pycma's stagnation test: over the best and median values recorded every
  fifth generation, the median of the recent l records not below that of the l before
  (l = max(T/10, records/10), T = ⌊100 + 100 dim^1.5/λ⌋), after more than dim (5 + 100/λ)
  generations and more than T/2 generations since the run's best.
* ``maxiter``: 100 + 150 (dim + 3)² / √λ generations.

The covariance matrix is decomposed (``numpy.linalg.eigh``) lazily, when more than
λ / (c1 + cμ) / dim / 10 evaluations were made since the last decomposition (every generation
in small dimensions), as in pycma's and Hansen's reference codes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: Width of the quadratic margins of the unit cube (pycma: max(1, |bound|) / 20).
MARGIN = 0.05
#: Floor of an eigenvalue of C (a round-off negative eigenvalue is replaced by it).
EIG_FLOOR = 1e-8
#: pycma's default thresholds of the stopping rules named in the module docstring.
TOLFUNHIST = 1e-12
TOLFACUPX = 1e3
TOLUPSIGMA = 1e20
TOLCONDITIONCOV = 1e14
TOLFLATFITNESS = 1


@njit(cache=True)
def _to_box(X: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    a = MARGIN
    lo = -2.0 * a - 0.5
    period = 2.0 * (1.0 + 2.0 * a)
    for k in range(X.shape[0]):
        for i in range(X.shape[1]):
            y = X[k, i]
            if y < lo or y > 1.0 + 2.0 * a + 0.5:
                y -= period * math.floor((y - lo) / period)
            if y > 1.0 + a:
                y = 2.0 * (1.0 + a) - y
            if y < -a:
                y = -2.0 * a - y
            if y < a:
                y = (y + a) ** 2 / (4.0 * a)
            elif y > 1.0 - a:
                y = 1.0 - (y - 1.0 - a) ** 2 / (4.0 * a)
            out[k, i] = y


def to_box(X: np.ndarray) -> np.ndarray:
    """Map genotypes into the unit cube (pycma's linear-quadratic box transformation).

    Parameters
    ----------
    X : ndarray, shape (λ, dim)
        Genotypes, any real values.

    Returns
    -------
    ndarray, shape (λ, dim)
        Phenotypes in [0, 1]: identity on [a, 1 - a], quadratic on the margins
        ((y + a)² / (4a) below, 1 - (y - 1 - a)² / (4a) above), mirrored at -a and 1 + a,
        periodic with period 2 (1 + 2a) beyond -2a - 1/2 and 3/2 + 2a (a = :data:`MARGIN`).
    """
    X = np.ascontiguousarray(X, dtype=float)
    out = np.empty_like(X)
    _to_box(X, out)
    return out


def from_box(U: np.ndarray) -> np.ndarray:
    """Genotype of a point of the unit cube: the inverse of :func:`to_box` on [-a, 1 + a].

    Parameters
    ----------
    U : ndarray, shape (..., dim)
        Points in [0, 1] (clipped into it first).

    Returns
    -------
    ndarray, shape (..., dim)
        ``X`` with ``to_box(X) == U`` (to round-off).
    """
    a = MARGIN
    u = np.clip(np.asarray(U, dtype=float), 0.0, 1.0)
    x = np.where(u < a, -a + 2 * np.sqrt(a * u), u)
    return np.where(u > 1 - a, 1 + a - 2 * np.sqrt(a * (1 - u)), x)


@njit(cache=True)
def _update(X: np.ndarray, order: np.ndarray, mean: np.ndarray, ps: np.ndarray,
            pc: np.ndarray, C: np.ndarray, B: np.ndarray, D: np.ndarray, BD: np.ndarray,
            invsqrt: np.ndarray, w: np.ndarray, prm: np.ndarray, sigma: float, g: int,
            decompose: bool) -> float:  # pragma: no cover - compiled
    """One generation's update in place (mean, paths, C; if ``decompose`` also B, D,
    BD = B diag(D) and invsqrt = C^(-1/2) = B diag(1/D) Bᵀ, which are O(dim³) and so kept
    between decompositions); returns the new σ. ``prm``: μ, first negative weight, c_σ,
    d_σ, c_c, c1, cμ, the two path gains, E‖N(0, I)‖, Σ w."""
    lam, n = X.shape
    mu, neg0 = int(prm[0]), int(prm[1])
    cs, ds, cc, c1, cmu = prm[2], prm[3], prm[4], prm[5], prm[6]
    ps_gain, pc_gain, chin, wsum = prm[7], prm[8], prm[9], prm[10]
    Y = np.empty((lam, n))
    for k in range(lam):
        for i in range(n):
            Y[k, i] = (X[order[k], i] - mean[i]) / sigma
    yw = np.zeros(n)
    for k in range(mu):
        for i in range(n):
            yw[i] += w[k] * Y[k, i]
    z = invsqrt @ yw
    norm2 = 0.0
    for i in range(n):
        mean[i] += sigma * yw[i]
        ps[i] = (1.0 - cs) * ps[i] + ps_gain * z[i]
        norm2 += ps[i] * ps[i]
    norm_ps = math.sqrt(norm2)
    sigma = min(sigma * math.exp(cs / ds * (norm_ps / chin - 1.0)), 1e32)
    left = norm_ps / math.sqrt(1.0 - (1.0 - cs) ** (2 * (g + 1)))
    hsig = left < (1.4 + 2.0 / (n + 1)) * chin
    gain = pc_gain if hsig else 0.0
    for i in range(n):
        pc[i] = (1.0 - cc) * pc[i] + gain * yw[i]
    w_io = cmu * w
    Yc = Y[neg0:] @ invsqrt.T
    for k in range(neg0, lam):
        sq = 0.0
        for i in range(n):
            sq += Yc[k - neg0, i] ** 2
        w_io[k] *= n / (sq + 1e-8)
    decay = 1.0 - c1 - cmu * wsum
    if not hsig:
        decay += c1 * cc * (2.0 - cc)
    WY = Y.copy()
    for k in range(lam):
        for i in range(n):
            WY[k, i] *= w_io[k]
    M = WY.T @ Y
    for i in range(n):
        for j in range(n):
            C[i, j] = decay * C[i, j] + c1 * pc[i] * pc[j] + M[i, j]
    if decompose:
        S = (C + C.T) / 2.0
        D2, V = np.linalg.eigh(S)
        for i in range(n):
            if D2[i] < 0.0:
                D2[i] = EIG_FLOOR
            D[i] = math.sqrt(D2[i])
        B[:, :] = V
        C[:, :] = (V * D2) @ V.T
        BD[:, :] = V * D
        invsqrt[:, :] = (V / D) @ V.T
    return sigma


@njit(cache=True)
def _sample(Z: np.ndarray, mean: np.ndarray, sigma: float, BD: np.ndarray
            ) -> np.ndarray:  # pragma: no cover - compiled
    """Candidates m + σ B diag(D) z_k, shape (λ, dim) (``BD`` = B diag(D))."""
    X = Z @ BD.T
    for k in range(X.shape[0]):
        for i in range(X.shape[1]):
            X[k, i] = mean[i] + sigma * X[k, i]
    return X


@njit(cache=True)
def _checks(C: np.ndarray, B: np.ndarray, D: np.ndarray, mean: np.ndarray, pc: np.ndarray,
            sigma: float, sigma0: float, tolx: float, g: int
            ) -> tuple[bool, bool, bool, bool, bool, bool]:  # pragma: no cover - compiled
    """tolfacupx, tolx, tolupsigma, noeffectcoord, noeffectaxis, tolconditioncov."""
    n = mean.size
    facupx, small, coord = False, True, False
    for i in range(n):
        sd = sigma * math.sqrt(C[i, i])
        facupx = facupx or sd > sigma0 * TOLFACUPX
        small = small and sd < tolx and sigma * abs(pc[i]) < tolx
        coord = coord or mean[i] == mean[i] + 0.2 * sd
    j = g % n
    axis = True
    for i in range(n):
        axis = axis and mean[i] == mean[i] + 0.1 * sigma * D[j] * B[i, j]
    upsigma = sigma / D[n - 1] > sigma0 * TOLUPSIGMA
    condition = D[n - 1] > math.sqrt(TOLCONDITIONCOV) * D[0]
    return facupx, small, upsigma, coord, axis, condition


class CMARun:
    """One CMA-ES run in the genotype space, ask-and-tell over a whole population.

    Parameters
    ----------
    mean : ndarray, shape (dim,)
        Initial mean (genotype).
    sigma : float
        Initial step size σ0 (> 0).
    popsize : int
        Population λ (≥ 2).
    rng : numpy.random.Generator
        Source of the normal samples (the caller's per-job generator).
    tolfun, tolx : float
        Thresholds of the ``tolfun`` and ``tolx`` rules.
    """

    def __init__(self, mean: np.ndarray, sigma: float, popsize: int,
                 rng: np.random.Generator, tolfun: float = 1e-11, tolx: float = 1e-11) -> None:
        n = int(np.size(mean))
        lam = int(popsize)
        mu = lam // 2
        self.n, self.lam, self.mu, self.rng = n, lam, mu, rng
        self.tolfun, self.tolx = float(tolfun), float(tolx)
        w = math.log((lam + 1) / 2) - np.log(np.arange(1, lam + 1))
        self.mueff = w[:mu].sum() ** 2 / (w[:mu] ** 2).sum()
        mueff_minus = w[mu:].sum() ** 2 / (w[mu:] ** 2).sum()
        self.c1 = 2 / ((n + 1.3) ** 2 + self.mueff)
        self.cmu = min(1 - self.c1 - 1e-8,
                       2 * (self.mueff - 2 + 1 / self.mueff) / ((n + 2) ** 2 + self.mueff))
        alpha_minus = 1 + 2 * mueff_minus / (self.mueff + 2)
        if self.cmu > 0:  # cμ = 0 for λ ≤ 3: the other two bounds are infinite
            alpha_minus = min(alpha_minus, 1 + self.c1 / self.cmu,
                              (1 - self.c1 - self.cmu) / (n * self.cmu))
        pos, neg = w[w > 0].sum(), -w[w < 0].sum()
        self.weights = np.where(w >= 0, w / pos, alpha_minus * w / neg)
        self.weights_sum = float(self.weights.sum())
        self.neg0 = int(np.argmax(w < 0))  # the weights are negative from here on
        self.cs = (self.mueff + 2) / (n + self.mueff + 5)
        self.ds = 1 + 2 * max(0.0, math.sqrt((self.mueff - 1) / (n + 1)) - 1) + self.cs
        self.cc = (4 + self.mueff / n) / (n + 4 + 2 * self.mueff / n)
        self.ps_gain = math.sqrt(self.cs * (2 - self.cs) * self.mueff)
        self.pc_gain = math.sqrt(self.cc * (2 - self.cc) * self.mueff)
        self.chin = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n ** 2))
        self.eigen_gap = lam / (self.c1 + self.cmu) / n / 10
        self.prm = np.array([mu, self.neg0, self.cs, self.ds, self.cc, self.c1, self.cmu,
                             self.ps_gain, self.pc_gain, self.chin, self.weights_sum])
        self.mean = np.array(mean, dtype=float)
        self.sigma0 = self.sigma = float(sigma)
        self.C, self.B, self.D = np.eye(n), np.eye(n), np.ones(n)  # C = B diag(D²) Bᵀ
        self.BD, self.invsqrt = np.eye(n), np.eye(n)  # B diag(D), B diag(1/D) Bᵀ
        self.ps, self.pc = np.zeros(n), np.zeros(n)
        self.g = 0
        self.counteval = 0
        self.eigen_eval = 0
        self.fit = np.zeros(lam)
        self.best_f, self.best_eval = math.inf, 0
        self.hist: list[float] = []  # best value per generation, newest last (short)
        self.histbest: list[float] = []  # every fifth generation, newest last (long)
        self.histmedian: list[float] = []
        self.flat = 0
        self.tolstagnation = int(100 + 100 * n ** 1.5 / lam)
        self.maxiter = 100 + 150 * (n + 3) ** 2 / math.sqrt(lam)

    def ask(self) -> np.ndarray:
        """λ candidates m + σ B D z with z ~ N(0, I), shape (λ, dim) (genotypes)."""
        return _sample(self.rng.standard_normal((self.lam, self.n)), self.mean, self.sigma,
                       self.BD)

    def tell(self, X: np.ndarray, f: np.ndarray) -> None:
        """Update the distribution from the candidates ``X`` (λ, dim) and their values ``f``
        (λ,), lower is better."""
        f = np.asarray(f, dtype=float)
        order = np.argsort(f, kind="stable")
        fs = f[order]
        self.g += 1
        self.counteval += self.lam
        if fs[0] < self.best_f:
            self.best_f, self.best_eval = float(fs[0]), self.counteval
        decompose = self.counteval - self.eigen_eval > self.eigen_gap
        if decompose:
            self.eigen_eval = self.counteval
        self.sigma = _update(np.ascontiguousarray(X, dtype=float), order, self.mean, self.ps,
                             self.pc, self.C, self.B, self.D, self.BD, self.invsqrt,
                             self.weights, self.prm, self.sigma, self.g, decompose)
        self._record(fs)

    def _record(self, fs: np.ndarray) -> None:
        self.fit = fs
        self.hist.append(float(fs[0]))
        if len(self.hist) > 10 + 30 * self.n / self.lam:
            del self.hist[0]
        if self.g % 5 == 0:
            self.histbest.append(float(fs[0]))
            half = self.lam // 2
            self.histmedian.append(float(fs[half] if self.lam % 2 else
                                         (fs[half - 1] + fs[half]) / 2))
            if len(self.histbest) > 20000:
                del self.histbest[0], self.histmedian[0]
        self.flat = 0 if fs[0] < fs[int(0.75 * self.lam)] else self.flat + 1

    def stop(self) -> list[str]:
        """Names of the stopping rules met after the last :meth:`tell` (empty: go on)."""
        if self.g == 0:
            return []
        facupx, small, upsigma, coord, axis, condition = _checks(
            self.C, self.B, self.D, self.mean, self.pc, self.sigma, self.sigma0, self.tolx,
            self.g)
        hist_range = max(self.hist) - min(self.hist)
        flags = (("maxiter", self.g >= self.maxiter), ("tolfacupx", facupx),
                 ("tolx", small),
                 ("tolfun", self.fit[-1] - self.fit[0] < self.tolfun
                  and hist_range < self.tolfun),
                 ("tolfunhist", len(self.hist) > 9 and hist_range < TOLFUNHIST),
                 ("tolstagnation", self._stagnated()), ("tolupsigma", upsigma),
                 ("noeffectcoord", coord), ("noeffectaxis", axis),
                 ("tolconditioncov", condition),
                 ("tolflatfitness", self.flat > TOLFLATFITNESS))
        return [name for name, met in flags if met]

    def _stagnated(self) -> bool:
        records = len(self.histbest)
        span = max(self.tolstagnation / 10, records / 10)
        if span > self.g or records <= 100:
            return False
        span = int(span)
        if not (self.g > self.n * (5 + 100 / self.lam) and 2 * span < records
                and (self.counteval - self.best_eval) / self.lam > self.tolstagnation / 2):
            return False
        recent, before = slice(records - span, records), slice(records - 2 * span,
                                                                records - span)
        return bool(np.median(self.histmedian[recent]) >= np.median(self.histmedian[before])
                    and np.median(self.histbest[recent]) >= np.median(self.histbest[before]))
