"""Report checks: active bounds, non-finite evaluations, unknown statuses."""

from __future__ import annotations

import json

import pandas as pd

from penaltyrun.report import protocol
from penaltyrun.report.build import checks
from penaltyrun.report.stats import converged


def job(param, K, status="ok", n_nonfinite=0, cost=1.0):
    return {"problem": "zermelo", "case": "default", "variant": "", "problem_variant": "",
            "optimizer": "pso", "param": param, "status": status, "best_converged": True,
            "best_cost": cost, "matrices": json.dumps({"K": K}), "problem_params": "{}",
            "n_nonfinite": n_nonfinite, "n_evals": 100}


def test_active_bounds_nonfinite_and_unknown_status():
    protocol.reset()
    df = pd.DataFrame([
        job("diagonal", [[10.0, 0.0], [0.0, 0.5]], n_nonfinite=9),  # entry at the upper bound
        job("full", [[1.0, 0.0], [0.0, 1e-8]]),  # eigenvalue at the lower bound
        job("full", [[1.0, 0.0], [0.0, 1.0]], status="mystery", cost=0.1),
    ])
    lines = checks(df)
    text = "\n".join(lines)
    assert ("zermelo / default: best diagonal K (pso/diagonal): diagonal entry 10 at its "
            "upper bound 10") in text
    assert ("zermelo / default: best full K (pso/full): eigenvalue 1e-08 at its lower "
            "bound 1e-08") in text
    assert text.count("the box may be too small") == 2
    assert "9 of 100 evaluations were non-finite" in text
    assert "1 job(s) with status 'mystery', unknown to this report" in text
    assert not converged(df).iloc[2]  # an unknown status never counts as converged


def test_no_bound_flag_inside_the_box():
    protocol.reset()
    df = pd.DataFrame([job("diagonal", [[2.0, 0.0], [0.0, 0.5]]),
                       job("full", [[2.0, 0.3], [0.3, 1.0]])])
    assert not any("box may be too small" in line for line in checks(df))


def test_an_unknown_status_reaches_the_markdown_inert():
    """S5: a status carrying Markdown or HTML is escaped, never an image, link or tag."""
    protocol.reset()
    df = pd.DataFrame([job("full", [[1.0, 0.0], [0.0, 1.0]], status=s) for s in
                       ("![k](/etc/passwd)", "<script>x</script>", "[x](javascript:y)")])
    text = "\n".join(checks(df))
    assert "status '!\\[k\\](/etc/passwd)'" in text
    assert "status '\\<script\\>x\\</script\\>'" in text
    assert "](" not in text.replace("\\](", "")
