"""The local modules a user problem imports are part of its source hash: editing a helper
module between an interrupted run and its resume is a new configuration too."""

from __future__ import annotations

import hashlib
import logging
import sys
import textwrap
import uuid

import pytest

import penaltyrun
from penaltyrun.problems import user_code_params
from penaltyrun.runner.usercode import (
    local_sources,
    module_source_hash,
    source_root,
    user_code_hash,
)

PROBLEM = textwrap.dedent('''
    import json

    import numpy as np

    import penaltyrun

    from . import helper
    from .sub.deep import SCALE

    CASES = ("one",)
    DEFAULT_CASE = "one"


    def make_problem(case, params):
        return penaltyrun.from_cost(lambda K: SCALE * float(np.sum(K ** 2)) + helper.offset(),
                                    {"K": (1, (0.1, 10.0))}, name="fit")
''')


@pytest.fixture
def package(tmp_path, monkeypatch):
    """A fresh package on ``sys.path``: ``fit`` imports ``helper`` (which imports ``cyc``,
    which imports ``helper`` back) and ``sub.deep``; ``unrelated`` is imported by nobody;
    ``broken`` does not parse; ``sub.deep`` has an import beyond the top-level package in a
    function nobody calls. Yields the package's name and folder."""
    pkg = f"usercode_{uuid.uuid4().hex[:8]}"
    folder = tmp_path / pkg
    (folder / "sub").mkdir(parents=True)
    files = {"__init__.py": "", "fit.py": PROBLEM,
             "helper.py": "from .cyc import Y\n\n\ndef offset():\n    return 0.0 * Y\n",
             "cyc.py": "Y = 1.0\n\n\ndef back():\n    from . import helper\n    return helper\n",
             "sub/__init__.py": "",
             "sub/deep.py": "SCALE = 1.0\n\n\ndef never():\n    from ... import nowhere\n",
             "unrelated.py": "X = 1\n", "broken.py": "def (:\n"}
    for name, text in files.items():
        (folder / name).write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    yield pkg, folder
    for name in [n for n in sys.modules if n == pkg or n.startswith(f"{pkg}.")]:
        del sys.modules[name]


def test_local_sources_follow_the_imports_of_the_package_only(package):
    pkg, folder = package
    origin = folder / "fit.py"
    assert source_root(f"{pkg}.fit", origin) == folder.parent
    assert source_root(pkg, folder / "__init__.py") == folder.parent
    found = local_sources(f"{pkg}.fit", origin)
    assert found == sorted(folder / n for n in ("__init__.py", "helper.py", "cyc.py",
                                                "sub/__init__.py", "sub/deep.py"))


@pytest.mark.parametrize(("edited", "changes"), [
    ("helper.py", True), ("cyc.py", True), ("sub/deep.py", True), ("__init__.py", True),
    ("unrelated.py", False), ("broken.py", False)])
def test_the_hash_follows_every_imported_local_module_and_nothing_else(package, edited,
                                                                     changes):
    pkg, folder = package
    before = module_source_hash(f"{pkg}.fit")
    path = folder / edited
    path.write_text(path.read_text() + "\n# edited\n")
    assert (module_source_hash(f"{pkg}.fit") != before) is changes


