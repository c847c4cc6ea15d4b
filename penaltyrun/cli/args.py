"""The command line around Hydra: penaltyrun's own flags, Hydra's options and Hydra's errors.

Hydra prints its own errors on several lines (``Ambiguous value for argument ...``, ``Could
not find 'param/bogus'`` with the list of options, argparse's usage) and exits with 1, the
code of an internal error. Here every such mistake becomes one line
``penaltyrun: error: <key>: <message>`` and exit code 2:

* :func:`check_options` checks the flags with Hydra's own argument parser before anything
  else runs;
* :func:`check_sweeps` refuses a comma list (a sweep) without ``-m``, ``hydra.run.dir``
  as the run directory of a sweep (``-m`` writes under ``hydra.sweep.dir``), MATLAB
  matrix syntax (:func:`matlab_to_yaml`) and an unquoted value with characters Hydra's
  grammar reads only inside quotes (a unicode run directory), each with the fix;
* :func:`hydra_errors` turns an error Hydra raises while it composes a config (e.g. a bad
  value inside an experiment profile's ``hydra.sweeper.params``, met when the sweep reaches
  that cell) into one line, and leaves a real bug in penaltyrun's code a traceback (exit 1).

``--keep`` (:func:`pop_keep`) is penaltyrun's flag: ``mode=evaluate`` writes nothing unless
it, or ``hydra.run.dir``, is given (:func:`evaluate_overrides`).
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import sys
import tempfile
import unicodedata
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from penaltyrun.cli.overrides import check_size, parse_each, split_argv
from penaltyrun.errors import ConfigError

KEEP_FLAG = "--keep"
#: What an evaluation that kept no run directory says on stderr.
EVALUATE_NOTHING_WRITTEN = ("penaltyrun: evaluate: nothing written (pass --keep, or "
                            "hydra.run.dir=DIR (with -m hydra.sweep.dir=DIR), to keep "
                            "Hydra's config and log)")
#: Exceptions raised inside penaltyrun's task function (bugs): kept as tracebacks.
_TASK_ERRORS: list[BaseException] = []


def pop_keep(argv: list[str]) -> tuple[list[str], bool]:
    """``argv`` without ``--keep``, and whether it was there."""
    rest = [a for a in argv if a != KEEP_FLAG]
    return rest, len(rest) != len(argv)


def _hydra_parser() -> Any:
    """Hydra's own argument parser, raising :class:`ConfigError` instead of exiting."""
    from penaltyrun.cli.hydra_private import args_parser

    parser = args_parser()

    def error(message: str) -> None:
        text = message.replace("unrecognized arguments", "unknown option")
        raise ConfigError("command line", f"{text} (see penaltyrun --help)")

    parser.error = error  # type: ignore[method-assign]
    return parser


def options_first(argv: list[str]) -> list[str]:
    """``argv`` with the options (and their values) before the overrides, in their order.

    Hydra's parser refuses an option between overrides (``a=1 -m b=2``); penaltyrun accepts
    them anywhere, as a user writes them.
    """
    options, overrides = split_argv(argv)
    return options + overrides


def check_options(argv: list[str]) -> Any:
    """Parse ``argv`` (options first) as Hydra will; an unknown flag or a bad flag value is
    one line.

    Returns
    -------
    argparse.Namespace
        Hydra's parsed arguments (``overrides``, ``multirun``, ``cfg``, ...).

    Raises
    ------
    ConfigError
        ``command line: unknown option: --bogus`` and the like.
    """
    return _hydra_parser().parse_args(argv)


def check_sweeps(overrides: list[str], multirun: bool) -> list[Any]:
    """Refuse a sweep (``param=diagonal,full``, ``range(3)``, ...) without ``-m``, and the
    command lines Hydra would otherwise run in a way the user did not mean (see the module
    docstring), each with one line naming the fix.

    Returns
    -------
    list
        Hydra's parsed overrides.
    """
    parsed = []
    for arg in overrides:
        check_size(arg)
        _check_matlab(arg)
        try:
            parsed += parse_each([arg], _one_line)
        except ConfigError:
            _check_unquoted(arg)
            raise
    _check_run_dir_key(parsed, multirun)
    if not multirun:
        for o in parsed:
            if o.is_sweep_override():
                value = o.input_line.split("=", 1)[1]
                hint = f" (or {o.key_or_group}=[{value}] for a list)" \
                    if "," in value and "(" not in value else ""
                raise ConfigError(o.key_or_group, f"{value!r} is a sweep: add -m to sweep"
                                  + hint)
    return parsed


