"""What the tests of the figures share: a figure drawn keeps every text inside itself and apart from the others.

:func:`misplaced` renders a figure with Agg and measures what :mod:`tumble.output.layout` only estimated: each
panel's frame, each axis with its ticks, tick labels and label, each title, each legend outside the panels and the
suptitle. It names every box that leaves the figure and every two that overlap (an axis and its own frame meet, as
do a panel's two axes at its corner: those pairs are not compared).
"""

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.transforms import Bbox

from tumble.output import figures as plots


def boxes(fig, renderer):
    """The boxes (display units) of what must neither leave the figure nor overlap, by name."""
    found = {}
    for i, ax in enumerate(fig.axes):
        if ax.name == "3d":
            continue
        found[(i, "frame")] = ax.get_window_extent(renderer)
        for side, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            box = axis.get_tightbbox(renderer)
            if box is not None and box.width > 0:
                found[(i, side)] = box
        for title in (ax.title, ax._left_title, ax._right_title):
            if title.get_text():
                found[(i, "title")] = title.get_window_extent(renderer)
    for k, legend in enumerate(fig.legends):
        found[("legend", k)] = legend.get_window_extent(renderer)
    if fig.get_suptitle():
        found[("suptitle", 0)] = fig._suptitle.get_window_extent(renderer)
    return found


def misplaced(fig, dpi=100, style=plots._STYLE):
    """Texts of ``fig`` (drawn at ``dpi`` under the rcParams ``style``, as it is saved) that leave the figure or
    overlap: a list of messages, empty when the layout is right. One pixel of slack."""
    fig.set_dpi(dpi)
    canvas = FigureCanvasAgg(fig)
    with matplotlib.rc_context(style):
        canvas.draw()
        found = boxes(fig, canvas.get_renderer())
    width, height = fig.bbox.width, fig.bbox.height
    wrong = [f"{name} leaves the figure" for name, box in found.items()
             if box.x0 < -1 or box.y0 < -1 or box.x1 > width + 1 or box.y1 > height + 1]
    names = list(found)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            if a[0] == b[0] and {a[1], b[1]} in ({"frame", "x"}, {"frame", "y"}, {"x", "y"}):
                continue
            overlap = Bbox.intersection(found[a], found[b])
            if overlap is not None and overlap.width > 1 and overlap.height > 1:
                wrong.append(f"{a} overlaps {b}")
    return wrong
