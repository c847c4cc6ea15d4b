"""First contact with the command line (subprocesses, as a user): penaltyrun's own --help,
Hydra's errors as one line, mode=evaluate leaving nothing behind, problem parameters."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from penaltyrun import problems
from penaltyrun.cli.userconf import CONF_DIR

K2 = "matrices.K=[[1.7421,0.9560],[0.9560,1.1414]]"
#: Modules a refused command line must not import (heavy, and not needed to check it).
HEAVY = ("cma", "pyswarms", "pandas", "pyarrow", "matplotlib", "dask", "scipy.optimize",
         "scipy.stats")


def cli(*args: str, cwd: Path, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    full = {**os.environ, **(env or {})}
    return subprocess.run([sys.executable, "-m", "penaltyrun.cli", *args], cwd=cwd, env=full,
                          capture_output=True, text=True, timeout=300)


def one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("penaltyrun: error: ")
    return lines[0]


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def imported_by(argv: list[str], cwd: Path) -> tuple[int, set[str], str]:
    """Exit code, the heavy modules imported, and stdout+stderr of ``penaltyrun argv``."""
    code = textwrap.dedent(f"""\
        import sys
        sys.argv = ["penaltyrun", *{argv!r}]
        from penaltyrun import cli
        try:
            cli.main()
            rc = 0
        except SystemExit as exc:
            rc = exc.code or 0
        heavy = [m for m in {HEAVY!r} if m in sys.modules]
        print("RESULT", rc, ",".join(heavy))
        """)
    proc = subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True,
                          text=True, timeout=300)
    last = proc.stdout.strip().splitlines()[-1].split()
    assert last[0] == "RESULT", proc.stdout + proc.stderr
    return int(last[1]), set(last[2].split(",")) if len(last) > 2 else set(), \
        proc.stdout + proc.stderr


# --- help ---------------------------------------------------------------------------------

def test_help_is_penaltyruns_own(tmp_path):
    proc = cli("--help", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    lines = text.strip().splitlines()
    assert len(lines) <= 60 and lines[0].startswith("usage: penaltyrun")
    assert "Hydra" not in lines[0] and "== Config groups ==" not in text
    for mode in ("optimize", "evaluate", "report", "plan"):
        assert f"\n  {mode} " in text
    for group in ("problem", "param", "optimizer", "experiment"):
        names = sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml"))
        assert all(name in text for name in names), group
    for line in ("  problem    zermelo*", "  param      full*", "  optimizer  pso*"):
        assert line in text
    for path in (CONF_DIR / "problem").glob("*.yaml"):  # cases as the modules define them
        name = path.stem
        cases = problems.module(name).CASES
        row = next(ln for ln in lines if ln.startswith(f"  {name} "))
        assert row.split(None, 1)[1].startswith(f"{cases[0]}*, " if len(cases) > 1
                                                else f"{cases[0]}*")
        assert all(case in row for case in cases)
    examples = lines[lines.index("examples:") + 1:lines.index("options:") - 1]
    assert len(examples) == 5 and all(ln.startswith("  penaltyrun ") for ln in examples)
    assert "outputs/<date>/<time>_<problem>_<param>/" in text and "docs/" in text
    assert "--hydra-help" in text and "--keep" in text


def test_help_imports_no_heavy_module(tmp_path):
    rc, heavy, out = imported_by(["--help"], tmp_path)
    assert rc == 0 and "usage: penaltyrun" in out
    assert heavy == set(), heavy
    code = "import sys; sys.argv = ['penaltyrun', '--help']; from penaltyrun import cli; " \
           "cli.main(); print('numba' in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert proc.stdout.strip().splitlines()[-1] == "False"


def test_help_lists_user_groups_and_cases(tmp_path):
    write(tmp_path / "mods" / "toyhelp.py", 'CASES = ("calm", "stormy")\nDEFAULT_CASE = "calm"\n')
    write(tmp_path / "conf" / "problem" / "toyhelp.yaml", "name: toyhelp\nmodule: toyhelp\n")
    write(tmp_path / "conf" / "experiment" / "mystudy.yaml", "# @package _global_\n")
    proc = cli("--config-dir", "conf", "--help", cwd=tmp_path,
               env={"PYTHONPATH": os.pathsep.join(filter(None, [
                   os.environ.get("PYTHONPATH"), str(tmp_path / "mods")]))})
    assert proc.returncode == 0, proc.stderr
    assert "mystudy" in proc.stdout
    assert any(ln.split() == ["toyhelp", "calm*,", "stormy"] for ln in proc.stdout.splitlines())


def test_hydra_help_is_hydras(tmp_path):
    proc = cli("--hydra-help", cwd=tmp_path)
    assert proc.returncode == 0 and "Hydra (" in proc.stdout


# --- one line and exit 2 for every mistake --------------------------------------------------

@pytest.mark.parametrize(("args", "fragments"), [
    (["param=diagonal,full"], ["param: 'diagonal,full' is a sweep: add -m to sweep",
                               "param=[diagonal,full]"]),
    (["runner.seed=range(3)"], ["runner.seed: 'range(3)' is a sweep: add -m"]),
    (["--bogus"], ["unknown option: --bogus"]),
    (["--cfg", "bogus"], ["--cfg", "invalid choice: 'bogus'"]),
    (["--config-dir", "nowhere"], ["--config-dir", "not a directory"]),
    (["--config-path", "nowhere"], ["--config-path", "not a directory"]),
    (["--config-name", "nope"], ["--config-name", "nope.yaml"]),
    (["foo"], ["foo: malformed override 'foo'"]),
    (["optimizer.iters=[1"], ["optimizer.iters: malformed override"]),
    (["hydra/launcher=bogus"], ["hydra/launcher: unknown choice 'bogus' (allowed: basic"]),
    (["hydra.job.chdir=maybe"], ["hydra.job.chdir: Value 'maybe' is not a valid bool"]),
    (["-m", "hydra/sweeper=foo", "mode=plan"], ["hydra/sweeper: unknown choice 'foo'"]),
])
def test_hydra_mistakes_are_one_line(tmp_path, args, fragments):
    key = "hydra.sweep.dir" if "-m" in args else "hydra.run.dir"
    line = one_error_line(cli(*args, f"{key}={tmp_path / 'run'}", cwd=tmp_path))
    for fragment in fragments:
        assert fragment in line, line
    assert not (tmp_path / "run").exists()


def test_bad_override_imports_only_what_the_checks_need(tmp_path):
    rc, heavy, out = imported_by(["optimizer.iters=-1"], tmp_path)
    assert rc == 2 and "optimizer.iters" in out
    assert heavy == set(), heavy


def test_bad_choice_in_profile_sweep_is_one_line_before_any_job(tmp_path):
    write(tmp_path / "myconf" / "experiment" / "badsweep.yaml", """\
        # @package _global_
        runner: {n_starts: 1, report: false}
        optimizer: {iters: 1, n_particles: 2}
        hydra:
          sweeper:
            params:
              param: diagonal,bogus,full
        """)
    line = one_error_line(cli("-m", "--config-dir", "myconf", "+experiment=badsweep",
                              f"hydra.sweep.dir={tmp_path / 'sweep'}", cwd=tmp_path))
    assert "param: unknown choice 'bogus'" in line and "diagonal" in line, line
    assert not list(tmp_path.glob("sweep/**/jobs"))


def test_options_may_come_between_overrides(tmp_path):
    proc = cli("runner.n_starts=1", "-m", "param=diagonal,full", "mode=plan",
               "runner.forecast_samples=0", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "diagonal" in proc.stdout and "full" in proc.stdout


# --- mode=evaluate writes nothing unless asked ------------------------------------------------

def test_evaluate_writes_nothing_and_says_so(tmp_path):
    (tmp_path / "tmp").mkdir()
    proc = cli("mode=evaluate", K2, cwd=tmp_path, env={"TMPDIR": str(tmp_path / "tmp")})
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1])["converged"] is True
    assert proc.stderr.strip().splitlines() == [
        "penaltyrun: evaluate: nothing written (pass --keep, or hydra.run.dir=DIR (with -m "
        "hydra.sweep.dir=DIR), to keep Hydra's config and log)"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]
    sweep = cli("-m", "mode=evaluate", K2 + ",[[2,0],[0,2]]", cwd=tmp_path,
                env={"TMPDIR": str(tmp_path / "tmp")})
    assert sweep.returncode == 0, sweep.stderr
    assert sweep.stdout.count('"converged": true') == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tmp"]
    assert not list((tmp_path / "tmp").iterdir())  # the temporary sweep directory is gone


def test_evaluate_keeps_its_run_directory_when_asked(tmp_path):
    proc = cli("mode=evaluate", K2, "--keep", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    kept = [p.parent for p in tmp_path.glob("outputs/*/*/.hydra")]
    assert len(kept) == 1 and (kept[0] / ".hydra" / "config.yaml").is_file()
    assert proc.stderr.strip() == f"penaltyrun: evaluate: Hydra's config and log kept in {kept[0]}"
    proc = cli("mode=evaluate", K2, f"hydra.run.dir={tmp_path / 'ev'}", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "ev" / ".hydra" / "overrides.yaml").is_file()
    assert str(tmp_path / "ev") in proc.stderr


# --- every field of a problem's Params dataclass is a parameter ---------------------------

TOY = """\
    from dataclasses import dataclass

    import numpy as np

    from penaltyrun.problems.base import MatrixSpec, ParamsMixin

    CASES = ("one",)
    DEFAULT_CASE = "one"


    @dataclass(frozen=True)
    class Params(ParamsMixin):
        gain: float = 1.0          # not in the YAML file
        offset: float = 0.0        # in the YAML file


    class Toy:
        name, case, scalars = "toyparams", "one", ()
        matrices = (MatrixSpec("K", 1, (0.1, 10.0)),)

        def __init__(self, params):
            self.params = params

        def evaluate_batch(self, mats, scalars=None):
            raise NotImplementedError

        def evaluate(self, mats, scalars=None):
            k = float(np.asarray(mats["K"])[0, 0])
            return {"cost": self.params.gain * k + self.params.offset}

        def simulate(self, mats, scalars=None):
            return {}


    def make_problem(case, overrides):
        return Toy(Params.from_mapping(overrides))
    """


@pytest.fixture
def toy(tmp_path):
    write(tmp_path / "mods" / "toyparams.py", TOY)
    write(tmp_path / "conf" / "problem" / "toyparams.yaml", """\
        name: toyparams
        module: toyparams
        params:
          offset: 0.5
        """)
    env = {"PYTHONPATH": os.pathsep.join(filter(None, [os.environ.get("PYTHONPATH"),
                                                       str(tmp_path / "mods")]))}
    return lambda *args: cli("--config-dir", "conf", "problem=toyparams", "mode=evaluate",
                             "matrices.K=[[2.0]]", *args, cwd=tmp_path, env=env)


def cost(proc: subprocess.CompletedProcess) -> float:
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])["cost"]


def test_params_field_not_in_yaml_can_be_overridden(toy):
    assert cost(toy()) == pytest.approx(2.5)
    assert cost(toy("problem.params.gain=3")) == pytest.approx(6.5)
    assert cost(toy("+problem.params.gain=3")) == pytest.approx(6.5)
    assert cost(toy("problem.params.gain=3", "problem.params.offset=1")) == pytest.approx(7.0)


def test_unknown_params_are_refused_with_the_fields(toy):
    line = one_error_line(toy("problem.params.gian=3"))
    assert "problem.params.gian" in line and "(allowed: gain, offset)" in line, line
    line = one_error_line(toy("problem.params.gain=abc"))
    assert "problem.params.gain: must be a number" in line, line


def test_profile_sweeps_an_unlisted_param_with_plus_plus(toy, tmp_path):
    write(tmp_path / "conf" / "experiment" / "gains.yaml", """\
        # @package _global_
        hydra:
          sweeper:
            params:
              ++problem.params.gain: 1,3
        """)
    proc = toy("-m", "+experiment=gains")
    assert proc.returncode == 0, proc.stderr
    costs = [json.loads(ln)["cost"] for ln in proc.stdout.splitlines() if ln.startswith("{")]
    assert costs == pytest.approx([2.5, 6.5])
    write(tmp_path / "conf" / "experiment" / "gains.yaml", """\
        # @package _global_
        hydra:
          sweeper:
            params:
              problem.params.gain: 1,3
        """)
    proc = toy("-m", "+experiment=gains")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr, proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("penaltyrun: error: ")
    assert "++problem.params.gain" in proc.stderr