#: A number as MATLAB and YAML both write it.
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def matlab_to_yaml(value: str) -> str | None:
    """The YAML form of a MATLAB matrix literal (``[1 0; 0 1]`` → ``[[1,0],[0,1]]``, a row
    ``[1 2 3]`` → ``[1,2,3]``), or None if ``value`` is not one (YAML lists, anything else).

    A value is MATLAB syntax when it is one pair of brackets around numbers and it has a
    ``;`` between rows or two numbers separated by blanks only.
    """
    text = value.strip()
    if not (text.startswith("[") and text.endswith("]")):
        return None
    body = text[1:-1].strip()
    if "[" in body or "]" in body or not body:
        return None
    if ";" not in body and not re.search(r"[\d.]\s+[-+\d.]", body):
        return None
    rows = [row.strip() for row in body.split(";")]
    if rows[-1] == "":  # [1 0; 0 1;]
        rows.pop()
    cells = [[t for t in re.split(r"[\s,]+", row) if t] for row in rows]
    if not cells or not all(cells) or not all(re.fullmatch(_NUMBER, t)
                                              for row in cells for t in row):
        return None
    rendered = ["[" + ",".join(row) + "]" for row in cells]
    return rendered[0] if ";" not in body else "[" + ",".join(rendered) + "]"


def _check_matlab(arg: str) -> None:
    """Refuse ``key=[1 0; 0 1]`` with the YAML form of the same matrix."""
    key, eq, value = arg.partition("=")
    fixed = matlab_to_yaml(value) if eq else None
    if fixed is not None:
        raise ConfigError(key.lstrip("+~"), f"MATLAB matrix syntax {value.strip()!r} is not "
                          f"read: write the YAML form {shlex.quote(f'{key}={fixed}')} (a "
                          "list of rows, commas between entries)")


def _check_unquoted(arg: str) -> None:
    """An override that does not parse because its unquoted value has characters Hydra's
    grammar reads only inside quotes (``hydra.run.dir=runs/résumé``): the quoted form."""
    key, eq, value = arg.partition("=")
    odd = sorted({ch for ch in value if not ch.isascii()})
    if not eq or not odd or value[:1] in ("'", '"') or value[:1] == "[":
        return
    plain = unicodedata.normalize("NFKC", value)
    if plain.isascii():  # full-width digits or letters: their ASCII form is what was meant
        raise ConfigError(key.lstrip("+~"), f"{value!r} is written in full-width or other "
                          f"compatibility characters: write {shlex.quote(f'{key}={plain}')}")
    quote = '"' if '"' not in value else "'"
    raise ConfigError(key.lstrip("+~"), f"Hydra reads {''.join(odd)!r} only inside quotes: "
                      f"write {shlex.quote(f'{key}={quote}{value}{quote}')}")


def _check_run_dir_key(parsed: list[Any], multirun: bool) -> None:
    """Refuse ``hydra.run.dir`` as the only run directory of a sweep: ``-m`` ignores it and
    writes under ``hydra.sweep.dir`` (default ``outputs/multirun/<date>/<time>``)."""
    given = {o.key_or_group: o for o in parsed}
    if multirun and "hydra.run.dir" in given and "hydra.sweep.dir" not in given:
        value = given["hydra.run.dir"].input_line.split("=", 1)[1]
        raise ConfigError("hydra.run.dir", "a sweep (-m) ignores hydra.run.dir and writes "
                          f"to outputs/multirun/...: write hydra.sweep.dir={value} (one "
                          "subfolder per cell)")


