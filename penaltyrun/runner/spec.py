"""The typed specification of one cell's run: what the runner plans and executes.

The command line turns its composed Hydra config into a :class:`RunSpec` at one place
(:func:`penaltyrun.cli.spec.run_spec`), the library from the same YAML files
(:func:`penaltyrun.api.compose.run_spec`); both then plan with :meth:`RunSpec.plan` and run
with :func:`penaltyrun.runner.execute`, which takes the :class:`RunnerOptions`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from penaltyrun.errors import ConfigError
from penaltyrun.runner.options import check_runner_options, resolve_workers
from penaltyrun.runner.plan import Job, plan_jobs
from penaltyrun.runner.usercode import user_code_hash

#: Optimizer settings every search optimizer reads that only some presets list (the charge
#: per exact gradient of ``polish=gradient``): given on the command line as
#: ``+optimizer.grad_cost=...``, from Python in ``optimizer_options``.
OPTIONAL_OPTIMIZER_OPTIONS = ("grad_cost",)


@dataclass(frozen=True)
class RunnerOptions:
    """The ``runner.*`` options, checked when built (one :class:`ConfigError` naming the
    key). Defaults: those of ``conf/config.yaml``; each option's meaning is documented
    there and in the configuration reference.

    Raises
    ------
    ConfigError
        A value of the wrong type or out of range, or options that do not go together
        (:func:`penaltyrun.runner.options.check_runner_options`; the scheduler is not
        contacted).
    """

    n_starts: int = 10
    seed: int = 20250422
    workers: int | str = "auto"
    backend: str = "local"
    scheduler: str | None = None
    resume: bool = False
    retry_failed: bool = False
    max_retries: int = 1
    worker_timeout: float = 60
    stall_timeout: float = 600
    job_timeout: float | None = None
    evaluate_on: str = "local"
    chunks: int | str = "auto"
    report: bool = True
    holdout: bool = True
    warm_start: bool = False
    warm_start_share: float = 0.3
    progress: bool | str = "auto"
    forecast_samples: int = 8
    cutoff: bool = True

    def __post_init__(self) -> None:
        check_runner_options(self.as_dict(), connect=False)

    @classmethod
    def from_mapping(cls, options: Mapping[str, Any]) -> RunnerOptions:
        """The options of a ``runner`` config node (missing keys: the defaults).

        Raises
        ------
        ConfigError
            An unknown key (with the allowed ones), or a value as in the class.
        """
        check_runner_options(options, connect=False)
        return cls(**options)

    def as_dict(self) -> dict[str, Any]:
        """The options as a plain ``runner`` node."""
        return dataclasses.asdict(self)

    def local_workers(self) -> int | None:
        """Worker processes on this machine (``workers``, ``auto`` resolved); ``None`` for
        a remote dask scheduler (cluster size unknown here)."""
        if self.backend == "dask" and self.scheduler:
            return None
        return resolve_workers(self.workers)


@dataclass(frozen=True)
class RunSpec:
    """Everything one cell's run needs (plain data; the typed form of a composed config).

    Attributes
    ----------
    problem, param, optimizer : str
        Problem name, parameterization (map) name, optimizer name.
    case : str or None
        Problem case (``None``: the problem's default case).
    problem_params : dict
        Problem parameter overrides (nulls already dropped).
    param_options : dict
        The parameterization node (``name``, ``eig_bounds``, ``cayley_bound``).
    optimizer_options : dict
        Optimizer settings (without ``name``).
    problem_module : str or None
        Module of a problem outside penaltyrun (``object:<name>`` for an in-memory one).
    runner : RunnerOptions
        The ``runner.*`` options.
    hashed : dict
        The resolved ``problem``, ``case``, ``param`` and ``optimizer`` nodes and the root
        ``seed``: the run's ``config_hash`` (studies deduplicate runs by it).
    config_text : str
        The whole config as YAML, recorded with every job.
    report_output : str or None
        Report folder after the run (``None``: ``<run_dir>/report``), if ``runner.report``.
    report_paper : bool
        Put the paper's numbers beside the run's in that report.
    """

    problem: str
    case: str | None
    param: str
    optimizer: str
    problem_params: dict[str, Any] = field(default_factory=dict)
    param_options: dict[str, Any] = field(default_factory=dict)
    optimizer_options: dict[str, Any] = field(default_factory=dict)
    problem_module: str | None = None
    runner: RunnerOptions = field(default_factory=RunnerOptions)
    hashed: dict[str, Any] = field(default_factory=dict)
    config_text: str = ""
    report_output: str | None = None
    report_paper: bool = True

    def build(self) -> tuple[Any, Any, Any]:
        """Validated (problem, decision layout, optimizer settings) of the cell
        (:func:`penaltyrun.runner.setup.build`: the optimizer's grid fits the dimension; a
        problem not of penaltyrun's own is first built under ``runner.job_timeout``,
        :func:`penaltyrun.runner.setup.build_within`)."""
        from penaltyrun.runner.setup import build_within

        return build_within(self.runner.job_timeout, self.problem, self.case,
                            self.problem_params, self.param, self.param_options,
                            self.optimizer, self.optimizer_options, self.problem_module)

    def warm_start_share(self) -> float:
        """Share of the budget spent on the diagonal stage (0: no warm start).

        Raises
        ------
        ConfigError
            A warm start without ``optimizer.max_evals``, or with an optimizer that has
            no budget to share.
        """
        rc = self.runner
        if not rc.warm_start:
            return 0.0
        if self.optimizer_options.get("max_evals") is None:
            raise ConfigError("runner.warm_start", "needs an evaluation budget: set "
                              "optimizer.max_evals (the diagonal stage spends "
                              "warm_start_share of it)")
        from penaltyrun.optim import OPTIMIZERS

        entry = OPTIMIZERS.get(self.optimizer)
        if entry is not None and not entry.warm_start:
            raise ConfigError("runner.warm_start", f"not for optimizer {self.optimizer!r}",
                              allowed=[n for n, o in OPTIMIZERS.items() if o.warm_start])
        return float(rc.warm_start_share)

    def plan(self, case: str, meta: Mapping[str, Any] | None = None) -> list[Job]:
        """The jobs of the cell, one per start (:func:`penaltyrun.runner.plan.plan_jobs`);
        ``case`` is the problem's resolved case, ``meta`` the run-level metadata copied
        into every record."""
        from penaltyrun.problems import user_code_params

        rc = self.runner
        code_params, file_params = user_code_params(self.problem, self.problem_module)
        return plan_jobs(
            self.problem, case, self.param, self.optimizer, n_starts=rc.n_starts,
            root_seed=int(rc.seed), problem_params=self.problem_params,
            param_options=self.param_options, optimizer_options=self.optimizer_options,
            meta=dict(meta or {}), holdout=rc.holdout,
            warm_start_share=self.warm_start_share(), problem_module=self.problem_module,
            cutoff=rc.cutoff, module_hash=user_code_hash(self.problem_module,
                                                         self.problem_params, code_params,
                                                         file_params))
