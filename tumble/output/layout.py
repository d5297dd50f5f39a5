"""Figure layouts without a layout engine: every margin in inches, from the text it has to hold.

matplotlib's constrained layout measures every axes' decorations with a renderer and solves for the margins at
each ``savefig``, after a first draw done only for it: half of a tumble figure's 0.3-0.6 s ``savefig``. The
figures here are simple — a row or a grid of panels, an optional colour bar at the right, an optional legend
below or at the right of the panels — so :func:`fit` places them in one pass with no renderer: the extent of
each text (tick labels from the axis' own locator and formatter, axis labels, titles, legend entries) is
estimated from the font's glyph advances (FreeType, as the Agg backend measures text) and mathtext is counted
glyph by glyph, scripts at 70 %. The margins are those sums; a figure with a legend below grows by the legend's
height, as it did under constrained layout.

:func:`log_scale` makes the figures' log axes: matplotlib's decade labels in plain text with Unicode superscripts
(no mathtext to parse and draw glyph by glyph) and fewer minor ticks as the axis spans more decades.

Used by :mod:`tumble.output.figures`, :mod:`tumble.output.attitude_figures` (herpolhode) and
:mod:`tumble.output.check_figure`. The tests render every figure with Agg and check that no text leaves the
figure and that no two of its texts, panels and legends overlap (``tests/layout_checks.py``); the estimates are
held within a few percent of Agg's own measure (``tests/test_layout.py``).
"""

from __future__ import annotations

import functools
import re
from typing import NamedTuple

import matplotlib
import numpy as np
from matplotlib import font_manager, ft2font, ticker
from matplotlib.font_manager import FontProperties

__all__ = ["EDGE", "MINOR_DECADES", "colorbar", "fit", "legend", "log_scale", "text_size"]

#: White space kept at the figure's edges and between a panel's decorations and what sits beside them, inches.
EDGE = 0.05
_GAP = 0.08  # between neighbouring panels' decorations, and between the panels and a colour bar or legend
_COLORBAR_WIDTH = 0.11  # inches
_SETTLED = 0.005  # inches: margins that moved less than this from one pass to the next are kept (a pixel at 200 dpi)
_SCRIPT = 0.7  # mathtext sub- and superscripts, relative to the text size

# mathtext, counted glyph by glyph: commands drawn as nothing, as one glyph, and the binary operators and relations
# that mathtext sets off by spaces (0.2 em at each side)
_SILENT = re.compile(r"\\(?:mathdefault|mathrm|mathbf|mathit|mathsf|mathcal|left|right|displaystyle|hat|bar|"
                     r"tilde|vec|dot)\b\s?")
_GLYPHS = {"times": "×", "cdot": "·", "pm": "±", "mp": "∓", "approx": "≈", "leq": "≤", "geq": "≥", "neq": "≠",
           "sqrt": "√", "ln": "ln", "log": "log", "exp": "exp", "sin": "sin", "cos": "cos", "max": "max",
           "min": "min"}
_COMMAND = re.compile(r"\\([A-Za-z]+)\s?")
_SCRIPTS = re.compile(r"[_^](\{[^{}]*\}|\\[A-Za-z]+|.)")
_OPERATORS = "+−=×·±∓≈≤≥≠<>"
_TALL = re.compile(r"\\(?:sqrt|hat|bar|tilde|vec|dot|frac)")
_PLAIN_LINE = 1.0  # height of a line of DejaVu Sans ("lp": ascent + descent), in units of the font size
_SCRIPT_LINE = 1.25  # ... of mathtext with sub- or superscripts
_TALL_LINE = 1.5  # ... with a root, an accent or a fraction
_LINE_SPACING = 1.2  # matplotlib's spacing of multi-line text
_NO_HINTING = ft2font.LoadFlags.NO_HINTING if hasattr(ft2font, "LoadFlags") else ft2font.LOAD_NO_HINTING


@functools.lru_cache(maxsize=None)
def _char_advance(char):
    """Advance of ``char`` in the default sans-serif font (what Agg draws text in), inches per point of size."""
    font = font_manager.get_font(font_manager.findfont(FontProperties()))
    font.set_size(100.0, 72.0)  # Agg sets the size again before it draws with this (shared) font
    return font.load_char(ord(char), flags=_NO_HINTING).linearHoriAdvance / 65536.0 / 100.0 / 72.0