def evaluate_overrides(parsed: list[Any], multirun: bool, keep: bool) -> list[str]:
    """Extra Hydra overrides so that ``mode=evaluate`` writes nothing.

    Without ``--keep`` and without ``hydra.run.dir`` (``hydra.sweep.dir`` with ``-m``) on the
    command line, Hydra is told to save no ``.hydra/`` config, to configure no log file and
    to use the current directory as its run directory (which it then leaves untouched); a
    sweep of evaluations gets a temporary sweep directory, removed at exit. Each evaluation
    then says on stderr whether anything was kept (:data:`EVALUATE_NOTHING_WRITTEN`).

    Returns
    -------
    list of str
        To append to the command line (empty when the run directory is kept).
    """
    run_key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    if keep or any(o.key_or_group == run_key for o in parsed):
        return []
    extra = ["hydra.output_subdir=null", "hydra/job_logging=none"]
    if multirun:
        tmp = tempfile.mkdtemp(prefix="penaltyrun-evaluate-")
        _REMOVE_AT_EXIT.append(tmp)
        extra += [f"hydra.sweep.dir={tmp}", "hydra.sweep.subdir=."]
    else:
        extra.append("hydra.run.dir=.")
    return extra


_REMOVE_AT_EXIT: list[str] = []


def remove_temporary() -> None:
    """Remove the temporary sweep directories of :func:`evaluate_overrides`."""
    while _REMOVE_AT_EXIT:
        shutil.rmtree(_REMOVE_AT_EXIT.pop(), ignore_errors=True)


def mark_task_error(exc: BaseException) -> None:
    """Remember an exception raised inside the task function (a bug, not a Hydra error)."""
    _TASK_ERRORS.append(exc)


def _one_line(exc: BaseException) -> str:
    """Hydra's message on one line: ``<group>: unknown choice 'x' (allowed: ...)`` for a
    missing config, else its lines joined (without the config search path it lists)."""
    options = getattr(exc, "options", None)
    if options is None and isinstance(exc.__cause__, BaseException):
        options = getattr(exc.__cause__, "options", None)
    text = str(exc).split("Config search path:")[0]
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    missing = re.search(r"Could not (?:find|load) '([^']+)/([^'/]+)'", text)
    if missing and options is not None:
        group, name = missing.groups()
        return str(ConfigError(group, f"unknown choice {name!r}", allowed=sorted(options)))
    for err in (exc, exc.__cause__):  # OmegaConf's own: "<full_key>: <message>"
        key, msg = getattr(err, "full_key", None), getattr(err, "msg", None)
        if key and msg:
            text = " ".join(str(msg).split("full_key:")[0].split())
            if str(key).startswith("problem.params.") and "not in struct" in text:
                text += (f" (a sweep in hydra.sweeper.params sets a parameter its YAML does "
                         f"not list as ++{key})")
            return f"{key}: {text}"
    text = " ".join(ln for ln in lines if not ln.startswith("Available options")
                    and ln not in (options or ()))
    cause = exc.__cause__
    if cause is not None and str(cause).strip() and str(cause).strip() not in text:
        text += ": " + " ".join(str(cause).split())
    return text or type(exc).__name__


def _is_hydra_error(exc: BaseException) -> bool:
    from hydra.errors import HydraException
    from omegaconf.errors import OmegaConfBaseException

    if any(exc is seen for seen in _TASK_ERRORS):
        return False
    return isinstance(exc, (HydraException, OmegaConfBaseException))


@contextmanager
def hydra_errors() -> Iterator[None]:
    """Run Hydra with its errors as one line and exit code 2 (see the module docstring).

    Hydra re-raises instead of printing when ``HYDRA_FULL_ERROR`` is set; it is set here
    for the duration. A user who set it keeps Hydra's full tracebacks.
    """
    if os.environ.get("HYDRA_FULL_ERROR"):
        yield
        return
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        yield
    except Exception as exc:
        if not _is_hydra_error(exc):
            raise
        print(f"penaltyrun: error: {_one_line(exc)}", file=sys.stderr)
        sys.exit(2)
    finally:
        os.environ.pop("HYDRA_FULL_ERROR", None)
        remove_temporary()
