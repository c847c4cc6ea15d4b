"""Every package's public names stay the objects they name after every submodule is imported.

A package that exposes a function under the same name as one of its submodules loses the
function as soon as anything imports the submodule (the import system sets the package
attribute to the module). Which code imports it first depends on the test order, so the
clash shows up only in some orders; importing everything first makes it show every time.
"""

from __future__ import annotations

import importlib
import pkgutil
import types

import penaltyrun

# Submodules that need an optional tool at import time (the MkDocs build hook).
_OPTIONAL = {"penaltyrun.docsgen.mkdocs_hook"}


def _packages_and_modules() -> tuple[list[str], list[str]]:
    packages, modules = ["penaltyrun"], []
    for info in pkgutil.walk_packages(penaltyrun.__path__, "penaltyrun."):
        (packages if info.ispkg else modules).append(info.name)
    return packages, modules


def _public_names(package: types.ModuleType) -> list[str]:
    lazy = getattr(package, "_NAMES", {})
    return sorted(set(getattr(package, "__all__", ())) | set(lazy))


def test_no_public_name_is_shadowed_by_a_submodule():
    packages, modules = _packages_and_modules()
    for name in packages + modules:
        if name in _OPTIONAL:
            continue
        importlib.import_module(name)
    shadowed = []
    for name in packages:
        package = importlib.import_module(name)
        submodules = {info.name for info in pkgutil.iter_modules(package.__path__)}
        for public in _public_names(package):
            value = getattr(package, public)
            if isinstance(value, types.ModuleType) or public in submodules:
                shadowed.append(f"{name}.{public}")
    assert shadowed == [], f"public names that are (or clash with) submodules: {shadowed}"


def test_lazy_names_resolve_to_their_definitions():
    packages, _ = _packages_and_modules()
    for name in packages:
        package = importlib.import_module(name)
        for public, module in getattr(package, "_NAMES", {}).items():
            source = importlib.import_module(f"{name}.{module}")
            assert getattr(package, public) is getattr(source, public), f"{name}.{public}"


def test_top_level_api_has_the_documented_signatures():
    import inspect

    expected = {
        "from_cost": "(cost, matrices, *, scalars=None, batched=False, name='user', "
                     "gradient=None, gradient_cost=None)",
        "tune": "(problem, *, param='full', optimizer='cmaes', n_starts=10, seed=None, "
                "optimizer_options=None, case=None, params=None, run_dir=None, workers=None, "
                "resume=False, job_timeout=None, param_options=None, runner_options=None)",
        "load": "(path, *, problem=None)",
        "compare": "(result_a, result_b)",
    }
    for name, text in expected.items():
        sig = inspect.signature(getattr(penaltyrun, name))
        plain = sig.replace(parameters=[p.replace(annotation=inspect.Parameter.empty)
                                        for p in sig.parameters.values()],
                            return_annotation=inspect.Signature.empty)
        assert str(plain) == text, name
    params = inspect.signature(penaltyrun.evaluate).parameters
    assert list(params)[:2] == ["problem", "matrices"]
    assert isinstance(penaltyrun.TuneResult, type) and penaltyrun.__version__


def test_importing_the_package_imports_no_api_module():
    import subprocess
    import sys

    code = ("import sys, penaltyrun; "
            "print(sorted(m for m in ('numpy', 'pandas', 'penaltyrun.api') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]"
