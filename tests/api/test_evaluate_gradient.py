"""penaltyrun.evaluate(..., z=..., gradient=True) and `penaltyrun mode=evaluate z=[...]
+gradient=true`: the candidate as the optimizer's variables, d cost / d z against central
differences, and bad input as one line with exit 2."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import penaltyrun
from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr
from penaltyrun.runner.setup import build_layout

Z = [1.0, 2.0, 3.0, 1.5, 0.7]  # problem=lqr (3 states, 2 inputs), diagonal map


def test_z_gives_the_same_cost_as_its_matrices():
    by_z = penaltyrun.evaluate("lqr", z=Z, param="diagonal")
    by_m = penaltyrun.evaluate("lqr", {"Q": np.diag(Z[:3]).tolist(),
                                       "R": np.diag(Z[3:]).tolist()})
    assert by_z["cost"] == by_m["cost"]
    assert by_z["z_names"] == ["Q.lam1", "Q.lam2", "Q.lam3", "R.lam1", "R.lam2"]


def test_z_as_a_numpy_array_equals_the_list():
    """A result's ``best_z`` is an array: it is taken as its numbers; a 2-D one is refused."""
    by_array = penaltyrun.evaluate("lqr", z=np.asarray(Z), param="diagonal", gradient=True)
    by_list = penaltyrun.evaluate("lqr", z=Z, param="diagonal", gradient=True)
    assert by_array["cost"] == by_list["cost"] and by_array["grad"] == by_list["grad"]
    with pytest.raises(ConfigError, match="must be a list of 5 numbers"):
        penaltyrun.evaluate("lqr", z=np.asarray([Z]), param="diagonal")


@pytest.mark.parametrize("param", ["diagonal", "full", "givens"])
def test_gradient_matches_central_differences_of_evaluate(param):
    rng = np.random.default_rng(3)
    if param == "diagonal":
        z = np.asarray(Z)
    else:  # a generic interior point of the full map
        layout = build_layout(lqr.make_problem("default", {}), param, {})
        lb, ub = layout.bounds()
        z = lb + (ub - lb) * rng.uniform(0.3, 0.7, size=lb.size)
        z[:3] = Z[:3]
    base = penaltyrun.evaluate("lqr", z=z.tolist(), param=param, gradient=True)
    grad = np.asarray(base["grad"])
    assert base["gradient_note"] == "" and grad.shape == z.shape
    for i in range(z.size):
        h = 1e-3 * max(1.0, abs(z[i]))

        def f(s, i=i):
            zz = z.copy()
            zz[i] += s
            return penaltyrun.evaluate("lqr", z=zz.tolist(), param=param)["cost"]

        cd = (4 * (f(h / 2) - f(-h / 2)) / h - (f(h) - f(-h)) / (2 * h)) / 3
        assert grad[i] == pytest.approx(cd, rel=1e-6, abs=1e-9), base["z_names"][i]


def test_no_gradient_is_null_with_its_reason():
    out = penaltyrun.evaluate("lqr", z=Z, param="diagonal", params={"u_max": [0.2, 0.2]},
                              gradient=True)
    assert out["grad"] is None and "simulated" in out["gradient_note"]


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"z": Z[:4]}, "expected 5 values"),
    ({"z": [1000.0, 2, 3, 1, 1]}, "outside its bounds"),
    ({"z": Z, "matrices": {"R": [[1, 0], [0, 1]]}}, "not both"),
    ({"matrices": {"Q": [[2, 1, 0], [1, 2, 0], [0, 0, 1]], "R": [[1, 0], [0, 1]]},
      "gradient": True}, "cannot represent"),
])
def test_bad_input_names_the_fix(kwargs, words):
    with pytest.raises(ConfigError, match=words):
        penaltyrun.evaluate("lqr", param="diagonal", **kwargs)


def test_problem_without_gradient_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="no gradient"):
        penaltyrun.evaluate("lyapunov_transfer", {"K": np.eye(5).tolist()}, gradient=True)


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                           "problem=lqr", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600)


def test_cli_z_and_gradient_equal_the_library(tmp_path):
    proc = _cli("param=diagonal", f"z={Z}".replace(" ", ""), "+gradient=true", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    lib = penaltyrun.evaluate("lqr", z=Z, param="diagonal", gradient=True)
    assert out["grad"] == lib["grad"] and out["cost"] == lib["cost"]


@pytest.mark.parametrize(("args", "words"), [
    (["param=diagonal", "z=[1,2]", "+gradient=true"], "z: expected 5 values"),
    (["param=diagonal", "z=[1,2,3,1,1]", "+gradient=maybe"], "gradient: must be true or false"),
    (["mode=optimize", "+gradient=true"], "only mode=evaluate"),
])
def test_cli_bad_input_is_one_line_exit_2(tmp_path, args, words):
    proc = _cli(*args, cwd=tmp_path)
    assert proc.returncode == 2
    assert words in proc.stderr and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_map_without_derivative_keeps_the_matrix_gradient():
    """GEAGSP (param=full) encodes a diagonal matrix at a point where Gram–Schmidt skips a
    basis vector: no d cost / d z there, but d cost / d Q, R still exists."""
    mats = {"Q": np.diag(Z[:3]).tolist(), "R": np.diag(Z[3:]).tolist()}
    out = penaltyrun.evaluate("lqr", mats, param="full", gradient=True)
    assert out["grad"] is None and "not differentiable" in out["gradient_note"]
    diag = penaltyrun.evaluate("lqr", z=Z, param="diagonal", gradient=True)
    np.testing.assert_allclose(np.diag(out["grad_matrices"]["Q"]), diag["grad"][:3],
                               rtol=1e-12)
