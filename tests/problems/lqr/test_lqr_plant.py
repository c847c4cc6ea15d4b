"""Plant sources of problem=lqr (lists, .mat, .npz, python-control StateSpace, (A, B) pair,
Jacobians of a nonlinear model) and bad input: one line naming the key, exit 2."""

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scipy.io import savemat

from penaltyrun.errors import ConfigError
from penaltyrun.problems import lqr

A = np.array([[0.0, 1.0], [-1.0, 0.2]])
B = np.array([[0.0], [1.0]])
PLANTS = '''
import numpy as np
import control

A = np.array([[0.0, 1.0], [-1.0, 0.2]])
B = np.array([[0.0], [1.0]])
system = control.ss(A, B, np.eye(2), np.zeros((2, 1)))
discrete = control.ss(A, B, np.eye(2), np.zeros((2, 1)), 0.1)
pair = (A.tolist(), B.tolist())
'''


@pytest.fixture
def plants(tmp_path, monkeypatch):
    pytest.importorskip("control")
    (tmp_path / "lqr_test_plants.py").write_text(textwrap.dedent(PLANTS))
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    sys.modules.pop("lqr_test_plants", None)


def cost_of(params):
    prob = lqr.make_problem("default", {"t_max": 5.0, **params})
    return prob.evaluate({"Q": np.eye(2), "R": np.eye(1)})["cost"]


def test_every_source_gives_the_same_problem(tmp_path, plants):
    savemat(tmp_path / "plant.mat", {"A": A, "B": B})
    np.savez(tmp_path / "plant.npz", A=A, B=B)
    expected = cost_of({"A": A.tolist(), "B": B.tolist()})
    for params in ({"plant_file": str(tmp_path / "plant.mat")},
                   {"plant_file": str(tmp_path / "plant.npz")},
                   {"plant": "lqr_test_plants:system"},
                   {"plant": "lqr_test_plants:pair"},
                   {"A": A.tolist(), "B": B[:, 0].tolist()}):
        assert cost_of(params) == pytest.approx(expected, rel=1e-13), params


def test_user_plant_drops_the_known_answer_values():
    prob = lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist()})
    np.testing.assert_array_equal(prob.x0, np.eye(2))
    np.testing.assert_array_equal(prob.Wx, np.eye(2))
    assert [s.size for s in prob.matrices] == [2, 1]


@pytest.mark.parametrize(("params", "key", "words"), [
    ({"A": [[0, 1]], "B": [[0], [1]]}, "problem.params.A", "square"),
    ({"A": [[0, 1], [0, 0]], "B": [[0], [1], [1]]}, "problem.params.B", "rows"),
    ({"A": [[1, 0], [0, 0]], "B": [[0], [1]]}, "problem.params.B", "not stabilizable"),
    ({"A": [[0, 1], [0, 0]]}, "problem.params.B", "missing"),
    ({"plant": "lqr_test_plants:nothing"}, "problem.params.plant", "no attribute"),
    ({"plant": "no_such_module_lqr:sys"}, "problem.params.plant", "cannot import"),
    ({"plant": "lqr_test_plants"}, "problem.params.plant", "module:attribute"),
    ({"plant": "lqr_test_plants:discrete", "dt": 0.2}, "problem.params.dt", "has dt = 0.1"),
    ({"A": [[0, 1], [0, 0]], "B": [[0], [1]], "x0": [[1, 2, 3]]}, "problem.params.x0", "n = 2"),
    ({"A": [[0, 1], [0, 0]], "B": [[0], [1]], "u_max": [1, 2]}, "problem.params.u_max", "m = 1"),
    ({"A": [[0, 1], [0, 0]], "B": [[0], [1]], "state_weight": [[1, 2], [2, 1]]},
     "problem.params.state_weight", "semi-definite"),
    ({"A": [[0, 1], [0, 0]], "B": [[0], [1]], "holdout_x0": [[1, 0]]},
     "problem.params.holdout_x0", "training"),
    ({"q_bounds": [1, 0.1]}, "problem.params.q_bounds", "lower < upper"),
    ({"t_max": -1}, "problem.params.t_max", "> 0"),
    ({"shape": 3}, "problem.params.shape", "unknown"),
])
def test_bad_input_names_its_key(plants, params, key, words):
    with pytest.raises(ConfigError) as err:
        lqr.make_problem("default", params)
    assert err.value.key == key and words in str(err.value)


def test_a_plant_file_that_is_missing_or_not_a_regular_file_is_never_opened(tmp_path):
    fifo = tmp_path / "plant.yaml"
    os.mkfifo(fifo)  # opening it to read would block until a writer comes
    for path, words in ((fifo, "not a regular file"), (tmp_path, "not a regular file"),
                        (tmp_path / "none.yaml", "no such file")):
        with pytest.raises(ConfigError, match=words) as err:
            lqr.make_problem("default", {"plant_file": str(path)})
        assert err.value.key == "problem.params.plant_file"


