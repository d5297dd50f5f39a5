"""Figure layouts without a layout engine (tumble.output.layout): text extents estimated from the font's advances
agree with what Agg draws, and a laid-out figure keeps its texts inside and apart."""

import matplotlib
import numpy as np
import pytest
from matplotlib.backends.backend_agg import RendererAgg
from matplotlib.figure import Figure
from matplotlib.font_manager import FontProperties

from tumble.output import figures, layout

from layout_checks import misplaced


@pytest.fixture(autouse=True)
def paper_style():
    """The figures' rcParams (8-9 pt text) while a test builds, lays out and draws its figure."""
    with matplotlib.rc_context(figures._STYLE):
        yield

LABELS = ["−0.025", "300", "1.00", "$\\mathdefault{10^{-16}}$", "$\\mathdefault{4\\times10^{-1}}$", "10⁻¹⁶", "4×10⁻¹",
          "time $t$ (s)", "measured rate: $\\omega$ (rad/s) or $\\lambda$ (1/s)", "linear theory $\\sqrt{-q}$",
          "$k_1 = (I_2 - I_3)/I_1$", "$1 + 3k_1 + k_1k_3 = 4\\sqrt{k_1k_3}$", "$|L|^2/(2(I_{max}+J))$",
          "$\\ln(1/\\varepsilon)$, tilt $\\varepsilon$ in rad", "flip ($\\omega_2$ changes sign)",
          "(measured − theory) / theory ($\\times 10^{-5}$)", "gravity gradient, I = (1.935, 1, 1.039) kg m²"]


@pytest.mark.parametrize("text", LABELS)
@pytest.mark.parametrize("size", [7.0, 8.0, 9.0])
def test_text_extent_is_within_a_few_percent_of_what_agg_draws(text, size):
    dpi = 200.0
    width, height, _ = RendererAgg(10, 10, dpi).get_text_width_height_descent(text, FontProperties(size=size),
                                                                              ismath="$" in text)
    estimate = layout.text_size(text, size)
    assert 0.95 * width / dpi <= estimate[0] <= 1.1 * width / dpi  # mathtext's spacing counted generously
    assert height / dpi - 0.01 <= estimate[1] <= 1.4 * height / dpi  # never short by more than a pixel or two


def test_lines_add_up_and_empty_text_takes_no_room():
    one, two = layout.text_size("abc", 8.0), layout.text_size("abc\nabcdef", 8.0)
    assert two[0] > one[0] and two[1] > 2 * one[1]
    assert layout.text_size("", 8.0) == (0.0, 0.0)


def _log_axes(low, high):
    fig = Figure(figsize=(3.4, 2.5))
    ax = fig.subplots()
    ax.plot([low, high], [low, high])
    layout.log_scale(ax, "x")
    layout.log_scale(ax, "y")
    ax.set_xlim(low, high)
    return ax


def _labels(axis, which):
    ticker = getattr(axis, which)
    low, high = axis.get_view_interval()
    locs = [x for x in ticker.locator() if low <= x <= high]
    return locs, ticker.formatter.format_ticks(locs)


def test_log_scale_labels_decades_in_plain_text_as_matplotlib_would_in_mathtext():
    ax = _log_axes(1e-7, 1e-3)
    locs, labels = _labels(ax.xaxis, "major")
    assert np.allclose(locs, [1e-7, 1e-6, 1e-5, 1e-4, 1e-3])
    assert labels == ["10⁻⁷", "10⁻⁶", "10⁻⁵", "10⁻⁴", "10⁻³"]
    assert layout._PlainLogFormatter()(1.0) == "10⁰" and layout._PlainLogFormatter()(1e12) == "10¹²"
    # under a decade matplotlib labels the minor ticks too: 2×10⁻¹ ... in the same plain form, no "$" anywhere
    ax = _log_axes(0.15, 0.9)
    _, minor = _labels(ax.xaxis, "minor")
    assert {"2×10⁻¹", "3×10⁻¹", "6×10⁻¹"} <= set(minor) and not any("$" in text for text in minor)