def _advance(text, size):
    """Width, inches, of plain ``text`` at ``size`` points: the sum of its glyphs' advances (kerning left out:
    under 1 % of a label's width)."""
    return size * sum(_char_advance(char) for char in text)


def _glyphs(expr):
    """Plain glyphs of a mathtext expression (commands as their symbols, "-" as the minus sign), and the number
    of binary operators or relations in it that mathtext spaces out (not one that starts it: a sign)."""
    expr = _COMMAND.sub(lambda m: _GLYPHS.get(m.group(1), "x"), expr).replace("-", "−")
    # mathtext draws no spaces but those asked for (\, \; \ ): their widths are near enough one space's
    expr = re.sub(r"\\[,;: ]", "\0", expr).replace("\\!", "").replace(" ", "").replace("\0", " ")
    expr = expr.replace("{", "").replace("}", "")
    body = expr.lstrip()
    return expr, sum(body[1:].count(op) for op in _OPERATORS)


def _math_size(expr, size):
    """``(width, height)`` in inches of one mathtext expression (without its ``$``) at ``size`` points."""
    tall = bool(_TALL.search(expr))
    expr = _SILENT.sub("", expr)
    scripts = []

    def script(match):
        scripts.append(match.group(1).strip("{}"))
        return ""

    full, operators = _glyphs(_SCRIPTS.sub(script, expr))
    small = [_glyphs(text)[0] for text in scripts]
    width = _advance(full, size) + sum(_advance(text, size * _SCRIPT) for text in small)
    width += (operators * 0.4 + len(scripts) * 0.08) * size / 72.0  # spaces around operators, after scripts
    line = _TALL_LINE if tall else _SCRIPT_LINE if scripts else _PLAIN_LINE
    return 1.03 * width, line * size / 72.0  # italic letters run a little wider than upright ones


def _line_size(line, size):
    """``(width, height)`` in inches of one line of text that may hold ``$...$`` mathtext."""
    parts = line.split("$")
    if len(parts) % 2 == 0:  # an unpaired $: matplotlib draws the text as it is
        parts = [line]
    width, height = 0.0, _PLAIN_LINE * size / 72.0
    for i, part in enumerate(parts):
        if i % 2 == 0:
            width += _advance(part, size)
        else:
            w, h = _math_size(part, size)
            width, height = width + w, max(height, h)
    return width, height


def text_size(text, size):
    """Estimated extent of ``text`` drawn at ``size`` points, inches: ``(width, height)`` (unrotated).

    Parameters
    ----------
    text : str
        Plain text or matplotlib mathtext (``$...$``), one line or several.
    size : float
        Font size, points.

    Returns
    -------
    (float, float)
        Width of the longest line, and the height of all lines with matplotlib's line spacing.
    """
    if not text:
        return 0.0, 0.0
    sizes = [_line_size(line, size) for line in text.split("\n")]
    height = sum(h for _, h in sizes) + (len(sizes) - 1) * (_LINE_SPACING - 1.0) * _PLAIN_LINE * size / 72.0
    return max(w for w, _ in sizes), height


def _points(value):
    """A font size (number or name such as ``"medium"``) in points, under the current rcParams."""
    return FontProperties(size=value).get_size_in_points()


def _tick_labels(axis):
    """The tick labels ``axis`` draws (major and minor, within its view) as ``(texts, fractions along the axis)``,
    from its locator and formatter: no tick objects, no renderer; and the offset text ("1e-5", "+1e3") or ""."""
    low, high = sorted(axis.get_view_interval())
    span = (high - low) or 1.0
    texts, where, offset = [], [], ""
    for locator_side in ("major", "minor"):
        ticker = getattr(axis, locator_side)
        locs = np.asarray(ticker.locator(), dtype=float)
        locs = locs[(locs >= low - 1e-10 * span) & (locs <= high + 1e-10 * span)]
        if not locs.size:
            continue
        labels = ticker.formatter.format_ticks(locs)
        if locator_side == "major" and hasattr(ticker.formatter, "get_offset"):
            offset = ticker.formatter.get_offset()
        shown = [i for i, text in enumerate(labels) if text]
        texts += [labels[i] for i in shown]
        where.append(locs[shown])
    locs = np.concatenate(where) if where else np.zeros(0)
    ax = axis.axes
    points = np.column_stack([locs, np.zeros_like(locs)] if axis is ax.xaxis else [np.zeros_like(locs), locs])
    along = (ax.transScale + ax.transLimits).transform(points)[:, 0 if axis is ax.xaxis else 1] if locs.size else locs
    return texts, along, offset


