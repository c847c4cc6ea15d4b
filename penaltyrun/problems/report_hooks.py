"""The report hooks of a problem module, with their defaults (see :mod:`.base`).

A problem module may define, at module level:

* ``report_info(case: str, params: Mapping[str, Any]) -> ReportInfo`` — cost name and unit,
  what the held-out scenarios are, the paper's values (:class:`~.base.ReportInfo`);
* ``report_plots(sims: Mapping[str, Mapping[str, ndarray]], case: str, params: Mapping) ->
  dict[str, Figure]`` — figures from ``Problem.simulate`` dicts, keyed by a label such as
  ``"best diagonal (de)"``; the dict keys are the figures' captions;
* ``report_sections(jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]`` — extra
  sections from the problem's jobs as plain dicts (:func:`job_keys` lists their keys).

A module without ``report_info`` may still declare ``COST_NAME`` (or ``COST_LABEL``) and
``COST_UNIT`` as constants. Without any of them the report uses :data:`DEFAULT_INFO`
(cost "cost", unit not declared), plots
every time history ``simulate`` returns (:func:`default_plots`) and adds no section. Only
numpy and (lazily) matplotlib are used here: no pandas, no Hydra.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import ModuleType
from typing import Any

import numpy as np

from penaltyrun.problems.base import ReportInfo, ReportSection

DEFAULT_INFO = ReportInfo()
#: Most panels the default plot draws (one per simulated quantity).
MAX_PANELS = 6


def job_keys() -> tuple[str, ...]:
    """Keys of the job dicts passed to ``report_sections`` (values are plain Python / numpy).

    ``problem``, ``case``, ``variant`` (label of the non-default settings), ``optimizer``,
    ``param`` (map), ``family`` (``diagonal`` / ``full``), ``start``, ``status``,
    ``converged`` (bool: a converged start), ``best_cost``, ``n_evals``, ``max_evals``,
    ``stop_reason``, ``matrices`` ({name: ndarray}), ``scalars``, ``metrics``, ``holdout``,
    ``problem_params``, ``optimizer_settings`` (dicts; ``None`` when absent).
    """
    return ("problem", "case", "variant", "optimizer", "param", "family", "start", "status",
            "converged", "best_cost", "n_evals", "max_evals", "stop_reason", "matrices",
            "scalars", "metrics", "holdout", "problem_params", "optimizer_settings")


def declared_info(mod: ModuleType | None) -> ReportInfo:
    """:class:`ReportInfo` from module constants, for a module without ``report_info``:
    ``COST_NAME`` (or ``COST_LABEL``, its trailing ``(<COST_UNIT>)`` removed) and
    ``COST_UNIT``; :data:`DEFAULT_INFO` without them."""
    unit = getattr(mod, "COST_UNIT", None)
    name = getattr(mod, "COST_NAME", None) or getattr(mod, "COST_LABEL", None)
    if not isinstance(name, str) and not isinstance(unit, str):
        return DEFAULT_INFO
    name = name if isinstance(name, str) else DEFAULT_INFO.cost_name
    unit = unit if isinstance(unit, str) else ""
    if unit and name.endswith(f"({unit})"):
        name = name[: -len(unit) - 2].rstrip()
    return ReportInfo(cost_name=name, cost_unit=unit)


def info(mod: ModuleType | None, case: str, params: Mapping[str, Any]) -> ReportInfo:
    """``mod.report_info(case, params)``, or :func:`declared_info` without the hook."""
    hook = getattr(mod, "report_info", None)
    if hook is None:
        return declared_info(mod)
    result = hook(case, dict(params))
    if not isinstance(result, ReportInfo):
        raise TypeError(f"report_info returned {type(result).__name__}, not ReportInfo")
    return result


def plots(mod: ModuleType | None, sims: Mapping[str, Mapping[str, np.ndarray]], case: str,
          params: Mapping[str, Any]) -> dict[str, Any]:
    """``mod.report_plots(sims, case, params)``, or :func:`default_plots`."""
    if not sims:
        return {}
    hook = getattr(mod, "report_plots", None)
    if hook is None:
        return default_plots(sims)
    return dict(hook(sims, case, dict(params)))


def sections(mod: ModuleType | None, jobs: Sequence[Mapping[str, Any]]) -> list[ReportSection]:
    """``mod.report_sections(jobs)``, or no section."""
    hook = getattr(mod, "report_sections", None)
    return [] if hook is None or not jobs else list(hook(jobs))


def _histories(sim: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays of a simulate dict sampled on its time grid ``t``, as (n, k) arrays."""
    t = np.asarray(sim.get("t", ()), float)
    out = {}
    for key, value in sim.items():
        arr = np.asarray(value)
        if key == "t" or arr.dtype.kind not in "fiub" or arr.ndim not in (1, 2):
            continue
        if arr.shape[0] == t.size and t.size > 1:
            out[key] = arr.reshape(t.size, -1).astype(float)
    return out


def default_plots(sims: Mapping[str, Mapping[str, np.ndarray]]) -> dict[str, Any]:
    """Every time history of the ``simulate`` dicts against ``t``, one panel per quantity.

    Parameters
    ----------
    sims : mapping label → simulate dict (``t`` plus arrays of shape (n,) or (n, k))

    Returns
    -------
    dict
        ``{"time histories": Figure}``, or ``{}`` when no dict has a time grid.
    """
    import matplotlib.pyplot as plt

    series = {label: _histories(sim) for label, sim in sims.items()}
    keys = sorted({k for h in series.values() for k in h})[:MAX_PANELS]
    if not keys:
        return {}
    fig, axes = plt.subplots(len(keys), 1, figsize=(8, 2.2 * len(keys) + 0.6), sharex=True,
                             squeeze=False)
    styles = ("-", "--", ":", "-.")
    for ax, key in zip(axes[:, 0], keys):
        for k, (label, hist) in enumerate(series.items()):
            if key not in hist:
                continue
            t = np.asarray(sims[label]["t"], float)
            data = hist[key]
            for j in range(data.shape[1]):
                name = f"{label}" + (f" [{j}]" if data.shape[1] > 1 else "")
                ax.plot(t, data[:, j], styles[k % len(styles)], color=f"C{j % 10}",
                        label=name)
        ax.set_ylabel(key)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=9)
    axes[-1, 0].set_xlabel("t")
    fig.suptitle("Closed-loop histories from the problem's simulate()")
    return {"time histories": fig}


__all__ = ["DEFAULT_INFO", "declared_info", "default_plots", "info", "job_keys", "plots",
           "sections"]
