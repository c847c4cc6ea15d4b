"""The source of user code (and of data files a problem reads) as part of a job's identity.

A problem module of the user's own (and a module a problem parameter names: the
parameters its module declares in ``CODE_PARAMS``, e.g. the LQR problem's ``plant`` and
``dynamics``; the files of those in ``FILE_PARAMS``, see
:func:`penaltyrun.problems.user_code_params`) is hashed with the local modules it imports: the
files its ``import`` statements reach inside the folder it was found in (its ``sys.path``
entry), followed transitively. Installed packages, the standard library and penaltyrun
itself are not hashed (their versions are recorded with every result). The imports are
read from the source (``ast``), not from what happens to be imported in the process, so
the hash depends on the files alone.

An in-memory problem (``object:<name>``, e.g. from :func:`penaltyrun.from_cost`) has no
file: its code is hashed instead (:func:`object_code_hash`), so that two cost functions
under one problem name are two configurations and an edited cost is never resumed from
the records of the old one.
"""

from __future__ import annotations

import ast
import hashlib
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from penaltyrun.runner.plan import config_hash

#: Most local files followed from one module (a bound on the work for a huge folder).
MAX_LOCAL_FILES = 500


def module_source_hash(module: str | None) -> str:
    """Short SHA-256 of the source of the user module ``module`` (dotted name) and of the
    local modules it imports (:func:`local_sources`); "" for none, an in-memory problem
    (``object:<name>``), a module of penaltyrun itself or a module without a source file.

    A module that imports no local module hashes as its own file alone. Finding the file
    imports the module's parent packages, as running the problem does.
    """
    if not module or ":" in module or module.split(".")[0] == "penaltyrun":
        return ""
    import importlib.util

    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError):  # the run reports an unimportable module itself
        return ""
    origin = getattr(spec, "origin", None) if spec is not None else None
    if not origin or not getattr(spec, "has_location", False):
        return ""
    origin_path = Path(origin)
    try:
        digest = hashlib.sha256(origin_path.read_bytes())
        root = source_root(module, origin_path)
        for path in local_sources(module, origin_path):
            digest.update(b"\0" + path.relative_to(root).as_posix().encode() + b"\0")
            digest.update(path.read_bytes())
    except (OSError, ValueError):
        return ""
    return digest.hexdigest()[:16]


def user_code_hash(problem_module: str | None, problem_params: Mapping[str, Any],
                   code_params: Sequence[str] = (), file_params: Sequence[str] = ()) -> str:
    """:func:`module_source_hash` of the problem module and of the modules that the
    ``code_params`` name (``module:attribute``) and the contents of the files that the
    ``file_params`` name, combined; "" when there is none (a missing file counts as
    none: the run itself says it is missing).

    Parameters
    ----------
    problem_module : str or None
        Dotted path of the problem module (None: a problem of penaltyrun or an entry point).
    problem_params : mapping
        The cell's problem parameters.
    code_params, file_params : sequence of str
        What the problem module declares (``CODE_PARAMS``, ``FILE_PARAMS``;
        :func:`penaltyrun.problems.user_code_params`).
    """
    modules, files = _user_code(problem_module, problem_params, code_params, file_params)
    hashes = [h for _, name in modules if (h := module_source_hash(name))]
    from penaltyrun.problems import OBJECT_PREFIX, held_object

    if problem_module and problem_module.startswith(OBJECT_PREFIX):
        hashes.append(object_code_hash(held_object(problem_module)))
    hashes += [h for _, path in files if (h := file_hash(path))]
    if len(hashes) <= 1:
        return hashes[0] if hashes else ""
    return config_hash(hashes)


def describe_user_code(problem_module: str | None, problem_params: Mapping[str, Any],
                       code_params: Sequence[str] = (), file_params: Sequence[str] = ()) -> str:
    """What :func:`user_code_hash` covers (same arguments), for a message: e.g. "the
    problem module lab.fit or a local module it imports; the plant_file plant.yaml"."""
    modules, files = _user_code(problem_module, problem_params, code_params, file_params)
    parts = [f"the {kind} module {name} or a local module it imports" for kind, name in modules]
    parts += [f"the {key} {path}" for key, path in files]
    return "; ".join(parts) or "the problem's code"


