"""The user's plant, from the config: matrices, a file, a python-control system, or a
nonlinear vectorized model with its Jacobians at the origin.

Sources (keys of ``problem.params``), checked in this order:

* ``A`` (n × n) and ``B`` (n × m) as nested lists (a flat list of n numbers is a single
  input column);
* ``plant_file``: a ``.mat`` (MATLAB, read by :func:`scipy.io.loadmat`), ``.npz`` or
  ``.yaml`` file holding ``A`` and ``B`` (and optionally ``dt``; a YAML file may also hold
  ``constants`` for expressions in its numbers);
* ``plant: module:attribute``: a python-control ``StateSpace`` (any object with ``A``,
  ``B`` and ``dt``: 0 or ``None`` continuous, a positive number discrete) or an ``(A, B)``
  pair;
* ``dynamics: module:function``: a vectorized nonlinear model f(X, U) → Ẋ (X: (R, n),
  U: (R, m)) with the origin as equilibrium. A, B then come from one of the sources above
  when one is given, else from central differences of f at the origin (step
  :data:`FD_STEP` relative to 1; truncation error O(h²) ≈ 4e-11 times the third
  derivatives, round-off ≈ 1e-11 times the size of f).

A discrete-time plant (key ``dt``, or a discrete ``StateSpace``) is x[k+1] = A x[k] + B u[k];
its stability region is the unit disk instead of the left half-plane.
While results are read (:func:`penaltyrun.problems.trust.reading_results`), ``plant`` and
``dynamics`` are imported only from a module the user allowed
(:func:`penaltyrun.problems.trust.allow_module`): the stored names come from the data. A
``plant_file`` the data names is read only if it is a regular file, and an error reading
it never quotes what it holds (a YAML parser's message shows the offending line): the
module declares it in ``FILE_PARAMS``, and :func:`penaltyrun.problems.make` then gives a
failure without its message.

Every malformed input is a :class:`~penaltyrun.errors.ConfigError` naming its key.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from penaltyrun.errors import ConfigError
from penaltyrun.problems import trust

PREFIX = "problem.params"
#: Central-difference step of the Jacobians of ``dynamics`` at the origin.
FD_STEP = 6e-6


@dataclass(frozen=True)
class Plant:
    """A validated plant.

    Attributes
    ----------
    A : ndarray, shape (n, n)
    B : ndarray, shape (n, m)
    f : callable
        Vectorized dynamics f(X, U) → Ẋ used for the closed loop (the linear one when no
        ``dynamics`` is given).
    linear : bool
        Whether ``f`` is the linear model itself.
    source : str
        Config key the linear model came from (``A``, ``plant_file``, ``plant`` or
        ``dynamics`` for Jacobians), used in error messages.
    dt : float or None
        Sampling time of a discrete-time plant (f is then the one-step map); ``None``:
        continuous time.
    """

    A: np.ndarray
    B: np.ndarray
    f: Callable[[np.ndarray, np.ndarray], np.ndarray]
    linear: bool
    source: str
    dt: float | None = None

    @property
    def n_states(self) -> int:
        return int(self.A.shape[0])

    @property
    def n_inputs(self) -> int:
        return int(self.B.shape[1])


def _matrix(key: str, value: Any) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ConfigError(key, f"not a numeric matrix ({' '.join(str(exc).split())})") from None
    if not np.all(np.isfinite(arr)):
        raise ConfigError(key, "matrix has non-finite entries")
    return arr


def check_pair(A: Any, B: Any, key_a: str, key_b: str) -> tuple[np.ndarray, np.ndarray]:
    """Shapes of A (n × n) and B (n × m, or a flat column of n numbers)."""
    A = _matrix(key_a, A)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise ConfigError(key_a, f"A must be a square n x n matrix, got shape {A.shape}")
    B = _matrix(key_b, B)
    if B.ndim == 1:
        B = B[:, None]
    if B.ndim != 2 or B.shape[0] != A.shape[0] or B.shape[1] == 0:
        raise ConfigError(key_b, f"B must have n = {A.shape[0]} rows (one per state of A), "
                          f"got shape {B.shape}")
    return A, B


def unstable_modes(A: np.ndarray, M: np.ndarray, dt: float | None = None
                   ) -> list[tuple[complex, np.ndarray]]:
    """PBH test: the eigenvalues λ of A outside the stability region (Re λ ≥ 0, or |λ| ≥ 1
    when ``dt`` is set) with rank [A − λI, M] < n, and a unit left null vector w of that
    matrix (wᴴ (A − λI) = 0, wᴴ M = 0: the mode M cannot act on). Pass Cᵀ-style blocks
    transposed for observability (detectability of (A, C) is stabilizability of (Aᵀ, Cᵀ)).
    """
    n = A.shape[0]
    scale = max(1.0, float(np.linalg.norm(np.hstack([A, M]))))
    found = []
    for lam in np.linalg.eigvals(A):
        outside = abs(lam) > 1.0 - 1e-9 * scale if dt else lam.real > -1e-9 * scale
        if not outside:
            continue
        U, sv, _ = np.linalg.svd(np.hstack([A - lam * np.eye(n), M.astype(complex)]))
        if sv[n - 1] < 1e-9 * scale:
            found.append((complex(lam), U[:, n - 1]))
    return found


def _mode(lam: complex) -> str:
    return f"{lam.real:.4g}{lam.imag:+.4g}j"


def check_stabilizable(A: np.ndarray, B: np.ndarray, key: str, dt: float | None = None
                       ) -> None:
    """PBH test: every eigenvalue λ of A outside the stability region has
    rank [A − λI, B] = n."""
    for lam, _ in unstable_modes(A, B, dt)[:1]:
        raise ConfigError(key, f"(A, B) is not stabilizable: the mode of A at {_mode(lam)} "
                          "is not reachable through B, so no Q, R gives a stabilizing gain")


def check_detectable(A: np.ndarray, C: np.ndarray, key: str, dt: float | None = None,
                     fix: str = "add a row to q_output or a q_fixed entry on one of these "
                                "states") -> None:
    """PBH test of (A, C), C (p × n) with ker C = ker Q: every eigenvalue λ of A outside
    the stability region has rank [A − λI; C] = n; else the stabilizing Riccati solution
    does not exist for any tuned Q̃.

    Raises
    ------
    ConfigError
        Naming the undetectable mode, the states it moves and the fix.
    """
    for lam, w in unstable_modes(A.T, C.T, dt)[:1]:
        v = np.conj(w)  # A v = λ v and C v = 0
        big = np.flatnonzero(np.abs(v) > 1e-6 * np.abs(v).max())
        raise ConfigError(key, f"(A, Q^1/2) is not detectable: the mode of A at {_mode(lam)} "
                          f"(states {', '.join(str(int(i)) for i in big)}, 0-based) is not "
                          f"stable and the Riccati equation's Q = C_qᵀ Q̃ C_q + q_fixed does not "
                          f"weight it; {fix}")


def resolve(spec: Any, key: str) -> Any:
    """The object named by ``module:attribute`` (dotted attributes allowed).

    Raises
    ------
    ConfigError
        Malformed ``spec``, a module that cannot be imported, a missing attribute.
    trust.NotImportedError
        While results are read: a module the user did not allow.
    """
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        if trust.is_reading():
            raise trust.refuse(key, f"{spec!r}")
        raise ConfigError(key, f"expected 'module:attribute', got {spec!r}")
    mod_name, attr = spec.split(":")
    if trust.is_reading() and not trust.allowed(mod_name):
        raise trust.refuse(key, f"{spec!r} (allow its module with --plant-module "
                           f"{mod_name})")
    try:
        obj: Any = importlib.import_module(mod_name)
    except ImportError as exc:
        raise ConfigError(key, f"cannot import module {mod_name!r}: {exc} (is its folder on "
                          "PYTHONPATH?)") from None
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise ConfigError(key, f"module {mod_name!r} has no attribute {attr!r}")
        obj = getattr(obj, part)
    return obj


def _from_yaml(file: Path, key: str) -> dict[str, Any]:
    """A YAML plant file: ``A``, ``B``, optional ``dt`` and ``constants``; numbers may be
    expressions over the constants (:mod:`~penaltyrun.problems.lqr.expr`)."""
    from penaltyrun import yamlsafe
    from penaltyrun.problems.lqr import expr

    try:
        data = yamlsafe.load_file(file)
    except yamlsafe.YamlLimitError as exc:
        raise ConfigError(key, str(exc)) from None
    if not isinstance(data, Mapping):
        raise ConfigError(key, f"{file.name} must be a mapping with A and B")
    unknown = sorted(set(data) - {"A", "B", "dt", "constants"})
    if unknown:
        raise ConfigError(key, f"{file.name}: unknown key {unknown[0]!r} (allowed: A, B, dt, "
                          "constants)")
    names = expr.resolve_constants(data.get("constants"), f"{key}:constants")
    return {k: expr.resolve_value(v, names, f"{key}:{k}") for k, v in data.items()
            if k != "constants"}


def _from_file(path: Any, key: str) -> tuple[Any, Any, float | None]:
    file = Path(str(path)).expanduser()
    if not file.is_file():
        what = "not a regular file" if file.exists() else "no such file"
        raise ConfigError(key, f"{what}: {file} (the plant as a .mat, .npz or .yaml file)")
    data = _read_plant_file(file, key)
    dt = data.get("dt")
    if dt is not None:
        dt = float(np.asarray(dt, dtype=float).ravel()[0])
    return data["A"], data["B"], dt


#: Most bytes the arrays of one ``.npz`` or ``.mat`` plant file may take once read (checked
#: from the file's headers before its arrays are decompressed).
MAX_PLANT_BYTES = 64 << 20


def _declared_bytes(file: Path, suffix: str) -> int:
    """Bytes the arrays of a ``.npz`` (its members' uncompressed sizes) or ``.mat`` plant
    file (each variable's shape, 16 bytes an entry at most) declare, read from headers
    only; 0 for other files (a YAML file has its own limit)."""
    if suffix == ".npz":
        import zipfile

        with zipfile.ZipFile(file) as archive:
            return sum(info.file_size for info in archive.infolist())
    if suffix == ".mat":
        from scipy.io import whosmat

        return sum(16 * int(np.prod(shape, dtype=np.int64)) for _, shape, _ in whosmat(file))
    return 0


def _read_plant_file(file: Path, key: str) -> Mapping[str, Any]:
    """The variables of a regular plant file, at least ``A`` and ``B``.

    Raises
    ------
    ConfigError
        An unsupported type, a damaged file (the reader's message, which may quote the
        file), a file without ``A`` or ``B``.
    """
    suffix = file.suffix.lower()
    try:
        declared = _declared_bytes(file, suffix)
        if declared > MAX_PLANT_BYTES:
            raise ConfigError(key, f"{file.name} holds arrays of {declared} bytes once read "
                              f"(the limit for a plant file is {MAX_PLANT_BYTES} bytes)")
        if suffix == ".mat":
            from scipy.io import loadmat

            data: Mapping[str, Any] = loadmat(file)
        elif suffix == ".npz":
            data = dict(np.load(file, allow_pickle=False))
        elif suffix in (".yaml", ".yml"):
            data = _from_yaml(file, key)
        else:
            raise ConfigError(key, f"unsupported file type {suffix!r} (use .mat, .npz or "
                              ".yaml)")
    except ConfigError:
        raise
    except Exception as exc:  # a damaged file: scipy / numpy / yaml raise many kinds
        raise ConfigError(key, f"cannot read {file}: {' '.join(str(exc).split())}") from None
    for name in ("A", "B"):
        if name not in data:
            raise ConfigError(key, f"{file.name} has no variable {name!r} (need A and B)")
    return data


def _from_object(spec: Any, key: str) -> tuple[Any, Any, float | None]:
    obj = resolve(spec, key)
    if hasattr(obj, "A") and hasattr(obj, "B"):
        dt = getattr(obj, "dt", 0)
        if dt is True or (dt is not None and not isinstance(dt, (int, float))):
            raise ConfigError(key, f"{spec} is a discrete-time system with an unspecified "
                              f"sampling time (dt = {dt!r}); give its dt")
        return obj.A, obj.B, (float(dt) if dt else None)
    if isinstance(obj, (tuple, list)) and len(obj) == 2:
        return obj[0], obj[1], None
    raise ConfigError(key, f"{spec} is a {type(obj).__name__}, not a StateSpace or an "
                      "(A, B) pair")


def jacobians(f: Callable[[np.ndarray, np.ndarray], np.ndarray], n: int, m: int
              ) -> tuple[np.ndarray, np.ndarray]:
    """A = ∂f/∂x and B = ∂f/∂u at the origin by central differences (step :data:`FD_STEP`)."""
    h = FD_STEP
    E = np.eye(n + m)
    Z = np.vstack([h * E, -h * E])
    F = np.asarray(f(Z[:, :n], Z[:, n:]), dtype=float)
    J = (F[: n + m] - F[n + m:]).T / (2.0 * h)
    return J[:, :n], J[:, n:]


def _check_dynamics(f: Any, n: int | None, m: int | None, key: str) -> tuple[int, int]:
    if not callable(f):
        raise ConfigError(key, f"{type(f).__name__} is not callable; need f(X, U)")
    if n is None or m is None:
        raise ConfigError(key, "the sizes n, m are unknown: give A and B (or plant / "
                          "plant_file) with dynamics, or the state size through x0 and the "
                          "input size through input_weight")
    try:
        out = np.asarray(f(np.zeros((2, n)), np.zeros((2, m))), dtype=float)
    except Exception as exc:  # the user's function: any error is a config error
        raise ConfigError(key, f"f(X, U) failed on X = 0 ({n} states), U = 0 ({m} inputs): "
                          f"{type(exc).__name__}: {' '.join(str(exc).split())}") from None
    if out.shape != (2, n):
        raise ConfigError(key, f"f(X, U) must return shape (R, {n}) for X (R, {n}), "
                          f"U (R, {m}); got {out.shape} for R = 2")
    if not np.all(np.isfinite(out)) or np.max(np.abs(out)) > 1e-9:
        raise ConfigError(key, f"f(0, 0) = {out[0].tolist()}: the origin must be an "
                          "equilibrium (shift the state so that it is)")
    return n, m


def load(params: Mapping[str, Any], n_hint: int | None = None, m_hint: int | None = None
         ) -> Plant:
    """Build the plant from ``problem.params`` keys (see the module docstring).

    Parameters
    ----------
    params : mapping
        ``A``, ``B``, ``plant_file``, ``plant``, ``dynamics`` (absent or None when unused).
    n_hint, m_hint : int, optional
        State and input sizes from other keys (``x0``, ``input_weight``), needed only for a
        ``dynamics`` without any linear model.

    Raises
    ------
    ConfigError
        Naming the key: conflicting or missing sources, bad shapes, unreadable files,
        missing module attributes, a non-stabilizable (A, B), a bad ``dynamics``, a
        ``dt`` that contradicts the ``plant`` object's or comes with ``dynamics``.
    """
    dt = params.get("dt")
    given = [k for k in ("A", "plant_file", "plant") if params.get(k) is not None]
    if params.get("B") is not None and "A" not in given:
        raise ConfigError(f"{PREFIX}.A", "B is given without A")
    if len(given) > 1:
        raise ConfigError(f"{PREFIX}.{given[1]}", f"give one plant source, not both "
                          f"{given[0]} and {given[1]}")
    source = given[0] if given else "dynamics"
    key = f"{PREFIX}.{source}"
    if source == "A":
        if params.get("B") is None:
            raise ConfigError(f"{PREFIX}.B", "missing: A is given, B (n x m) is needed too")
        A, B = check_pair(params["A"], params["B"], f"{PREFIX}.A", f"{PREFIX}.B")
    elif source in ("plant_file", "plant"):
        a, b, obj_dt = (_from_file if source == "plant_file" else _from_object)(
            params[source], key)
        A, B = check_pair(a, b, key, key)
        if obj_dt is not None and dt is not None and not np.isclose(obj_dt, dt, rtol=1e-12):
            raise ConfigError(f"{PREFIX}.dt", f"dt = {dt} but {params[source]} has dt = "
                              f"{obj_dt}; drop dt (the system's is used) or make them agree")
        if obj_dt is not None and not (np.isfinite(obj_dt) and obj_dt > 0):
            raise ConfigError(key, f"its sample time dt = {obj_dt} is not a positive number "
                                   "(a continuous-time plant has none)")
        dt = obj_dt if dt is None else dt
    elif params.get("dynamics") is None:
        raise ConfigError(f"{PREFIX}.A", "no plant: give A and B, plant_file, plant or "
                          "dynamics")
    dyn_key = f"{PREFIX}.dynamics"
    if params.get("dynamics") is None:
        check_stabilizable(A, B, f"{PREFIX}.B" if source == "A" else key, dt)

        def f_lin(X: np.ndarray, U: np.ndarray) -> np.ndarray:
            return X @ A.T + U @ B.T

        return Plant(A, B, f_lin, True, source, None if dt is None else float(dt))
    if dt is not None:
        raise ConfigError(f"{PREFIX}.dt", "a discrete-time plant must be linear: give A and B "
                          "(or plant / plant_file) without dynamics, or drop dt")
    f = resolve(params["dynamics"], dyn_key)
    if source == "dynamics":
        _check_dynamics(f, n_hint, m_hint, dyn_key)
        A, B = jacobians(f, int(n_hint), int(m_hint))  # type: ignore[arg-type]
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(B))):
            raise ConfigError(dyn_key, "the Jacobians of f at the origin are not finite")
        check_stabilizable(A, B, dyn_key)
    else:
        _check_dynamics(f, A.shape[0], B.shape[1], dyn_key)
        check_stabilizable(A, B, f"{PREFIX}.B" if source == "A" else key)
    return Plant(A, B, f, False, source)


__all__ = ["FD_STEP", "PREFIX", "Plant", "check_detectable", "check_pair",
           "check_stabilizable", "jacobians", "load", "resolve", "unstable_modes"]