def _label_size(axis, side):
    """Font size, points, of ``axis``' tick labels (as the ticks will be made at draw time)."""
    params = axis._major_tick_kw  # noqa: SLF001 - what tick_params set; else the rcParams decide at draw time
    return _points(params.get("labelsize", matplotlib.rcParams[f"{side}tick.labelsize"]))


def _tick_room(axis, side):
    """Inches from the axes' spine to the far side of its tick labels (tick, pad, labels); how far the labels
    stand out beyond the axis' low and high ends (at the axes' present size); their size, points; and the offset
    text."""
    labelled = axis.get_tick_params()
    ticks = [key for key in (("left", "right") if side == "y" else ("bottom", "top")) if labelled.get(key)]
    shown = [key for key in (("labelleft", "labelright") if side == "y" else ("labelbottom", "labeltop"))
             if labelled.get(key)]
    rc = matplotlib.rcParams
    tick = (max(rc[f"{side}tick.major.size"], 0.0) if ticks and rc[f"{side}tick.direction"] != "in" else 0.0)
    if not shown:
        return tick / 72.0, 0.0, 0.0, 0.0, ""
    texts, fractions, offset = _tick_labels(axis)
    if not texts:
        return tick / 72.0, 0.0, 0.0, 0.0, ""
    size = _label_size(axis, side)
    extents = np.array([text_size(t, size) for t in texts])
    across, along = (extents[:, 0], extents[:, 1]) if side == "y" else (extents[:, 1], extents[:, 0])
    box = axis.axes.get_position()
    length = box.height * axis.figure.get_figheight() if side == "y" else box.width * axis.figure.get_figwidth()
    low = max(0.0, np.max(along / 2 - fractions * length))
    high = max(0.0, np.max(along / 2 - (1 - fractions) * length))
    return (tick + rc[f"{side}tick.major.pad"]) / 72.0 + across.max(), low, high, size, offset


def _decorations(ax):
    """Inches that ``ax``'s own texts take beyond its box: ``left, bottom, right, top``, and the width of its
    title (centred on the box)."""
    labelpad = matplotlib.rcParams["axes.labelpad"] / 72.0
    y_room, _, y_high, y_size, y_offset = _tick_room(ax.yaxis, "y")
    x_room, x_low, x_high, x_size, x_offset = _tick_room(ax.xaxis, "x")
    ylabel = ax.yaxis.label.get_text()
    xlabel = ax.xaxis.label.get_text()
    # a rotated y label's thickness is its height; the end x tick labels may stand out at the left and right
    left = max(x_low, y_room + (labelpad + text_size(ylabel, ax.yaxis.label.get_size())[1] if ylabel else 0.0))
    bottom = x_room + (labelpad + text_size(xlabel, ax.xaxis.label.get_size())[1] if xlabel else 0.0)
    if x_offset:
        bottom += text_size(x_offset, x_size)[1]
    right = x_high
    top = y_high  # the top y tick label may stand out at the top
    title_width = 0.0
    titles = [t for t in (ax.title, ax._left_title, ax._right_title) if t.get_text()]  # noqa: SLF001
    if titles:
        width, height = zip(*(text_size(t.get_text(), t.get_size()) for t in titles))
        top = max(top, matplotlib.rcParams["axes.titlepad"] / 72.0 + max(height))
        title_width = max(width)
    if y_offset:  # above the axes at its left end; a title is raised above it
        top += text_size(y_offset, y_size)[1] + (2.0 / 72.0 if titles else 0.0)
    return left, bottom, right, top, title_width


def _legend_size(leg):
    """Estimated ``(width, height)`` of a legend, inches, from its texts and matplotlib's legend geometry."""
    texts = leg.get_texts()
    fontsize = texts[0].get_size() if texts else _points(matplotlib.rcParams["legend.fontsize"])
    em = fontsize / 72.0
    sizes = [text_size(t.get_text(), t.get_size()) for t in texts]
    ncols = max(1, min(leg._ncols, len(sizes)))  # noqa: SLF001 - the ncols it was made with
    columns = [c for c in np.array_split(np.arange(len(sizes)), ncols) if len(c)]
    entry = (leg.handlelength + leg.handletextpad) * em
    width = sum(entry + max(sizes[i][0] for i in column) for column in columns)
    width += (len(columns) - 1) * leg.columnspacing * em + 2 * leg.borderpad * em
    rows = max(len(c) for c in columns)
    heights = [max(max(sizes[i][1] for i in column[r:r + 1]) if r < len(column) else 0.0 for column in columns)
               for r in range(rows)]
    height = sum(max(h, leg.handleheight * em) for h in heights) + (rows - 1) * leg.labelspacing * em
    return width, height + 2 * leg.borderpad * em