def test_file_without_a_and_bad_dynamics(tmp_path, plants):
    np.savez(tmp_path / "onlyb.npz", B=B)
    with pytest.raises(ConfigError, match="no variable 'A'") as err:
        lqr.make_problem("default", {"plant_file": str(tmp_path / "onlyb.npz")})
    assert err.value.key == "problem.params.plant_file"
    (tmp_path / "lqr_bad_dyn.py").write_text(
        "import numpy as np\n\ndef off(X, U):\n    return X + 1.0\n\n"
        "def shape(X, U):\n    return X[:, :1]\n")
    for name, words in (("off", "equilibrium"), ("shape", "must return shape")):
        with pytest.raises(ConfigError, match=words) as err:
            lqr.make_problem("default", {"A": A.tolist(), "B": B.tolist(),
                                         "dynamics": f"lqr_bad_dyn:{name}"})
        assert err.value.key == "problem.params.dynamics"
    sys.modules.pop("lqr_bad_dyn", None)


BOMB = "A: &a [[0, 1], [0, 0]]\nB: [[0], [1]]\n" + "".join(
    f"c{i}: &c{i} [{', '.join([f'*c{i - 1}' if i else '*a'] * 10)}]\n" for i in range(8))


@pytest.mark.parametrize(("text", "words"), [
    (BOMB, "aliases expand to more than"),
    ("A: " + "[" * 500 + "]" * 500 + "\nB: [[1]]\n", "nesting deeper than"),
    ("A: [" + "0, " * 400_000 + "0]\nB: [[1]]\n", "larger than"),
])
def test_a_plant_yaml_beyond_a_limit_names_file_and_limit(tmp_path, text, words):
    (tmp_path / "plant.yaml").write_text(text)
    with pytest.raises(ConfigError, match=words) as err:
        lqr.make_problem("default", {"plant_file": str(tmp_path / "plant.yaml")})
    assert err.value.key == "problem.params.plant_file"
    assert str(tmp_path / "plant.yaml") in err.value.message


@pytest.mark.parametrize(("override", "key"), [
    ("problem.params.plant_file=bomb.yaml", "problem.params.plant_file"),
    ("problem.params.A=[[0,1]]", "problem.params.A"),
    ("problem.params.B=[[0],[1],[1]]", "problem.params.B"),
    ("problem.params.A=[[1,0],[0,0]]", "problem.params.B"),
    ("problem.params.plant_file=onlyb.npz", "problem.params.plant_file"),
    ("problem.params.plant=json:no_such_attribute", "problem.params.plant"),
])
def test_bad_plant_on_the_command_line_exits_2(tmp_path, override, key):
    np.savez(tmp_path / "onlyb.npz", B=B)
    (tmp_path / "bomb.yaml").write_text(BOMB)
    args = ["problem.params.A=[[0,1],[0,0]]", "problem.params.B=[[0],[1]]"]
    name = override.split("=")[0]
    args = [a for a in args if a.split("=")[0] != name]
    if "plant" in name:
        args = []
    proc = subprocess.run([sys.executable, "-m", "penaltyrun.cli", "mode=evaluate",
                           "problem=lqr", *args, override, "matrices.Q=[[1,0],[0,1]]",
                           "matrices.R=[[1]]"], capture_output=True, text=True,
                          cwd=tmp_path, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and key in lines[0] and "Traceback" not in proc.stderr


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_a_plant_file_whose_arrays_are_too_large_is_refused_from_its_headers(tmp_path, suffix):
    """A small file of compressed zeros declaring a 3000 × 3000 matrix (72 MB once read):
    refused from its headers, before any array is decompressed (both formats compress)."""
    from penaltyrun.problems.lqr import plant

    A = np.zeros((3000, 3000))
    path = tmp_path / f"big{suffix}"
    if suffix == ".npz":
        np.savez_compressed(path, A=A, B=np.zeros((3000, 1)))
    else:
        savemat(path, {"A": A, "B": np.zeros((3000, 1))}, do_compression=True)
    assert path.stat().st_size < 2_000_000
    assert 3000 * 3000 * 8 > plant.MAX_PLANT_BYTES
    with pytest.raises(ConfigError, match="the limit for a plant file is"):
        lqr.make_problem("default", {"plant_file": str(path)})


@pytest.mark.parametrize("dt", ["-1", "0", ".nan"])
def test_a_plant_files_sample_time_must_be_positive(tmp_path, dt):
    """As ``problem.params.dt`` on the command line: refused when built, naming the file's
    key (it failed the jobs at run time: a singular or non-finite discretization)."""
    (tmp_path / "plant.yaml").write_text(f"A: [[0, 1], [0, 0]]\nB: [[0], [1]]\ndt: {dt}\n")
    with pytest.raises(ConfigError, match="is not a positive number") as err:
        lqr.make_problem("default", {"plant_file": str(tmp_path / "plant.yaml")})
    assert err.value.key == "problem.params.plant_file"