def _user_code(problem_module: str | None, problem_params: Mapping[str, Any],
               code_params: Sequence[str], file_params: Sequence[str]
               ) -> tuple[list[tuple[str, str]], list[tuple[str, str]]]:
    """(modules, files) of user code a cell names, each as (what names it, name or path):
    ``problem`` for the problem module, a ``code_params`` key for the module of its
    ``module:attribute`` value, a ``file_params`` key for its file."""
    modules = [("problem", problem_module)] if problem_module else []
    modules += [(key, value.partition(":")[0]) for key in code_params
                if isinstance(value := problem_params.get(key), str) and ":" in value]
    files = [(key, value) for key in file_params
             if isinstance(value := problem_params.get(key), str)]
    return modules, files


def object_code_hash(problem: Any) -> str:
    """Short SHA-256 of what defines the in-memory problem ``problem``: its public
    attributes (of a :func:`~penaltyrun.from_cost` problem its cost and gradient functions
    and its matrix specifications) and, for a class of the user's own, the class's
    methods. A function
    counts by its compiled code (bytecode, constants, names, nested functions), default
    arguments and the values it closes over (:func:`_callable_digest`); any other value
    by its contents (an array's bytes, else its ``repr``).

    Values a function reads from global variables at call time are not part of it: a cost
    that depends on a module-level variable changed between runs looks the same.
    """
    digest = hashlib.sha256(type(problem).__qualname__.encode())
    for name, value in sorted(getattr(problem, "__dict__", {}).items()):
        if name.startswith("_"):  # the object's own bookkeeping, not what it computes
            continue
        digest.update(name.encode())
        if callable(value) and not isinstance(value, type):
            _callable_digest(value, digest, depth=0)
        else:
            _value_digest(value, digest)
    if not type(problem).__module__.startswith("penaltyrun"):
        for name, value in vars(type(problem)).items():
            if callable(value):
                digest.update(name.encode())
                _callable_digest(value, digest, depth=0)
    return digest.hexdigest()[:16]


def _callable_digest(function: Any, digest: Any, depth: int) -> None:
    """Feed ``digest`` with what defines ``function`` (see :func:`object_code_hash`)."""
    import functools
    import types

    if depth > 8:
        return
    if isinstance(function, functools.partial):
        _callable_digest(function.func, digest, depth + 1)
        _value_digest((function.args, function.keywords), digest)
        return
    if isinstance(function, types.MethodType):
        function = function.__func__
    code = getattr(function, "__code__", None)
    if code is None:  # a builtin, a numba dispatcher, an object with __call__
        inner = getattr(function, "py_func", None)  # a numba dispatcher's Python function
        if inner is None:
            method = type(function).__call__  # an object's own __call__ (Python code)
            inner = method if hasattr(method, "__code__") else None
        if inner is not None:
            _callable_digest(inner, digest, depth + 1)
        else:
            digest.update(repr(getattr(function, "__qualname__", function)).encode())
        return
    _code_digest(code, digest)
    _value_digest(getattr(function, "__defaults__", None), digest)
    _value_digest(getattr(function, "__kwdefaults__", None), digest)
    for cell in getattr(function, "__closure__", None) or ():
        try:
            value = cell.cell_contents
        except ValueError:  # an empty cell
            continue
        if callable(value) and not isinstance(value, type):
            _callable_digest(value, digest, depth + 1)
        else:
            _value_digest(value, digest)


def _code_digest(code: Any, digest: Any) -> None:
    digest.update(code.co_code)
    digest.update(repr((code.co_names, code.co_varnames)).encode())
    for const in code.co_consts:
        if hasattr(const, "co_code"):
            _code_digest(const, digest)
        else:
            _value_digest(const, digest)