def legend(fig, handles, where="below", **kwargs):
    """A figure legend outside the panels, ``where`` = ``"below"`` (in as many columns as the figure's width
    holds, unless ``ncols`` is given) or ``"right"``; :func:`fit` makes its room. Returns the legend.

    Keyword arguments go to :meth:`matplotlib.figure.Figure.legend` (``ncols``, ``fontsize``, ...).
    """
    if where not in ("below", "right"):
        raise ValueError(f"a legend goes 'below' or 'right', not {where!r}")
    loc = "lower center" if where == "below" else "upper right"
    if where == "below" and "ncols" not in kwargs:
        room = fig.get_figwidth() - 2 * EDGE
        probe = fig.legend(handles=handles, loc=loc, ncols=1, **kwargs)
        ncols = 1
        for n in range(len(handles), 1, -1):
            probe._ncols = n  # noqa: SLF001 - measure the same legend in n columns
            if _legend_size(probe)[0] <= room:
                ncols = n
                break
        probe.remove()
        kwargs["ncols"] = ncols
    leg = fig.legend(handles=handles, loc=loc, borderaxespad=0.0, **kwargs)
    leg._tumble_where = where  # noqa: SLF001 - read by fit()
    return leg


#: Minor ticks of a log axis: 2 to 9 in each decade where it spans at most one (matplotlib labels them there), 2 and 5
#: where it spans at most this many decades, none beyond: dense minor ticks read as a grey band, and each costs
#: about 1 ms to make and draw (a scan summary: 72 of them, a third of its drawing time, before this rule).
MINOR_DECADES = 3

_MATHTEXT_LABEL = re.compile(r"\$\\mathdefault\{(.*)\}\$")
_EXPONENT = re.compile(r"\^\{(-?\d+)\}")
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


class _PlainLogFormatter(ticker.LogFormatterSciNotation):
    """matplotlib's log-axis labels (10⁻³, 2×10⁻³) as plain text with Unicode superscripts instead of mathtext: the
    same look in DejaVu Sans, without mathtext's parse and glyph-by-glyph drawing (3-6 ms a label in a process
    that draws once). A label of another form is left as matplotlib makes it."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _MATHTEXT_LABEL.fullmatch(label)
        if match is None:
            return label
        plain = _EXPONENT.sub(lambda m: m.group(1).translate(_SUPERSCRIPT), match.group(1).replace("\\times", "×"))
        return label if any(c in plain for c in "\\^{}$") else plain.replace("-", "−")


class _MinorLogLocator(ticker.LogLocator):
    """Minor ticks of a log axis by its span (:data:`MINOR_DECADES`)."""

    def tick_values(self, vmin, vmax):
        decades = abs(np.log10(vmax / vmin)) if vmin > 0 and vmax > 0 else 0.0
        if decades > MINOR_DECADES:
            return np.array([])
        self.set_params(subs="auto" if decades <= 1 else (2.0, 5.0))
        return super().tick_values(vmin, vmax)


def log_scale(ax, which="y"):
    """Put ``ax``'s ``which`` ("x" or "y") axis on a base-10 log scale whose labels are plain text
    (:class:`_PlainLogFormatter`) and whose minor ticks thin out as it spans more decades (:data:`MINOR_DECADES`).
    Call it after plotting: ``semilogy`` and ``set_yscale`` put matplotlib's own locators and formatters back."""
    if which not in ("x", "y"):
        raise ValueError(f"which is 'x' or 'y', not {which!r}")
    (ax.set_xscale if which == "x" else ax.set_yscale)("log")
    axis = ax.xaxis if which == "x" else ax.yaxis
    axis.set_major_formatter(_PlainLogFormatter())
    axis.set_minor_formatter(_PlainLogFormatter(labelOnlyBase=False))
    axis.set_minor_locator(_MinorLogLocator(subs="auto"))


