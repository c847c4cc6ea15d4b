"""Command line: ``penaltyrun`` (Hydra app: optimize / evaluate / report) and
``penaltyrun-report`` (report from Parquet files).

Every user error (unknown names, bad values, malformed matrices) ends with one readable
line ``penaltyrun: error: <key>: <message> (allowed: ...)`` on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import json
import logging
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from penaltyrun import __version__, io, problems, report, runner
from penaltyrun.errors import ConfigError

logger = logging.getLogger("penaltyrun")

MODES = ("optimize", "evaluate", "report")
EXIT_USAGE = 2


def git_commit() -> str:
    """Commit of the package source (with ``-dirty`` if modified), or ``unknown``."""
    src = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=src, capture_output=True,
                             text=True, timeout=5, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=src, capture_output=True, text=True, timeout=5).stdout
        return sha + ("-dirty" if dirty.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _plain(node: Any) -> Any:
    return OmegaConf.to_container(node, resolve=True) if node is not None else None


def problem_params(cfg: DictConfig) -> dict[str, Any]:
    """Problem overrides from ``problem.params`` (nulls mean "from the case table")."""
    params = _plain(cfg.problem.get("params")) or {}
    return {k: v for k, v in params.items() if v is not None}


def _setup(cfg: DictConfig) -> tuple[Any, Any, Any]:
    return runner.build(cfg.problem.name, cfg.case, problem_params(cfg), cfg.param.name,
                        _plain(cfg.param), cfg.optimizer.name,
                        {k: v for k, v in _plain(cfg.optimizer).items() if k != "name"})


def run_optimize(cfg: DictConfig) -> Path:
    """Plan and run the jobs of one cell, then write results.parquet (and the report)."""
    prob, _, _ = _setup(cfg)  # validate everything before any job starts
    run_dir = Path(HydraConfig.get().runtime.output_dir)
    resolved = OmegaConf.to_container(cfg, resolve=True)
    hashed = {k: resolved[k] for k in ("problem", "case", "param", "optimizer")}
    hashed["seed"] = resolved["runner"]["seed"]
    meta = {"config_hash": runner.config_hash(hashed), "config": OmegaConf.to_yaml(cfg),
            "package_version": __version__, "git_commit": git_commit(),
            "run_id": run_dir.name}
    rc = cfg.runner
    jobs = runner.plan_jobs(
        cfg.problem.name, prob.case, cfg.param.name, cfg.optimizer.name, rc.n_starts,
        int(rc.seed), problem_params(cfg), _plain(cfg.param),
        {k: v for k, v in _plain(cfg.optimizer).items() if k != "name"}, meta)
    logger.info("%d jobs (%s / %s / %s / %s) → %s", len(jobs), prob.name, prob.case,
                cfg.param.name, cfg.optimizer.name, run_dir)
    runner.execute(jobs, run_dir, workers=rc.workers, backend=rc.backend,
                   scheduler=rc.scheduler, resume=bool(rc.resume),
                   retry_failed=bool(rc.retry_failed))
    path = io.collect(run_dir)
    if rc.report:
        out = Path(cfg.report.output) if cfg.report.output else run_dir / "report"
        report.build_report(path, out, paper=bool(cfg.report.paper))
        logger.info("report written to %s", out)
    return path


def run_evaluate(cfg: DictConfig) -> dict[str, Any]:
    """Evaluate the matrices given in ``matrices.*`` and print one JSON line."""
    prob = problems.make(cfg.problem.name, cfg.case, problem_params(cfg))
    given = {k: v for k, v in (_plain(cfg.matrices) or {}).items() if v is not None}
    wanted = [spec.name for spec in prob.matrices]
    extra = sorted(set(given) - set(wanted))
    if extra:
        raise ConfigError(f"matrices.{extra[0]}", f"not a matrix of problem {prob.name!r}",
                          allowed=wanted)
    for spec in prob.matrices:
        if spec.name not in given:
            raise ConfigError(f"matrices.{spec.name}", f"missing; pass "
                              f"'matrices.{spec.name}=[[...], ...]' ({spec.size}x{spec.size})")
        problems.base.check_spd(f"matrices.{spec.name}", given[spec.name], spec.size)
    scalars_cfg = {k: v for k, v in (_plain(cfg.scalars) or {}).items() if v is not None}
    scalars = {}
    for spec in prob.scalars:
        if spec.name not in scalars_cfg:
            raise ConfigError(f"scalars.{spec.name}", "missing; pass "
                              f"'scalars.{spec.name}=<value>' in {list(spec.bounds)}")
        scalars[spec.name] = float(scalars_cfg[spec.name])
    result = prob.evaluate(given, scalars or None)
    print(json.dumps(result, default=str), flush=True)
    return result


def run_report(cfg: DictConfig) -> Path:
    """Tables and figures from Parquet results under ``report.input``."""
    if not cfg.report.input:
        raise ConfigError("report.input", "missing; pass report.input=<results.parquet or "
                          "folder>")
    src = Path(cfg.report.input)
    if not src.exists():
        raise ConfigError("report.input", f"{src} does not exist")
    out = Path(cfg.report.output) if cfg.report.output else \
        (src.parent if src.is_file() else src) / "report"
    report.build_report(src, out, paper=bool(cfg.report.paper))
    print(f"report written to {out}")
    return out


def _guard(func: Callable[[], Any]) -> Any:
    """Run ``func``; turn user errors into one line on stderr and exit code 2."""
    try:
        return func()
    except ConfigError as exc:
        print(f"penaltyrun: error: {exc}", file=sys.stderr)
        sys.exit(EXIT_USAGE)
    except FileNotFoundError as exc:
        print(f"penaltyrun: error: {exc}", file=sys.stderr)
        sys.exit(EXIT_USAGE)


@hydra.main(version_base="1.3", config_path="conf", config_name="config")
def _hydra_main(cfg: DictConfig) -> None:
    def dispatch() -> Any:
        if cfg.mode not in MODES:
            raise ConfigError("mode", f"unknown mode {cfg.mode!r}", allowed=MODES)
        return {"optimize": run_optimize, "evaluate": run_evaluate,
                "report": run_report}[cfg.mode](cfg)

    _guard(dispatch)


def main() -> None:
    """Entry point of ``penaltyrun``."""
    _hydra_main()


def report_main(argv: list[str] | None = None) -> None:
    """Entry point of ``penaltyrun-report INPUT [-o OUTPUT] [--no-paper]``."""
    parser = argparse.ArgumentParser(
        prog="penaltyrun-report",
        description="Tables and figures from penaltyrun results (Parquet only).")
    parser.add_argument("input", help="results.parquet or a folder searched recursively")
    parser.add_argument("-o", "--output", help="output folder (default <input>/report)")
    parser.add_argument("--no-paper", action="store_true",
                        help="leave out the paper's numbers")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    src = Path(args.input)

    def build() -> None:
        if not src.exists():
            raise ConfigError("input", f"{src} does not exist")
        out = Path(args.output) if args.output else \
            (src.parent if src.is_file() else src) / "report"
        report.build_report(src, out, paper=not args.no_paper)
        print(f"report written to {out}")

    _guard(build)


if __name__ == "__main__":
    main()