def test_log_scale_thins_minor_ticks_as_the_axis_spans_more_decades():
    locs = _labels(_log_axes(0.1, 1.0).xaxis, "minor")[0]  # one decade: 2..9, as matplotlib
    assert np.allclose(locs, np.arange(2, 10) / 10)
    locs = _labels(_log_axes(1e-2, 1.0).xaxis, "minor")[0]  # two decades: 2 and 5 of each
    assert np.allclose(locs, [0.02, 0.05, 0.2, 0.5])
    assert len(_labels(_log_axes(1e-3, 1.0).xaxis, "minor")[0]) == 3 * 2  # layout.MINOR_DECADES, exactly
    assert len(_labels(_log_axes(1e-7, 1e-3).xaxis, "minor")[0]) == 0  # four decades: none
    with pytest.raises(ValueError, match="which is 'x' or 'y'"):
        layout.log_scale(_log_axes(1.0, 10.0), "z")


def test_a_label_the_plain_form_cannot_hold_is_left_as_mathtext(monkeypatch):
    assert layout._PlainLogFormatter(base=2.5)(2.5 ** 3) == "2.5³"
    odd = r"$\mathdefault{10^{0.50}}$"  # a fractional exponent has no superscript form
    monkeypatch.setattr(matplotlib.ticker.LogFormatterSciNotation, "__call__", lambda self, x, pos=None: odd)
    assert layout._PlainLogFormatter()(10 ** 0.5) == odd


def _panels(ncols=1, **kwargs):
    fig = Figure(figsize=(7.0 if ncols > 1 else 3.4, 2.5))
    axes = fig.subplots(1, ncols, squeeze=False, **kwargs)[0]
    for ax in axes:
        ax.plot([1e-3, 1e4], [1e-16, 1.0])
        ax.set(xscale="log", yscale="log", xlabel="time $t$ (s)", ylabel="relative drift\n(zero at $10^{-17}$)")
    return fig, axes


def test_a_row_of_panels_with_a_legend_at_the_right_and_a_colour_bar():
    fig, axes = _panels(3)
    axes[1].set_title("a title much wider than its own panel, standing out at both sides")
    layout.colorbar(fig, matplotlib.cm.ScalarMappable(cmap="viridis"), label="growth rate / spin rate")
    layout.legend(fig, axes[0].lines, "right")
    fig.suptitle("and a suptitle over all")
    assert misplaced(layout.fit(fig)) == []
    assert fig.get_layout_engine() is None


def test_a_title_wider_than_its_panel_moves_the_panels_into_the_figure():
    fig, (ax,) = _panels()
    ax.set_title("heavy top, I = (1, 1, 1.5) kg m², mgl = 1 N m")
    layout.fit(fig)
    assert misplaced(fig) == []
    assert ax.get_position().width * fig.get_figwidth() < layout.text_size(ax.get_title(), 9.0)[0]


def test_panels_of_a_fixed_aspect_leave_no_empty_band():
    fig = Figure(figsize=(7.0, 3.0))
    axes = fig.subplots(1, 3, sharey=True)
    for ax in axes:
        ax.plot([0, 1], [0.5, 1.0])
        ax.set(aspect="equal", xlim=(0, 1), ylim=(0.5, 1.0), xlabel="x", title="panel")
    layout.fit(fig)
    width, height = fig.get_size_inches()
    box = axes[0].get_position()
    assert box.width * width * 0.5 == pytest.approx(box.height * height, rel=1e-3), "the box has the data's aspect"
    assert height < 3.0
    assert misplaced(fig) == []


def test_fit_refuses_what_it_cannot_lay_out():
    with pytest.raises(ValueError, match="panels"):
        layout.fit(Figure())
    fig = Figure(figsize=(1.0, 0.5))
    fig.subplots().set(xlabel="a label", ylabel="a label", title="a title")
    with pytest.raises(ValueError, match="no room"):
        layout.fit(fig)
    with pytest.raises(ValueError, match="below"):
        layout.legend(Figure(), [], "above")


def test_a_grid_of_panels_keeps_rows_and_columns_apart():
    fig = Figure(figsize=(7.0, 4.0))
    panels = fig.subplots(2, 2)
    for k, ax in enumerate(panels.ravel()):
        ax.plot(np.arange(10) * 10.0**k, np.arange(10))
        ax.set(xlabel="time (s)", ylabel=f"quantity {k} (units)", title=f"panel {k}")
    assert misplaced(layout.fit(fig)) == []