def colorbar(fig, mappable, **kwargs):
    """A colour bar at the right of the panels, in an axes :func:`fit` places; keyword arguments go to
    :meth:`matplotlib.figure.Figure.colorbar` (``label``, ...). Returns the colour bar."""
    cax = fig.add_axes((0.9, 0.1, 0.02, 0.8), label="<colorbar>")
    bar = fig.colorbar(mappable, cax=cax, **kwargs)
    cax._tumble_colorbar = True  # noqa: SLF001 - read by fit()
    return bar


def _grid(fig):
    """The grid (gridspec) of the figure's panels, and the panels: every axes made by ``Figure.subplots``."""
    panels = [ax for ax in fig.axes if ax.get_subplotspec() is not None and ax.get_label() != "<colorbar>"]
    if not panels:
        raise ValueError("fit() lays out panels made by Figure.subplots or add_subplot; this figure has none")
    specs = {id(ax.get_subplotspec().get_gridspec()) for ax in panels}
    if len(specs) != 1:
        raise ValueError("fit() lays out the panels of one grid")
    return panels[0].get_subplotspec().get_gridspec(), panels


class _Parts(NamedTuple):
    """What :func:`fit` places: the panels of one grid and what stands around them."""

    panels: list  # the axes of the grid
    shape: tuple  # (rows, columns) of the grid
    below: list  # legends below the panels, made by legend()
    below_height: float  # inches they take, with the gap above them
    right: list  # legends at the right of the panels
    bars: list  # colour bars' axes, made by colorbar()


def fit(fig):
    """Place the panels, colour bar and outside legend of ``fig`` with margins that hold their texts; no layout
    engine is set, so ``savefig`` draws the figure once. Returns ``fig``.

    The panels are those of one grid (``Figure.subplots``); a colour bar made by :func:`colorbar` stands at their
    right over their full height; a legend made by :func:`legend` sits below the panels (the figure grows by its
    height) or at their right, top-aligned with them; ``Figure.suptitle`` text sits above all. Call it last, once
    every text is set (inside the same ``rc_context`` as the drawing, so that tick label sizes are those drawn).
    """
    gridspec, panels = _grid(fig)
    if any(getattr(gridspec, name) is not None for name in ("left", "right", "bottom", "top", "wspace", "hspace")):
        raise ValueError("fit() sets the figure's subplot parameters: the grid must not set its own")
    where = [(leg, getattr(leg, "_tumble_where", None)) for leg in fig.legends]
    below = [leg for leg, side in where if side == "below"]
    below_height = sum(_legend_size(leg)[1] for leg in below) + (_GAP if below else 0.0)
    parts = _Parts(panels, gridspec.get_geometry(), below, below_height, [leg for leg, side in where if side == "right"],
                   [ax for ax in fig.axes if getattr(ax, "_tumble_colorbar", False)])
    width, height = fig.get_size_inches()
    height += below_height
    # Tick locators choose their ticks by the length of the axis: a pass reads the ticks of the sizes the pass before
    # gave, until the margins hold (2 passes, most often). Should the ticks flip between two choices, a last pass
    # keeps the larger of each margin.
    fig.set_size_inches(width, height)
    margins = _place(fig, height, parts, np.zeros(6))
    for _ in range(3):
        placed = _place(fig, height, parts, np.zeros(6))
        if np.allclose(placed, margins, rtol=0.0, atol=_SETTLED):
            return fig
        margins, before = placed, margins
    _place(fig, height, parts, np.maximum(margins, before))
    return fig


def _margins(fig, parts):
    """Margins (inches: left, right, top, bottom, gap between columns, between rows) that hold the texts of the
    panels and what stands around them; what the last column's texts stand out at the right; the panels' titles
    as ``(subplotspec, width)``."""
    nrows, ncols = parts.shape
    left_of, right_of, top_of, bottom_of = np.zeros(ncols), np.zeros(ncols), np.zeros(nrows), np.zeros(nrows)
    titles = []
    for ax in parts.panels:
        spec = ax.get_subplotspec()
        left, bottom, right, top, title_width = _decorations(ax)
        first, last = spec.colspan.start, spec.colspan.stop - 1
        left_of[first], right_of[last] = max(left_of[first], left), max(right_of[last], right)
        top_of[spec.rowspan.start] = max(top_of[spec.rowspan.start], top)
        bottom_of[spec.rowspan.stop - 1] = max(bottom_of[spec.rowspan.stop - 1], bottom)
        titles.append((spec, title_width))
    right_extra = 0.0
    for bar in parts.bars:
        label = bar.yaxis.label.get_text()
        label_room = matplotlib.rcParams["axes.labelpad"] / 72.0 + text_size(label, bar.yaxis.label.get_size())[1]
        right_extra = max(right_extra, _GAP + _COLORBAR_WIDTH + _tick_room(bar.yaxis, "y")[0]
                          + (label_room if label else 0.0))
    legend_width = max((_legend_size(leg)[0] for leg in parts.right), default=0.0)
    if legend_width:
        right_extra += _GAP + legend_width
    suptitle = fig.get_suptitle()
    top_extra = text_size(suptitle, fig._suptitle.get_size())[1] + _GAP / 2 if suptitle else 0.0  # noqa: SLF001
    margins = [EDGE + left_of[0], EDGE + right_of[-1] + right_extra, EDGE + top_of[0] + top_extra,
               EDGE + bottom_of[-1] + parts.below_height,
               max((right_of[c - 1] + left_of[c] for c in range(1, ncols)), default=0.0) + _GAP,
               max((bottom_of[r - 1] + top_of[r] for r in range(1, nrows)), default=0.0) + _GAP]
    return np.array(margins), right_of[-1], titles


