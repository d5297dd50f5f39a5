"""The figure of a ``tumble check`` result: a recorded trajectory against the exact torque-free solution.

Four panels over time, from the dataset alone (:func:`tumble.check` makes it): the angular velocity, recorded
(solid) and exact (dashed); the angular-velocity and attitude errors; the drift of energy and of the angular
momentum (magnitude and, with the attitude, direction); each measured flip's time minus the exact one.
"""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from . import io, layout
from .figures import DOUBLE

__all__ = ["draw_check", "save_check_figure"]

_FLOOR = 1e-17  # plotted in place of exact zeros on log axes
_STYLE = {"font.size": 8}  # the tick labels' size (rcParams when the figure is saved)
_POINTS = 2000  # most points a curve draws: a 100 000-sample recording draws in half the time (1.6 s against 3.0)


def _every(n):
    """The stride that keeps at most :data:`_POINTS` of ``n`` samples."""
    return max(1, -(-n // _POINTS))


def _envelope(t, values):
    """``(t, max |values|)`` over windows of :func:`_every` samples: no peak of an error curve is lost."""
    step = _every(values.size)
    size = values.size // step * step
    peaks = np.abs(values[:size]).reshape(-1, step).max(axis=1)
    if size < values.size:
        peaks = np.append(peaks, np.abs(values[size:]).max())
    return t[::step][:peaks.size], np.maximum(peaks, _FLOOR)


def _log_panel(ax, t, ds, title, curves):
    """One panel of small positive series over time, log scale: the envelope (:func:`_envelope`) of each of
    ``curves`` ((name, label) pairs) that ``ds`` holds."""
    for name, label in curves:
        if name in ds:
            ax.plot(*_envelope(t, ds[name].values), lw=1.0, label=label)
    if ax.lines:
        layout.log_scale(ax, "y")
    ax.set(xlabel="time (s)", title=title)
    ax.legend(fontsize=7)


def draw_check(ds):
    """The four-panel :class:`matplotlib.figure.Figure` of a check result ``ds``."""
    fig = Figure(figsize=(DOUBLE, 5.2))
    (ax_w, ax_err), (ax_drift, ax_flip) = fig.subplots(2, 2)
    t = ds.time.values
    every = _every(t.size)
    for i, color in enumerate(("C0", "C1", "C2")):
        ax_w.plot(t[::every], ds.omega.values[::every, i], color=color, lw=1.0, label=f"$\\omega_{i + 1}$")
        ax_w.plot(t[::every], ds.omega_exact.values[::every, i], color=color, lw=0.8, ls="--")
    ax_w.set(xlabel="time (s)", ylabel="angular velocity (rad/s)", title="recorded (solid), exact (dashed)")
    ax_w.legend(fontsize=7, loc="upper right")
    _log_panel(ax_err, t, ds, "error against the exact solution",
               (("omega_error", r"$|\omega - \omega_{exact}| / |\omega_{exact}|$"),
                ("attitude_error", "attitude error (rad)")))
    _log_panel(ax_drift, t, ds, "drift of the invariants",
               (("energy_drift", "$|E/E_0 - 1|$"), ("momentum_drift", "$||L|/|L_0| - 1|$"),
                ("momentum_direction", "direction of $L$ in space (rad)")))
    shared = min(ds.sizes.get("flip", 0), ds.sizes.get("flip_exact", 0))
    if shared:
        lag = ds.flip_time.values[:shared] - ds.flip_time_exact.values[:shared]
        ax_flip.plot(np.arange(1, shared + 1), lag, "o-", ms=3)
        ax_flip.axhline(0.0, color="0.5", lw=0.5)
    else:
        ax_flip.text(0.5, 0.5, f"{ds.sizes.get('flip', 0)} measured flips, {ds.sizes.get('flip_exact', 0)} exact",
                     ha="center", va="center", transform=ax_flip.transAxes)
    ax_flip.set(xlabel="flip", ylabel="measured - exact flip time (s)", title="flips about the intermediate axis")
    verdict = ds.attrs.get("verdict", "?").upper()
    diagnosis = ds.attrs.get("diagnosis", "")
    fig.suptitle(f"tumble check: {verdict}" + (f" ({diagnosis.replace(',', ', ')})" if diagnosis else ""),
                 fontsize=10)
    with matplotlib.rc_context(_STYLE):  # the tick labels' size, as save_check_figure draws them
        return layout.fit(fig)


def save_check_figure(ds, path, *, dpi=150):
    """Draw :func:`draw_check` and write it to ``path`` (PNG or PDF by suffix) atomically; return ``path``."""
    fig = draw_check(ds)
    try:
        with io.replaced_atomically(path) as tmp, matplotlib.rc_context(_STYLE):
            fig.savefig(tmp, format=str(path).rsplit(".", 1)[-1], dpi=dpi)
    finally:
        fig.clear()
    return path