def _value_digest(value: Any, digest: Any) -> None:
    """Feed ``digest`` with ``value``: an array by its dtype, shape and bytes, anything else
    by its ``repr``."""
    import numpy as np

    if isinstance(value, np.ndarray):
        digest.update(repr((value.dtype.str, value.shape)).encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    else:
        text = repr(value)  # an object's default repr holds its address: its type instead
        digest.update((type(value).__qualname__ if " at 0x" in text else text).encode())


def file_hash(path: str) -> str:
    """Short SHA-256 of the bytes of the file ``path`` (``~`` expanded, as the problem reads
    it); "" when it is not a regular file (a FIFO or a device is never read) or cannot be
    read."""
    file = Path(path).expanduser()
    try:
        if not file.is_file():
            return ""
        return hashlib.sha256(file.read_bytes()).hexdigest()[:16]
    except (OSError, ValueError):
        return ""


def source_root(module: str, origin: Path) -> Path:
    """The folder ``module`` was found in (its ``sys.path`` entry): ``origin``'s folder,
    one level up per dot of the name and one more for a package's ``__init__.py``."""
    root = origin.parent
    for _ in range(module.count(".") + (origin.name == "__init__.py")):
        root = root.parent
    return root


def local_sources(module: str, origin: Path) -> list[Path]:
    """Source files of the local modules that ``module`` (file ``origin``) imports,
    transitively, sorted, ``origin`` itself excluded.

    Local: the ``__init__.py`` of ``module``'s parent packages (they run whenever it is
    imported), and what is found under :func:`source_root` by an import's dotted name (a
    module file, or a package's ``__init__.py`` and the packages on the way), outside the
    interpreter's prefixes (an installed module's imports are not followed) and not
    penaltyrun. Each import is resolved statically, ``from . import x`` relative to the
    importing file's package.
    """
    root = source_root(module, origin)
    prefixes = {Path(p).resolve() for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    todo, seen = [(origin, _dotted(origin, root))], {origin}
    parts = module.split(".")[:-1]  # its parent packages: their __init__.py run on import
    for depth in range(1, len(parts) + 1):
        init = root.joinpath(*parts[:depth], "__init__.py")
        if init.is_file() and init not in seen and not _under(init, prefixes):
            seen.add(init)
            todo.append((init, _dotted(init, root)))
    while todo and len(seen) <= MAX_LOCAL_FILES:
        path, dotted = todo.pop()
        for name in _imported_names(path, dotted, path.name == "__init__.py"):
            if name.split(".")[0] == "penaltyrun":
                continue
            for found in _module_files(root, name):
                if found not in seen and not _under(found, prefixes):
                    seen.add(found)
                    todo.append((found, _dotted(found, root)))
    return sorted(seen - {origin})


def _dotted(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported_names(path: Path, dotted: str, is_package: bool) -> list[str]:
    """Dotted names a source file imports (``import a.b`` → a.b; ``from a import b`` → a
    and a.b), relative imports resolved; [] for a file that does not parse."""
    try:
        tree = ast.parse(path.read_bytes(), filename=str(path))
    except (SyntaxError, ValueError, OSError):
        return []
    package = dotted.split(".") if is_package else dotted.split(".")[:-1]
    names = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            keep = len(package) - node.level + 1
            if node.level and (not package or keep < 1):
                continue  # no parent package, or beyond the top: Python refuses it too
            base = package[:keep] if node.level else []
            stem = ".".join(base + ([node.module] if node.module else []))
            if not stem:
                continue
            names.append(stem)
            names += [f"{stem}.{alias.name}" for alias in node.names if alias.name != "*"]
    return names


def _module_files(root: Path, name: str) -> list[Path]:
    """Files under ``root`` that importing ``name`` runs: each package's ``__init__.py``
    on the way and the module's own file; [] when the first part is not under ``root``."""
    files, base = [], root
    for part in name.split("."):
        if not part.isidentifier():
            break
        base = base / part
        if (base / "__init__.py").is_file():
            files.append(base / "__init__.py")
        elif base.with_suffix(".py").is_file():
            files.append(base.with_suffix(".py"))
            break
        elif not base.is_dir():  # a namespace package is a folder without __init__.py
            break
    return files


def _under(path: Path, prefixes: set[Path]) -> bool:
    """Whether ``path`` lies in one of the (resolved) folders ``prefixes``: the
    interpreter's installation or environment."""
    resolved = path.resolve()
    return any(resolved == p or p in resolved.parents for p in prefixes)
