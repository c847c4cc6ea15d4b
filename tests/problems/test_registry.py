"""The problem registry: own problems, `module:` paths, entry points, protocol checks."""

import sys
import textwrap

import pytest

from penaltyrun import problems
from penaltyrun.errors import ConfigError

GOOD = '''
import numpy as np
from penaltyrun.problems.base import BatchEvaluation, MatrixSpec

CASES = ("one", "two")
DEFAULT_CASE = "one"


class Quad:
    name = "quad"
    matrices = (MatrixSpec("K", 2, (0.1, 10.0)),)
    scalars = ()

    def __init__(self, case):
        self.case = case

    def evaluate_batch(self, mats, scalars=None):
        cost = np.einsum("bii->b", mats["K"])
        return BatchEvaluation(cost, np.ones(len(cost), bool),
                               np.array(["converged"] * len(cost), dtype=object))

    def evaluate(self, mats, scalars=None):
        return {"cost": float(np.trace(mats["K"])), "converged": True,
                "status": "converged", "t_final": 0.0}

    def simulate(self, mats, scalars=None):
        return {"t": np.zeros(1)}


def make_problem(case, params):
    return Quad(case)
'''


@pytest.fixture
def site(tmp_path, monkeypatch):
    """A folder on sys.path holding modules and an installed distribution's metadata."""
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("quadprob", "halfprob"):
        sys.modules.pop(name, None)
    problems.trust.forget_named()


def test_own_problems_are_available():
    assert {"zermelo", "attitude_lqr", "qlaw"} <= set(problems.available())
    assert problems.module("zermelo").__name__ == "penaltyrun.problems.zermelo"


def test_module_path_route(site):
    (site / "quadprob.py").write_text(GOOD)
    prob = problems.make("quad", None, {}, "quadprob")
    assert prob.case == "one" and prob.evaluate({"K": [[1, 0], [0, 2]]})["cost"] == 3.0
    with pytest.raises(ConfigError, match="unknown case 'three'.*allowed: one, two"):
        problems.make("quad", "three", {}, "quadprob")
    problems.register("quad", "quadprob")
    assert "quad" in problems.available() and problems.module("quad").CASES == ("one", "two")


def test_user_code_params_are_what_the_module_declares(site):
    assert problems.user_code_params("zermelo") == ((), ())
    assert problems.user_code_params("lqr") == (("plant", "dynamics"), ("plant_file",))
    (site / "quadprob.py").write_text(GOOD + 'CODE_PARAMS = ("law",)\nFILE_PARAMS = ("table",)\n')
    assert problems.user_code_params("quad", "quadprob") == (("law",), ("table",))
    (site / "halfprob.py").write_text(GOOD + 'CODE_PARAMS = "law"\n')
    with pytest.raises(ConfigError, match="halfprob.CODE_PARAMS must be a tuple of parameter"):
        problems.user_code_params("quad", "halfprob")


READS_ITS_TABLE = GOOD.replace("def make_problem(case, params):\n    return Quad(case)", """
FILE_PARAMS = ("table",)


def make_problem(case, params):
    if params.get("table"):
        text = open(params["table"]).read()
        raise ValueError(f"bad table: {text}")
    return Quad(case)
""")


def test_a_file_named_by_results_is_never_quoted_by_any_problem(site):
    """A user problem that quotes its data file in an error: your own run shows the
    message; while results are read (the file named by the data) only its type."""
    (site / "quadprob.py").write_text(READS_ITS_TABLE)
    secret = site / "mine.txt"
    secret.write_text("SECRET_TOKEN")
    params = {"table": str(secret)}
    with pytest.raises(ValueError, match="SECRET_TOKEN"):
        problems.make("quad", None, params, "quadprob")
    problems.register("quad", "quadprob")
    with problems.trust.reading_results(), pytest.raises(ConfigError) as info:
        problems.make("quad", None, params)
    assert info.value.key == "problem.params.table" and "SECRET_TOKEN" not in str(info.value)
    assert "ValueError" in str(info.value) and str(secret) in str(info.value)
    with problems.trust.reading_results():  # no file named: built as usual
        assert problems.make("quad", None, {}).case == "one"


def test_entry_point_route(site):
    (site / "quadprob.py").write_text(GOOD)
    dist = site / "mylab_quad-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: mylab-quad\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(textwrap.dedent("""\
        [penaltyrun.problems]
        quad = quadprob
        """))
    assert "quad" in problems.available()
    prob = problems.make("quad", "two", {})
    assert prob.name == "quad" and prob.case == "two"
    with pytest.raises(ConfigError, match="unknown problem 'nope'.*quad"):
        problems.module("nope")


@pytest.mark.parametrize(("source", "missing"), [
    ("CASES = ('a',)\n", "lacks DEFAULT_CASE, make_problem"),
    ("CASES = ('a',)\nDEFAULT_CASE = 'b'\nmake_problem = 3\n",
     "lacks make_problem (not callable)"),
    ("CASES = 'a'\nDEFAULT_CASE = 'a'\ndef make_problem(c, p): pass\n",
     "lacks CASES as a non-empty tuple of case names"),
    ("CASES = ('a',)\nDEFAULT_CASE = 'b'\ndef make_problem(c, p): pass\n",
     "lacks DEFAULT_CASE among CASES"),
])
def test_module_lacking_the_protocol_is_named(site, source, missing):
    (site / "halfprob.py").write_text(source)
    with pytest.raises(ConfigError) as err:
        problems.make("half", None, {}, "halfprob")
    text = str(err.value)
    assert text.startswith("problem.module: halfprob ") and missing in text
    assert "\n" not in text


def test_problem_object_lacking_the_protocol_is_named(site):
    (site / "halfprob.py").write_text(GOOD.replace("    def simulate", "    def _simulate"))
    with pytest.raises(ConfigError, match="returned a Quad that lacks simulate"):
        problems.make("half", None, {}, "halfprob")


def test_unimportable_module(site):
    with pytest.raises(ConfigError, match="cannot import 'no_such_mod'.*PYTHONPATH"):
        problems.make("x", None, {}, "no_such_mod")
    (site / "halfprob.py").write_text("import no_such_dependency\n")
    with pytest.raises(ConfigError, match="cannot import 'halfprob'"):
        problems.make("x", None, {}, "halfprob")
