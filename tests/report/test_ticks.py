"""Plain-text log tick labels: the same ticks and numbers as matplotlib's, no mathtext."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.mathtext  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from penaltyrun.report.tables import save_figure  # noqa: E402
from penaltyrun.report.ticks import PlainLogFormatter, plain_log_labels, plain_text  # noqa: E402


@pytest.mark.parametrize(("label", "plain"), [
    (r"$\mathdefault{10^{-3}}$", "10⁻³"),
    (r"$\mathdefault{10^{12}}$", "10¹²"),
    (r"$\mathdefault{2\times10^{4}}$", "2×10⁴"),
    (r"$\mathdefault{-10^{5}}$", "−10⁵"),
    (r"$\mathdefault{0.5}$", "0.5"),
    (r"$\mathdefault{0}$", "0"),
    ("", ""),
    ("plain", "plain"),
])
def test_plain_text(label, plain):
    assert plain_text(label) == plain


def _value(plain: str) -> float:
    """The number a plain label writes (inverse of the superscripts)."""
    digits = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻", "0123456789-")
    text = plain.replace("−", "-")
    if "10" in text and any(c in text for c in "⁰¹²³⁴⁵⁶⁷⁸⁹"):
        head, _, power = text.rpartition("10")
        coeff = float(head.rstrip("×")) if head.strip("-×") else (-1.0 if head == "-" else 1.0)
        return coeff * 10.0 ** int(power.translate(digits))
    return float(text)


@given(st.integers(-30, 30), st.sampled_from([1, 2, 3, 5]), st.booleans())
def test_labels_write_the_same_numbers(exponent, coeff, negative):
    """Every label the formatter gives names the tick's value, as the mathtext one does."""
    x = (-1 if negative else 1) * coeff * 10.0 ** exponent
    mathtext = matplotlib.ticker.LogFormatterSciNotation(labelOnlyBase=False)
    plain = PlainLogFormatter(labelOnlyBase=False)
    expected = mathtext(x)
    got = plain(x)
    assert "$" not in got
    assert bool(got) == bool(expected)
    if got:
        assert math.isclose(_value(got), x, rel_tol=1e-9)


def test_figure_formatters_swapped_with_their_settings():
    fig, (a, b) = plt.subplots(1, 2)
    a.loglog([1e-3, 1e3], [1e-2, 1e5])
    b.set_xscale("symlog", linthresh=1.0)
    b.plot([-100, 100], [0, 1])
    before = a.yaxis.get_minor_formatter()
    plain_log_labels(fig)
    for axis in (a.xaxis, a.yaxis, b.xaxis):
        assert type(axis.get_major_formatter()) is PlainLogFormatter
    after = a.yaxis.get_minor_formatter()
    assert type(after) is PlainLogFormatter
    assert after.labelOnlyBase == before.labelOnlyBase
    assert after.minor_thresholds == before.minor_thresholds
    assert type(b.yaxis.get_major_formatter()) is matplotlib.ticker.ScalarFormatter
    fig.canvas.draw()
    labels = [t.get_text() for ax in (a, b) for t in ax.get_xticklabels()
              + ax.get_yticklabels()]
    assert labels and not any("$" in t for t in labels)
    assert "10⁻²" in labels or "10⁻¹" in labels
    plt.close(fig)


def test_saving_a_log_figure_parses_no_mathtext(tmp_path, monkeypatch):
    calls = []
    parse = matplotlib.mathtext.MathTextParser.parse

    def counting(self, *args, **kwargs):
        calls.append(args[0])
        return parse(self, *args, **kwargs)

    monkeypatch.setattr(matplotlib.mathtext.MathTextParser, "parse", counting)
    fig, ax = plt.subplots()
    ax.loglog(np.geomspace(1e-6, 1e-3, 4), np.geomspace(1e-4, 10, 4), "o-")
    ax.set_title("log-log")
    path = save_figure(fig, tmp_path / "f.png")
    assert path.is_file() and path.stat().st_size > 0
    assert calls == []


def test_minor_ticks_thinned_to_1_2_5_only_on_axes_of_two_decades_or_more():
    from penaltyrun.report.ticks import THIN_SUBS, thin_log_minor_ticks

    fig = plt.figure(figsize=(12, 5))
    wide, narrow, linear = (fig.add_subplot(1, 3, k) for k in (1, 2, 3))
    wide.loglog([1.0, 1e3], [1e-3, 1.0])
    narrow.semilogy([0.0, 1.0], [0.02, 0.09])  # less than a decade: minor ticks labelled
    linear.plot([0, 1], [0, 1])
    fig.canvas.draw()
    narrow_labels = [t.get_text() for t in narrow.yaxis.get_minorticklabels()]
    assert len(wide.xaxis.get_minor_locator()()) > 12  # 2, 3, ..., 9 in each decade
    thin_log_minor_ticks(fig)
    for axis in (wide.xaxis, wide.yaxis):
        minor = axis.get_minor_locator()
        assert type(minor) is matplotlib.ticker.LogLocator
        locs = [v for v in minor() if axis.get_view_interval()[0] <= v
                <= axis.get_view_interval()[1]]
        mantissas = {round(v / 10 ** math.floor(math.log10(v)), 6) for v in locs}
        assert mantissas == set(THIN_SUBS)
    assert len(narrow.yaxis.get_minor_locator()()) > 2  # untouched
    fig.canvas.draw()
    assert [t.get_text() for t in narrow.yaxis.get_minorticklabels()] == narrow_labels
    assert any(narrow_labels)
    assert type(linear.xaxis.get_minor_locator()) is matplotlib.ticker.NullLocator
    plt.close(fig)