def _inside(width, ncols, left, right, wgap, titles):
    """``(left, right)`` margins moved until every title, centred on its panels, is inside the figure (a title
    wider than its panels stands out at both sides)."""
    for _ in range(8):
        panel_width = (width - left - right - (ncols - 1) * wgap) / ncols
        moved = False
        for spec, title_width in titles:
            if title_width > width - 2 * EDGE:
                continue  # wider than the figure: nothing to gain
            start, span = spec.colspan.start, spec.colspan.stop - spec.colspan.start
            centre = left + start * (panel_width + wgap) + 0.5 * (span * panel_width + (span - 1) * wgap)
            share = (start + 0.5 * span) / ncols  # how the centre moves: 1 - share per inch of left, -share of right
            out_left, out_right = EDGE - (centre - title_width / 2), centre + title_width / 2 - (width - EDGE)
            if out_left > 1e-3:
                left, moved = left + out_left / (1 - share), True
            elif out_right > 1e-3:
                right, moved = right + out_right / share, True
        if not moved:
            break
    return left, right


def _place(fig, height, parts, least):
    """One pass of :func:`fit`: ``fig`` laid out at ``height`` inches (less what panels of a fixed aspect leave
    unused), with margins no less than ``least`` (as :func:`_margins` gives them); returns the margins it set.
    Ticks are read at the figure's size as the pass before left it."""
    nrows, ncols = parts.shape
    width = fig.get_figwidth()
    margins, last_right, titles = _margins(fig, parts)
    left, right, top, bottom, wgap, hgap = np.maximum(margins, least)
    left, right = _inside(width, ncols, left, right, wgap, titles)
    panel_width = (width - left - right - (ncols - 1) * wgap) / ncols
    panel_height = (height - top - bottom - (nrows - 1) * hgap) / nrows
    if panel_width <= 0 or panel_height <= 0:
        raise ValueError(f"a {width:.2f} x {height:.2f} in figure has no room left for its panels")
    # panels of a fixed aspect (set_aspect) are drawn no taller than their width allows: the figure loses the rest
    if all(ax.get_aspect() != "auto" and ax.get_adjustable() == "box" for ax in parts.panels):
        needed = max(panel_width * ax.get_aspect() * ax.get_data_ratio() for ax in parts.panels)
        if needed < panel_height:
            height -= (panel_height - needed) * nrows
            panel_height = needed
    fig.set_size_inches(width, height)
    # the grid takes the figure's subplot parameters (Figure.subplots makes it so): setting them moves its panels
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height, top=1 - top / height,
                        wspace=wgap / panel_width, hspace=hgap / panel_height)
    for bar in parts.bars:
        x = width - right + last_right + _GAP
        bar.set_position((x / width, bottom / height, _COLORBAR_WIDTH / width, (height - top - bottom) / height))
    for leg in parts.right:
        leg.set_bbox_to_anchor((1 - EDGE / width, 1 - top / height), transform=fig.transFigure)
    offset = EDGE
    for leg in parts.below:
        leg.set_bbox_to_anchor((0.5, offset / height), transform=fig.transFigure)
        offset += _legend_size(leg)[1]
    if fig.get_suptitle():
        fig._suptitle.set_y(1 - EDGE / height)  # noqa: SLF001
        fig._suptitle.set_va("top")  # noqa: SLF001
    return np.array([left, right, top, bottom, wgap, hgap])