def test_f20_the_parent_packages_init_counts_though_nothing_imports_it(tmp_path, monkeypatch):
    """A package's ``__init__.py`` runs whenever its module is imported: editing it changes
    the hash even when the module imports nothing local."""
    pkg = f"lab_{uuid.uuid4().hex[:8]}"
    (tmp_path / pkg).mkdir()
    (tmp_path / pkg / "__init__.py").write_text("SCALE = 1\n")
    (tmp_path / pkg / "mod.py").write_text("import os\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        before = module_source_hash(f"{pkg}.mod")
        (tmp_path / pkg / "__init__.py").write_text("SCALE = 1000\n")
        assert module_source_hash(f"{pkg}.mod") != before
    finally:
        for name in [n for n in sys.modules if n == pkg or n.startswith(f"{pkg}.")]:
            del sys.modules[name]


def test_a_module_importing_nothing_local_hashes_as_its_own_file(tmp_path, monkeypatch):
    name = f"alone_{uuid.uuid4().hex[:8]}"
    path = tmp_path / f"{name}.py"
    path.write_text("import os\nimport numpy\nimport penaltyrun\nfrom . import x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert local_sources(name, path) == []
    assert module_source_hash(name) == hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def test_a_sibling_module_of_a_single_file_problem_counts(tmp_path, monkeypatch):
    name = f"single_{uuid.uuid4().hex[:8]}"
    (tmp_path / f"{name}.py").write_text(f"import {name}_help\n")
    (tmp_path / f"{name}_help.py").write_text("A = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = module_source_hash(name)
    (tmp_path / f"{name}_help.py").write_text("A = 2\n")
    assert module_source_hash(name) != before


def test_an_edited_helper_is_a_new_configuration_on_resume(package, tmp_path, caplog):
    pkg, folder = package
    kwargs = {"param": "diagonal", "optimizer": "baseline", "n_starts": 2, "workers": 1,
              "run_dir": tmp_path / "run"}
    first = penaltyrun.tune(f"{pkg}.fit", **kwargs)
    (folder / "helper.py").write_text((folder / "helper.py").read_text()
                                      .replace("0.0 * Y", "5.0 * Y"))
    for name in [n for n in sys.modules if n == pkg or n.startswith(f"{pkg}.")]:
        del sys.modules[name]  # as a new process would: the edited helper is imported
    with caplog.at_level(logging.WARNING):
        second = penaltyrun.tune(f"{pkg}.fit", resume=True, **kwargs)
    assert sum("or a local module it imports was edited since 2 finished" in r.getMessage()
               for r in caplog.records) == 1
    assert not set(first.records["job_id"]) & set(second.records["job_id"])
    assert (second.records["best_cost"] - first.records["best_cost"]).round(12).eq(5.0).all()


def test_two_problem_modules_of_one_name_in_one_process_do_not_mix(tmp_path, monkeypatch):
    """``lab_a.fit`` then ``lab_b.fit`` (both problem ``fit``) tuned in one process: the
    second run imports its own module, not the one the first run registered."""
    labs = [f"lab_{uuid.uuid4().hex[:8]}" for _ in range(2)]
    for lab, offset in zip(labs, ("0.0", "5.0")):
        (tmp_path / lab).mkdir()
        (tmp_path / lab / "__init__.py").write_text("")
        (tmp_path / lab / "helper.py").write_text(f"def offset():\n    return {offset}\n")
        (tmp_path / lab / "sub").mkdir()
        (tmp_path / lab / "sub" / "__init__.py").write_text("")
        (tmp_path / lab / "sub" / "deep.py").write_text("SCALE = 1.0\n")
        (tmp_path / lab / "fit.py").write_text(PROBLEM)
    monkeypatch.syspath_prepend(str(tmp_path))
    costs = [penaltyrun.tune(f"{lab}.fit", param="diagonal", optimizer="baseline", n_starts=1,
                             workers=1, run_dir=tmp_path / lab / "run").best.cost
             for lab in labs]
    assert costs[1] - costs[0] == pytest.approx(5.0, abs=1e-12)
    for name in [n for n in sys.modules if n.split(".")[0] in labs]:
        del sys.modules[name]


def test_an_edited_plant_file_is_a_new_configuration_on_resume(tmp_path, caplog):
    plant = tmp_path / "plant.yaml"
    plant.write_text("A: [[0.0, 1.0], [0.0, 0.0]]\nB: [[0.0], [1.0]]\n")
    params = {"plant_file": str(plant)}
    declared = user_code_params("lqr")
    assert user_code_hash(None, params, *declared) == \
        hashlib.sha256(plant.read_bytes()).hexdigest()[:16]
    assert user_code_hash(None, params) == ""  # a file only a declared parameter names
    assert user_code_hash(None, {"plant_file": str(tmp_path / "missing.yaml")},
                          *declared) == ""
    assert user_code_hash(None, {"plant_file": "/dev/zero"}, *declared) == ""  # never read
    kwargs = {"param": "diagonal", "optimizer": "baseline", "n_starts": 1, "workers": 1,
              "params": params, "run_dir": tmp_path / "run"}
    first = penaltyrun.tune("lqr", **kwargs)
    plant.write_text("A: [[0.0, 1.0], [-1.0, 0.0]]\nB: [[0.0], [1.0]]\n")
    with caplog.at_level(logging.WARNING):
        second = penaltyrun.tune("lqr", resume=True, **kwargs)
    assert not set(first.records["job_id"]) & set(second.records["job_id"])
    assert first.best.cost != second.best.cost
    assert sum(f"the plant_file {plant} was edited since 1 finished" in r.getMessage()
               for r in caplog.records) == 1
