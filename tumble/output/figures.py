"""Paper figures of tumble results.

Every figure is a function of a result Dataset (from :func:`tumble.measure`, :func:`tumble.scan` or a study)
that returns a :class:`matplotlib.figure.Figure` built without pyplot: no global figure state, no window,
nothing shared between calls; files are rendered by Agg (PNG) or the PDF backend. Figures are sized for a
journal column, :data:`SINGLE` (3.4 in) or :data:`DOUBLE` (7 in) wide, with 8–9 pt text, and their legends sit
outside the data.

Variables may carry scan dimensions (``body``, ``axis``, ``spin``, ``amplitude``, ``method``); NaN marks "not
applicable" (e.g. growth variables of a periodic scene). A figure that draws one scene takes the first scene
with data and names it in its title; a figure that draws several picks at most :data:`MAX_SERIES`, evenly.

:func:`can_draw` says cheaply whether a dataset holds what a figure reads; :func:`save_figures` writes files
atomically.

The attitude figures (``flip_animation``, ``flip_strip``, ``polhode``, ``herpolhode``) draw one traced spin's
orientation as :func:`tumble.measure.traces.attitude_trace` stores it; their drawing lives in :mod:`tumble.output.attitude_figures`.
``flip_animation`` gives a :class:`~tumble.output.attitude_figures.FlipAnimation`, which :func:`save_figures` writes as
a GIF (an MP4 when matplotlib finds ffmpeg), whatever image formats are asked for.
"""

from __future__ import annotations

import functools
import warnings
from pathlib import Path

import matplotlib
import numpy as np
import xarray as xr
from matplotlib.cm import ScalarMappable
from matplotlib.colors import ListedColormap, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator
from matplotlib.tri import Triangulation

from .. import registry
from ..physics import models, theory
from . import attitude_figures as attitude_plots
from . import chaos_figures as chaos_plots
from . import io, layout

__all__ = ["ANIMATIONS", "DOUBLE", "FIGURES", "SINGLE", "can_draw", "check_request", "flip_animation",
           "finite_time", "flip_components", "flip_law", "flip_strip", "gyrostat_map", "megno_map", "section", "spectrum", "herpolhode", "sleeping_top", "debra_delp_map",
           "pitch_libration", "flat_spin", "invariant_drift", "norm_growth", "polhode", "save_figures",
           "stability_map", "summary", "work_precision"]

#: Names of the figures, in the order a report shows them.
FIGURES = registry.FIGURES

#: Figures that are movies: written as ``<stem>_<name>.gif`` (``.mp4`` when ffmpeg is found), whatever formats.
ANIMATIONS = ("flip_animation",)

#: Figure widths, inches: one journal column, two columns.
SINGLE = 3.4
DOUBLE = 7.0

#: Most curves a figure draws from a scan (picked evenly).
MAX_SERIES = 6

#: Floor of dimensionless errors on a log axis: an exact zero is drawn here.
FLOOR = 1e-17

#: File formats :func:`save_figures` writes.
FORMATS = registry.FORMATS

_STYLE = {
    "font.size": 8, "axes.labelsize": 9, "axes.titlesize": 9, "legend.fontsize": 8, "xtick.labelsize": 8,
    "ytick.labelsize": 8, "legend.frameon": False, "axes.linewidth": 0.6, "lines.linewidth": 1.1,
    "lines.markersize": 3.5, "xtick.major.width": 0.6, "ytick.major.width": 0.6,
}

_KIND_STYLE = {"periodic": ("C0", "o"), "exponential": ("C3", "^"), "neutral": ("0.45", "x")}
_KIND_RATE = {"periodic": "frequency $\\omega$ (rad/s)", "exponential": "growth rate $\\lambda$ (1/s)",
              "neutral": "frequency $\\omega$ (rad/s)"}
_STABLE = "0.82"  # fill of stable (periodic) regions
_AXIS_NAMES = {1: "smallest", 2: "intermediate", 3: "largest"}
_COORD_TEXT = {"axis": "axis {}", "spin": "ω₀ = {:.3g} rad/s", "amplitude": "ε = {:.2g} rad", "method": "{}"}


# ------------------------------------------------------------------------------------------------ helpers


def _missing(ds, *names):
    """Reason naming the first of ``names`` that ``ds`` lacks, or ""."""
    for name in names:
        if name not in ds.variables:
            return f"the variable {name!r}"
    return ""


def _along(ds, name, *dims):
    """Reason if variable ``name`` is missing or lacks one of ``dims``, or ""."""
    if name not in ds.variables:
        return f"the variable {name!r} (dimensions {', '.join(dims)})"
    lacking = [d for d in dims if d not in ds[name].dims]
    return f"{name!r} along the dimension(s) {', '.join(map(repr, lacking))}" if lacking else ""


def _curve(ds, name, time, *dims):
    """Reason if ``name`` is not a curve against the time variable ``time`` (and along ``dims``), or "".

    The curve runs along the last dimension of ``time``: a coordinate of that name, or the point dimension of a
    NaN-padded time variable with the scan dimensions before it (as :func:`tumble.measure` keeps curves)."""
    if name not in ds.variables or time not in ds.variables or not ds[time].ndim:
        return f"the variables {name!r} and {time!r} (a curve against time)"
    return _along(ds, name, ds[time].dims[-1], *dims)


def _scenes(mask):
    """Selections ``{dim: index}`` where the boolean DataArray ``mask`` is True, in C order."""
    return [dict(zip(mask.dims, map(int, index))) for index in np.argwhere(np.asarray(mask.values))]


def _at(obj, where):
    """``obj`` at the scene ``where``, selecting only the dimensions it has."""
    return obj.isel({d: i for d, i in where.items() if d in obj.dims})


def _evenly(items, n=MAX_SERIES):
    if len(items) <= n:
        return items
    return [items[i] for i in np.unique(np.linspace(0, len(items) - 1, n).round().astype(int))]


def _label(ds, where):
    """Short text naming the scene ``where`` of a scan by its coordinates."""
    parts = []
    for dim, index in where.items():
        if dim == "body" and all(n in ds.coords and "body" in ds[n].dims for n in ("I1", "I2", "I3")):
            moments = ", ".join(f"{float(ds[n][index]):.3g}" for n in ("I1", "I2", "I3"))
            parts.append(f"I = ({moments}) kg m²")
        elif dim in ds.coords:
            value = ds[dim].values[index]
            parts.append(_COORD_TEXT.get(dim, dim + " = {}").format(value.item() if hasattr(value, "item")
                                                                     else value))
        else:
            parts.append(f"{dim} {index}")
    return ", ".join(parts)


def _first_with_data(da, core):
    """The first scene (over the dimensions of ``da`` not in ``core``) where ``da`` has a finite value."""
    finite = np.isfinite(da).any([d for d in core if d in da.dims])
    scenes = _scenes(finite)
    return scenes[0] if scenes else {d: 0 for d in finite.dims}


def _subplots(width, height, ncols=1, **kwargs):
    """A figure with a row of ``ncols`` panels and no layout engine: the drawing ends with :func:`layout.fit`."""
    fig = Figure(figsize=(width, height))
    return fig, fig.subplots(1, ncols, squeeze=False, **kwargs)[0]


def _series(ds, found, what="scenes"):
    """At most :data:`MAX_SERIES` of the scenes ``found``, picked evenly; their labels (naming only the
    coordinates that differ between them); and a title with what they share and how many were left out."""
    picked = _evenly(found)
    first = picked[0] if picked else {}
    varying = [d for d in first if len({w[d] for w in picked}) > 1]
    labels = [_label(ds, {d: w[d] for d in varying}) for w in picked]
    title = [_label(ds, {d: i for d, i in first.items() if d not in varying})]
    if len(found) > len(picked):
        title.append(f"{len(picked)} of {len(found)} {what}")
    return picked, labels, "; ".join(t for t in title if t)


def _legend(fig, handles, below=True):
    """Legend outside the data, then the figure laid out (:func:`layout.fit`): below the axes in as many columns
    as the width holds (the figure grows by its rows), or to the right. Returns the figure."""
    layout.legend(fig, handles, "below" if below else "right")
    return layout.fit(fig)


def _floor_note(text):
    return f"{text}\n(zero drawn at $10^{{{round(np.log10(FLOOR))}}}$)"


def _quiet_nan(func, *args, **kwargs):
    """``func`` with numpy's all-NaN warnings silenced (an all-NaN scene is 'not applicable', not an error)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return func(*args, **kwargs)


_CHECKS = {}


def _figure(check):
    """Register ``check(ds) -> reason`` for a figure; the figure raises ValueError when the reason is not ""."""
    def register(draw):
        name = draw.__name__

        def reason(ds):
            if not isinstance(ds, xr.Dataset):
                return f"{name} needs an xarray.Dataset, got {type(ds).__name__}"
            text = check(ds)
            return f"{name} needs {text}" if text else ""

        @functools.wraps(draw)
        def figure(ds):
            text = reason(ds)
            if text:
                raise ValueError(text)
            with matplotlib.rc_context(_STYLE):
                return draw(ds)

        _CHECKS[name] = reason
        return figure
    return register


# ------------------------------------------------------------------------------------------ stability map


def _check_stability_map(ds):
    if "body" not in ds.dims or not all(n in ds.coords for n in ("i2_over_i3", "i1_fraction")):
        return "a 'body' dimension with coordinates 'i2_over_i3' and 'i1_fraction' (a scan over scan.triangle)"
    if "axis" not in ds.dims:
        return "an 'axis' dimension (a scan over spin.axis)"
    return _missing(ds, "rate", "kind", "spin")


def _triangle_xy(s, u):
    """(I1/I3, I2/I3) of the triangle coordinates ``s = I2/I3``, ``u = i1_fraction`` (inertia_triangle)."""
    return (1.0 - s) + u * (2.0 * s - 1.0), s


def _theory_growth(axis, n=160):
    """Linear growth rate / spin ``sqrt(-q)`` (NaN where stable) on an n × n grid strictly inside the
    triangle, ``q = (Ia−Ib)(Ia−Ic)/(Ib Ic)`` (Landau & Lifshitz §37). Returns x, y, value, each (n, n)."""
    mid = (np.arange(n) + 0.5) / n
    s, u = np.meshgrid(0.5 + 0.5 * mid, mid, indexing="ij")
    x, y = _triangle_xy(s, u)
    q = theory.stability_exponent(np.stack([x, y, np.ones_like(x)], axis=-1), axis)
    return x, y, np.where(q < 0, np.sqrt(np.abs(q)), np.nan)


def _cells(s, u):
    """Delaunay triangles of the scan points in the (s, u) square, where a triangle scan is a regular grid;
    None when the points do not span an area."""
    try:
        return Triangulation(s, u).triangles
    except (ValueError, RuntimeError):
        return None


@_figure(_check_stability_map)
def stability_map(ds):
    """Measured growth rate over the inertia triangle, one panel per spin axis, with linear-theory contours.

    Reads ``rate``, ``kind``, ``spin`` and the ``body`` coordinates ``i2_over_i3``, ``i1_fraction`` of a
    triangle scan with an ``axis`` dimension; other scan dimensions are taken at their first value. Drawn in
    the (I1/I3, I2/I3) plane. Colour: measured growth rate / |spin| between exponential scenes; grey between
    stable (periodic) scenes. Contours: ``sqrt(−q)`` of linear theory on a fine grid.
    """
    where = {d: 0 for d in ds["rate"].dims if d not in ("body", "axis")}
    scene = _at(ds, where)
    s, u = scene["i2_over_i3"].values, scene["i1_fraction"].values
    x, y = _triangle_xy(s, u)
    kind = scene["kind"].transpose("body", "axis").values.astype(str)
    growth = (scene["rate"] / abs(scene["spin"])).transpose("body", "axis").values
    growth = np.where(kind == "exponential", growth, np.nan)
    axes_values = [int(a) for a in scene["axis"].values]
    grids = {a: _theory_growth(a) for a in axes_values}
    vmax = max([np.nanmax(g[2]) for g in grids.values() if np.isfinite(g[2]).any()]
               + [np.nanmax(growth) if np.isfinite(growth).any() else 0.0]) or 1.0
    norm = Normalize(0.0, vmax)
    cmap = matplotlib.colormaps["viridis"]
    levels = [v for v in MaxNLocator(6).tick_values(0.0, vmax) if 0 < v < vmax]
    cells = _cells(s, u)

    fig, axes = _subplots(DOUBLE, 2.05, len(axes_values), sharex=True, sharey=True)
    for ax, (j, a) in zip(axes, enumerate(axes_values)):
        exponential, periodic = kind[:, j] == "exponential", kind[:, j] == "periodic"
        if cells is not None:
            ax.tripcolor(Triangulation(x, y, cells, mask=~exponential[cells].all(axis=1)),
                         np.nan_to_num(growth[:, j]), shading="gouraud", cmap=cmap, norm=norm)
            ax.tripcolor(Triangulation(x, y, cells, mask=~periodic[cells].all(axis=1)),
                         facecolors=np.zeros(len(cells)), cmap=ListedColormap([_STABLE]), lw=0)
            ax.scatter(x, y, s=1, color="k", alpha=0.4, lw=0, zorder=2)
        else:
            ax.scatter(x[exponential], y[exponential], c=growth[exponential, j], cmap=cmap, norm=norm, s=30)
            ax.scatter(x[periodic], y[periodic], color=_STABLE, s=30)
        gx, gy, gvalue = grids[a]
        if np.isfinite(gvalue).any():
            lines = ax.contour(gx, gy, gvalue, levels=levels, colors="k", linewidths=0.6, zorder=3)
            row = np.argmin(np.abs(gy[:, 0] - 0.9))  # label where the contours are well apart: along I2/I3 = 0.9
            ax.clabel(lines, fmt="%.2g", fontsize=8, manual=[(np.interp(v, gvalue[row, ::-1], gx[row, ::-1]),
                                                              gy[row, 0]) for v in levels])
        ax.plot([0.5, 0.0, 1.0, 0.5], [0.5, 1.0, 1.0, 0.5], color="k", lw=0.8)
        ax.set_title(f"axis {a} ({_AXIS_NAMES.get(a, '?')} $I$)")
        ax.set_aspect("equal")
        ax.set_xlim(-0.03, 1.03)
        ax.set_ylim(0.44, 1.09)
        ax.set_xlabel("$I_1/I_3$")
    axes[0].set_ylabel("$I_2/I_3$")
    for text, xy, angle, va in (("$I_2 = I_3$", (0.5, 1.01), 0, "bottom"), ("$I_1 = I_2$", (0.78, 0.76), 45, "top"),
                                ("$I_1 + I_2 = I_3$", (0.22, 0.76), -45, "top")):
        axes[0].text(*xy, text, rotation=angle, rotation_mode="anchor", ha="center", va=va, fontsize=8)
    layout.colorbar(fig, ScalarMappable(norm, cmap), label="growth rate / spin rate")
    if where:
        fig.suptitle(f"at {_label(ds, where)}")
    return _legend(fig, [Patch(color=cmap(0.6), label="measured, exponential (unstable)"),
                         Patch(color=_STABLE, label="periodic (stable)"),
                         Line2D([], [], color="k", lw=0.6, label="linear theory $\\sqrt{-q}$")])


# ------------------------------------------------------------------------------------------- norm growth


def _growth_scenes(ds):
    mask = np.isfinite(ds["growth_norm"]).any(ds["growth_time"].dims[-1]) & (ds["kind"] == "exponential")
    return _scenes(mask)


def _check_norm_growth(ds):
    reason = _curve(ds, "growth_norm", "growth_time") or _missing(ds, "rate_theory", "kind")
    if not reason and not _growth_scenes(ds):
        reason = ("an exponential scene (spin about the intermediate axis) with a finite 'growth_norm'; "
                  "this dataset has none")
    return reason


@_figure(_check_norm_growth)
def norm_growth(ds):
    """Scaled transverse norm against time (log y) with its quartile band, the linear-theory slope
    ``exp(λ t)`` over the fit window, the window, and the saturation level.

    Reads ``growth_norm``, optional ``growth_norm_q1``/``growth_norm_q3`` against ``growth_time`` (s),
    ``rate_theory``, ``kind``, optional ``fit_t_start``, ``fit_t_stop``, ``fit_saturation``. A scan draws one
    curve per exponential scene (at most :data:`MAX_SERIES`, evenly).
    """
    picked, labels, title = _series(ds, _growth_scenes(ds), "exponential scenes")
    fig, (ax,) = _subplots(SINGLE if len(picked) == 1 else DOUBLE, 2.5)
    handles = []
    for color, where, label in zip((f"C{i}" for i in range(10)), picked, labels):
        scene = _at(ds, where)
        t, norm = scene["growth_time"].values, scene["growth_norm"].values
        handles += ax.plot(t, norm, color=color, label=label or "median over samples")
        if "growth_norm_q1" in scene and "growth_norm_q3" in scene:
            ax.fill_between(t, scene["growth_norm_q1"].values, scene["growth_norm_q3"].values, color=color,
                            alpha=0.25, lw=0)
        start, stop, saturation = (float(scene[n]) if n in scene else np.nan
                                   for n in ("fit_t_start", "fit_t_stop", "fit_saturation"))
        rate = float(scene["rate_theory"])
        ok = np.isfinite(t) & np.isfinite(norm) & (norm > 0)
        if np.isfinite([start, stop, rate]).all() and ok.any():
            if len(picked) == 1:
                ax.axvspan(start, stop, color="0.5", alpha=0.12, lw=0)
            anchor = np.exp(np.interp(start, t[ok], np.log(norm[ok])))
            window = np.linspace(start, stop, 64)
            ax.plot(window, anchor * np.exp(rate * (window - start)), color="k", ls=":", lw=1.3, marker="|",
                    markevery=[0, -1], ms=7)
        if np.isfinite(saturation):
            ax.axhline(saturation, color=color, ls="--", lw=0.8)
    layout.log_scale(ax, "y")
    ax.set_xlabel("time $t$ (s)")
    ax.set_ylabel("scaled transverse norm (rad/s)")
    ax.set_title(title)
    handles += [Patch(color="0.5", alpha=0.35, lw=0, label="quartiles over samples"),
                Line2D([], [], color="k", ls=":", lw=1.3, marker="|", ms=7,
                       label="linear theory $e^{\\lambda t}$ over the fit window"),
                Line2D([], [], color="0.3", ls="--", lw=0.8, label="saturation (end of linear regime)")]
    if len(picked) == 1:
        handles.append(Patch(color="0.5", alpha=0.15, lw=0, label="fit window"))
    return _legend(fig, handles, below=len(picked) == 1)


# ----------------------------------------------------------------------------------------------- flip law


def _flip_series(ds):
    counts = np.isfinite(ds["flip_first"]).sum("amplitude")
    return _scenes(counts >= 2)


def _check_flip_law(ds):
    if "amplitude" not in ds.dims or ds.sizes["amplitude"] < 2:
        return "an 'amplitude' dimension with at least 2 values (a scan over perturbation.amplitude)"
    reason = _along(ds, "flip_first", "amplitude") or _missing(ds, "flip_first_asymptote", "rate_theory")
    if not reason and not _flip_series(ds):
        reason = "finite 'flip_first' at 2 or more amplitudes (exponential scenes timed with flips > 0)"
    return reason


@_figure(_check_flip_law)
def flip_law(ds):
    """First-flip time against ``ln(1/ε)``: measured medians (bars: quartiles over samples), the linear-theory
    asymptote ``(1/λ) ln(4/k′)``, and a line of slope ``1/λ`` through the points' centroid.

    Reads ``flip_first``, ``flip_first_asymptote``, ``rate_theory``, optional ``sample_first_flip``, along
    ``amplitude``; other scan dimensions give one series each (at most :data:`MAX_SERIES`).
    """
    picked, labels, title = _series(ds, _flip_series(ds))
    fig, (ax,) = _subplots(SINGLE, 2.5)
    handles = []
    for color, where, name in zip((f"C{i}" for i in range(10)), picked, labels):
        scene = _at(ds, where)
        x = np.log(1.0 / scene["amplitude"].values)
        y = scene["flip_first"].values
        order = np.argsort(x)
        if "sample_first_flip" in scene and "sample" in scene["sample_first_flip"].dims:
            samples = scene["sample_first_flip"].transpose("amplitude", "sample").values
            q1, q3 = _quiet_nan(np.nanquantile, samples, [0.25, 0.75], axis=1)
            yerr = np.clip(np.nan_to_num([y - q1, q3 - y]), 0, None)
        else:
            yerr = None
        rate = _quiet_nan(np.nanmedian, scene["rate_theory"].values)  # the same at every amplitude
        ok = np.isfinite(x) & np.isfinite(y)
        slope = np.polyfit(x[ok], y[ok], 1)[0]
        text = f"slope {slope:.3g} s; $1/\\lambda$ = {1 / rate:.3g} s"
        handles.append(ax.errorbar(x, y, yerr=yerr, fmt="o", color=color, capsize=2, elinewidth=0.7,
                                   label=f"{name}: {text}" if name else f"measured {text}"))
        ax.plot(x[order], scene["flip_first_asymptote"].values[order], color=color, ls="--", lw=0.9)
        ends = np.array([x[ok].min(), x[ok].max()])
        ax.plot(ends, y[ok].mean() + (ends - x[ok].mean()) / rate, color=color, ls=":", lw=1.2)
    ax.set_xlabel("$\\ln(1/\\varepsilon)$, tilt $\\varepsilon$ in rad")
    ax.set_ylabel("first flip time (s)")
    ax.set_title(title)
    handles += [Line2D([], [], color="k", ls="none", marker="o", label="median; bars: quartiles over samples"),
                Line2D([], [], color="k", ls="--", lw=0.9, label="asymptote $(1/\\lambda)\\ln(4/k')$"),
                Line2D([], [], color="k", ls=":", lw=1.2, label="slope $1/\\lambda$ through the points")]
    return _legend(fig, handles)


# ---------------------------------------------------------------------------------------- flip components


def _check_flip_components(ds):
    reason = _curve(ds, "trace_omega", "trace_time", "component")
    if not reason and not np.isfinite(ds["trace_omega"]).any():
        reason = "finite values in 'trace_omega' (it is all NaN)"
    return reason


def _sign_changes(t, w):
    """Times where ``w(t)`` changes sign, by linear interpolation between stored times."""
    i = np.nonzero(w[:-1] * w[1:] < 0)[0]
    return t[i] - w[i] * (t[i + 1] - t[i]) / (w[i + 1] - w[i])


@_figure(_check_flip_components)
def flip_components(ds):
    """Body-frame angular velocity of one sample through its flips: three components against time, the spin
    axis highlighted, flips (sign changes of the spin-axis component) marked.

    Reads ``trace_omega`` against ``trace_time`` (s) and along ``component`` (1, 2, 3), the ``axis``
    coordinate, and optional ``flip_first``/``flip_spacing`` for the title; a scan shows its first scene with a
    trace.
    """
    time = ds["trace_time"].dims[-1]
    where = _first_with_data(ds["trace_omega"], (time, "component"))
    scene = _at(ds, where)
    t = scene["trace_time"].values
    omega = scene["trace_omega"].transpose(time, "component").values
    components = [int(c) for c in scene["component"].values] if "component" in scene.coords else [1, 2, 3]
    if "axis" in scene.coords and scene["axis"].ndim == 0 and int(scene["axis"]) in components:
        spin_axis = int(scene["axis"])
    else:
        spin_axis = components[int(np.nanargmax(np.abs(omega[0])))]
    fig, (ax,) = _subplots(DOUBLE, 2.5)
    ax.axhline(0.0, color="0.7", lw=0.5)
    for j, c in enumerate(components):
        main = c == spin_axis
        ax.plot(t, omega[:, j], color="k" if main else f"C{j}", lw=1.6 if main else 0.9, zorder=3 if main else 2,
                label=f"$\\omega_{c}$" + (" (spin axis)" if main else ""))
    flips = _sign_changes(t, omega[:, components.index(spin_axis)])
    for time in flips:
        ax.axvline(time, color="0.4", ls=":", lw=0.8)
    handles = ax.get_legend_handles_labels()[0]
    handles.append(Line2D([], [], color="0.4", ls=":", lw=0.8, label=f"flip ($\\omega_{spin_axis}$ changes sign)"))
    ax.set_xlabel("time $t$ (s)")
    ax.set_ylabel("body-frame angular velocity (rad/s)")
    ax.set_xlim(np.nanmin(t), np.nanmax(t))
    title = f"one sample, {len(flips)} flips"
    stats = [f"{text} {float(scene[n]):.3g} s" for n, text in (("flip_first", "first flip"),
                                                                 ("flip_spacing", "spacing"))
             if n in scene and scene[n].ndim == 0 and np.isfinite(float(scene[n]))]
    if stats:
        title += "; ensemble median " + ", ".join(stats)
    if where:
        title += f" ({_label(ds, where)})"
    ax.set_title(title)
    return _legend(fig, handles, below=False)


# ---------------------------------------------------------------------------------------- invariant drift


_DRIFTS = (("drift_l2", "$|L|^2$"), ("drift_energy", "kinetic energy $T$"))


def _check_invariant_drift(ds):
    reason = (_along(ds, "drift_l2", "drift_method", "drift_time")
              or _along(ds, "drift_energy", "drift_method", "drift_time"))
    if not reason and not any(np.isfinite(ds[name]).any() for name, _ in _DRIFTS):
        reason = "finite values in 'drift_l2' or 'drift_energy' (both are all NaN)"
    return reason


@_figure(_check_invariant_drift)
def invariant_drift(ds):
    """Relative drift of ``|L|²`` and of the energy against time, one curve per method (log y; an exact zero
    drawn at :data:`FLOOR`).

    Reads ``drift_l2`` and ``drift_energy`` along ``drift_method`` and ``drift_time`` (s).
    """
    where = _first_with_data(ds["drift_l2"], ("drift_method", "drift_time"))
    t = ds["drift_time"].values
    methods = [str(m) for m in ds["drift_method"].values]
    fig, axes = _subplots(DOUBLE, 2.6, 2, sharey=True)
    handles = {}
    for ax, (name, title) in zip(axes, _DRIFTS):
        drift = _at(ds[name], where).transpose("drift_method", "drift_time").values
        for j, method in enumerate(methods):
            if np.isfinite(drift[j]).any():
                handles[method], = ax.plot(t, np.clip(drift[j], FLOOR, None), color=f"C{j % 10}",
                                           ls=("-", "--", "-.", ":")[j // 10 % 4], label=method)
        layout.log_scale(ax, "y")
        ax.set_title(title)
        ax.set_xlabel("time $t$ (s)")
    axes[0].set_ylabel(_floor_note("relative drift $|X(t)/X(0) - 1|$"))
    if where:
        fig.suptitle(_label(ds, where))
    return _legend(fig, [handles[m] for m in methods if m in handles], below=False)


# ----------------------------------------------------------------------------------------- work-precision


def _check_work_precision(ds):
    reason = _along(ds, "wp_error", "solver", "wp_point") or _along(ds, "wp_wall", "solver", "wp_point")
    if not reason and not (np.isfinite(ds["wp_error"]) & (ds["wp_wall"] > 0)).any():
        reason = "a finite 'wp_error' with a positive 'wp_wall' (all points are NaN)"
    return reason


@_figure(_check_work_precision)
def work_precision(ds):
    """Relative error at the final time against median wall time (log-log), one curve per solver; the peers
    (SciPy, heyoka) dashed with open markers, the closed form ("exact") a star.

    Reads ``wp_error`` and ``wp_wall`` along ``solver`` and ``wp_point`` (NaN padding skipped); optional
    ``solver_kind`` ("tumble", "exact", "scipy", "heyoka"; else a name starting "scipy" is SciPy) and attributes
    ``samples`` and ``t_end`` for the title.
    """
    where = _first_with_data(ds["wp_error"], ("solver", "wp_point"))
    error = _at(ds["wp_error"], where).transpose("solver", "wp_point").values
    wall = _at(ds["wp_wall"], where).transpose("solver", "wp_point").values
    fig, (ax,) = _subplots(SINGLE, 2.7)
    handles = []
    kinds = (_at(ds["solver_kind"], where).values.astype(str) if "solver_kind" in ds
             else ["scipy" if str(s).startswith("scipy") else str(s) for s in ds["solver"].values])
    for j, solver in enumerate(str(s) for s in ds["solver"].values):
        ok = np.isfinite(error[j]) & np.isfinite(wall[j]) & (wall[j] > 0)
        if not ok.any():
            continue
        points = wall[j][ok], np.clip(error[j][ok], FLOOR, None)
        if solver == "exact":
            handles += ax.plot(*points, ls="none", marker="*", ms=9, color="k", label="exact (closed form)")
        else:
            peer = kinds[j] in ("scipy", "heyoka")
            handles += ax.plot(*points, color=f"C{j % 10}", ls="--" if peer else "-",
                               marker="osD^v<>ph"[j % 9], mfc="none" if peer else f"C{j % 10}", label=solver)
    layout.log_scale(ax, "x")
    layout.log_scale(ax, "y")
    ax.set_xlabel("median wall time (s)")
    ax.set_ylabel(_floor_note("relative error at the final time"))
    about = [text.format(ds.attrs[k]) for k, text in (("samples", "{} samples"), ("t_end", "$t$ = {:.3g} s"))
             if isinstance(ds.attrs.get(k), (int, float, np.number))]
    if where:
        about.append(_label(ds, where))
    if about:
        ax.set_title(", ".join(about))
    return _legend(fig, handles)


# ------------------------------------------------------------------------------------------------ summary


def _check_summary(ds):
    return _missing(ds, "rate", "rate_theory", "kind")


def _rate_label(kinds, what):
    units = {_KIND_RATE[k] for k in kinds if k in _KIND_RATE}
    return f"{what} {units.pop()}" if len(units) == 1 else f"{what} rate: $\\omega$ (rad/s) or $\\lambda$ (1/s)"


@_figure(_check_summary)
def summary(ds):
    """Measured rate against linear theory.

    One scene (0-d ``rate``): the per-sample rates (histogram of ``sample_rate`` if present), the median with
    its confidence interval (``rate_ci_low``/``rate_ci_high``) and the theory, as relative deviations from
    theory; ``rel_error`` in the legend.
    A scan: ``rate`` against ``rate_theory`` by ``kind`` (log-log when all positive) with the line y = x, and
    the distribution of ``rel_error`` (log x).
    """
    if ds["rate"].ndim == 0:
        return _summary_scene(ds)
    return _summary_scan(ds)


def _summary_scene(ds):
    """Per-sample rates, the median with its interval and linear theory, as relative deviations from theory
    (from ``|spin|`` for a neutral scene, whose theory is 0, as :func:`tumble.measure` does)."""
    kind = str(ds["kind"].values)
    color = _KIND_STYLE.get(kind, ("C0", "o"))[0]
    rate, rate_theory = float(ds["rate"]), float(ds["rate_theory"])
    scale, over = ((abs(rate_theory), "theory") if rate_theory
                   else (abs(float(ds["spin"])) if "spin" in ds else 1.0, "|spin|"))
    samples = ds["sample_rate"].values if "sample_rate" in ds else np.array([])
    interval = [float(ds[n]) for n in ("rate_ci_low", "rate_ci_high") if n in ds]
    shown = (np.concatenate([[rate], samples, interval]) - rate_theory) / scale
    extent = np.nanmax(np.abs(shown)) if np.isfinite(shown).any() else 0.0
    power = int(np.floor(np.log10(extent))) if extent > 0 else 0

    def deviation(value):
        return (np.asarray(value) - rate_theory) / scale / 10.0**power

    samples = deviation(samples)[np.isfinite(deviation(samples))]
    fig, (ax,) = _subplots(SINGLE, 2.3)
    handles = []
    if len(samples):
        ax.hist(samples, bins=min(40, max(8, len(samples) // 8)), color="0.8")
        handles.append(Patch(color="0.8", label=f"samples ({len(samples)})"))
        ax.set_ylabel("samples per bin")
    else:
        ax.set_yticks([])
    if len(interval) == 2:
        handles.append(ax.axvspan(*deviation(interval), color=color, alpha=0.3, lw=0,
                                  label="confidence interval of the median"))
    rel = float(ds["rel_error"]) if "rel_error" in ds else abs(rate - rate_theory) / scale
    handles.append(ax.axvline(deviation(rate), color=color, lw=1.4, label=f"measured median, error {rel:.2g}"))
    handles.append(ax.axvline(0.0, color="k", ls="--", lw=1.0, label="linear theory"))
    ax.set_xlabel(f"(measured − theory) / {over}" + (f" ($\\times 10^{{{power}}}$)" if power else ""))
    unit = ds["rate"].attrs.get("units", "1/s" if kind == "exponential" else "rad/s")
    axis = f"axis {int(ds['axis'])}, " if "axis" in ds.coords and ds["axis"].ndim == 0 else ""
    ax.set_title(f"{axis}{kind}: theory {rate_theory:.5g} {unit}")
    return _legend(fig, handles)


def _summary_scan(ds):
    def flat(name):
        """Variable ``name`` over the scenes of ``rate``, as a flat array."""
        return ds[name].broadcast_like(ds["rate"]).transpose(*ds["rate"].dims).values.ravel()

    kinds, rate, rate_theory = flat("kind").astype(str), flat("rate"), flat("rate_theory")
    rel = flat("rel_error") if "rel_error" in ds else np.abs(rate / rate_theory - 1)
    if "rate_ci_low" in ds and "rate_ci_high" in ds:
        spread = np.clip(np.nan_to_num([rate - flat("rate_ci_low"), flat("rate_ci_high") - rate]), 0, None)
    else:
        spread = np.zeros((2, len(rate)))
    finite = np.isfinite(rate) & np.isfinite(rate_theory)
    present = [k for k in _KIND_STYLE if (finite & (kinds == k)).any()]
    fig, (ax, hist) = _subplots(DOUBLE, 2.9, 2)
    for kind in present:
        color, marker = _KIND_STYLE[kind]
        pick = finite & (kinds == kind)
        ax.errorbar(rate_theory[pick], rate[pick], yerr=spread[:, pick], fmt=marker, color=color, mfc="none",
                    elinewidth=0.6, label=f"{kind} ({pick.sum()})")
    if finite.any():
        ends = np.array([min(rate[finite].min(), rate_theory[finite].min()),
                         max(rate[finite].max(), rate_theory[finite].max())])
        ax.plot(ends, ends, color="k", lw=0.6, zorder=0, label="measured = theory")
        if (ends > 0).all():
            layout.log_scale(ax, "x")
            layout.log_scale(ax, "y")
        ax.legend(loc="upper left")  # the points lie along y = x; "best" scans every error bar (0.2 s)
    ax.set_xlabel(_rate_label(present, "linear theory"))
    ax.set_ylabel(_rate_label(present, "measured"))
    errors = [np.clip(rel[finite & (kinds == k) & np.isfinite(rel)], FLOOR, None) for k in present]
    if sum(map(len, errors)):
        values = np.concatenate(errors)
        bins = np.logspace(np.floor(np.log10(values.min()) - 0.25), np.ceil(np.log10(values.max()) + 0.25), 25)
        hist.hist(errors, bins=bins, stacked=True, color=[_KIND_STYLE[k][0] for k in present])
    layout.log_scale(hist, "x")
    hist.set_xlabel(_floor_note("relative error |measured − theory| / theory"))
    hist.set_ylabel("scenes")
    hist.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts: no tick at 0.5 scenes
    return layout.fit(fig)


# ------------------------------------------------------------------------------------------------- models


def _check_gyrostat_map(ds):
    if "rotor" not in ds.dims:
        return "a 'rotor' dimension (a gyrostat study's scan.rotor)"
    return _missing(ds, "rate", "rate_theory", "kind", "spin", "axis", "I1", "I2", "I3")


def _model_theory(kinds, values):
    """Growth rate and frequency curves from :func:`tumble.physics.theory.linear` results (NaN where the other)."""
    kinds, values = np.asarray(kinds), np.asarray(values, dtype=float)
    return np.where(kinds == "exponential", values, np.nan), np.where(kinds == "periodic", values, np.nan)


def _measured(ax, x, ds_scene):
    """Measured rates of a line of scenes against ``x``, marked by kind."""
    kinds = np.asarray(ds_scene["kind"].values).astype(str)
    rate = np.asarray(ds_scene["rate"].values, dtype=float)
    for kind, (color, marker) in _KIND_STYLE.items():
        pick = kinds == kind
        if pick.any():
            ax.plot(x[pick], rate[pick], marker, color=color, mfc="none", ls="none", label=f"measured, {kind}")


def _theory_lines(ax, x, growth, frequency):
    ax.plot(x, growth, color=_KIND_STYLE["exponential"][0], lw=1.0, label="theory: growth rate (1/s)")
    ax.plot(x, frequency, color=_KIND_STYLE["periodic"][0], lw=1.0, ls="--", label="theory: frequency (rad/s)")


@_figure(_check_gyrostat_map)
def gyrostat_map(ds):
    """A gyrostat's stability against its rotor: measured growth rate or frequency against the rotor's angular
    momentum ``h`` along the spin axis, one panel per spin axis, with the linearisation's curves
    (:func:`tumble.physics.theory.linear` of :class:`tumble.physics.models.Gyrostat`, 400 values of ``h``).

    Reads ``rate``, ``kind``, ``spin``, ``axis``, ``rotor`` (a dimension, N m s) and the moments of the first body;
    other scan dimensions at their first value.
    """
    first = {d: 0 for d in ds["rate"].dims if d not in ("rotor", "axis")}
    scene = ds.isel(first)
    moments = np.array([float(np.asarray(scene[n]).reshape(-1)[0]) for n in ("I1", "I2", "I3")])
    spin = float(np.asarray(scene["spin"]).reshape(-1)[0])
    axes = np.atleast_1d(scene["axis"].values)
    h = np.asarray(scene["rotor"].values, dtype=float)
    dense = np.linspace(min(h.min(), 0.0), h.max(), 400)
    fig, panels = _subplots(DOUBLE, 2.5, len(axes), sharey=True)
    for i, (ax, a) in enumerate(zip(panels, axes)):
        line = scene.isel(axis=i) if "axis" in scene.dims else scene
        kinds, values = [], []
        for value in dense:
            rotor = np.zeros(3)
            rotor[int(a) - 1] = value
            kind, rate = theory.linear(models.Gyrostat(moments, rotor), int(a), spin)
            kinds.append(kind)
            values.append(rate)
        _theory_lines(ax, dense, *_model_theory(kinds, values))
        _measured(ax, h, line)
        ax.set_title(f"spin axis {int(a)} (I = {moments[int(a) - 1]:g} kg m²)")
        ax.set_xlabel("rotor h along the axis (N m s)")
    panels[0].set_ylabel(f"rate at spin {spin:g} rad/s")
    seen = {}
    for ax in panels:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(label, handle)
    return _legend(fig, list(seen.values()))


def _check_sleeping_top(ds):
    if "spin" not in ds.dims:
        return "a 'spin' dimension (a heavy top study's scan.rate)"
    return _missing(ds, "rate", "rate_theory", "kind", "mgl", "I1", "I2", "I3")


@_figure(_check_sleeping_top)
def sleeping_top(ds):
    """The top that wakes up as it slows: a heavy top's measured growth rate (below the threshold) or body-frame
    precession frequency (above) against its spin ``w3``, with the linearisation's curves
    (:class:`tumble.physics.models.HeavyTop`, 400 spins) and the threshold ``I3² w3² = 4 I1 mgl`` (``I1 = I2``).

    Reads ``rate``, ``kind``, ``spin`` (a dimension, rad/s), ``mgl`` and the moments of the first body; other scan
    dimensions at their first value.
    """
    first = {d: 0 for d in ds["rate"].dims if d != "spin"}
    scene = ds.isel(first)
    moments = np.array([float(np.asarray(scene[n]).reshape(-1)[0]) for n in ("I1", "I2", "I3")])
    mgl = float(np.asarray(scene["mgl"]).reshape(-1)[0])
    spin = np.asarray(scene["spin"].values, dtype=float)
    dense = np.linspace(min(spin.min(), 0.0) or 1e-3, spin.max(), 400)
    top = models.HeavyTop(moments, mgl)
    kinds, values = zip(*(theory.linear(top, 3, w) for w in dense))
    fig, (ax,) = _subplots(SINGLE, 2.6)
    _theory_lines(ax, dense, *_model_theory(kinds, values))
    _measured(ax, spin, scene)
    threshold = 2.0 * np.sqrt(moments[0] * mgl) / moments[2]
    ax.axvline(threshold, color="0.5", lw=0.7, ls=":", label=f"threshold w3 = {threshold:.4g} rad/s")
    ax.set_xlabel("spin w3 (rad/s)")
    ax.set_ylabel("rate (1/s or rad/s)")
    ax.set_title(f"heavy top, I = ({', '.join(f'{m:g}' for m in moments)}) kg m², mgl = {mgl:g} N m")
    return _legend(fig, ax.get_legend_handles_labels()[0])


def _check_debra_delp_map(ds):
    if "k1" not in ds.coords or "k3" not in ds.coords:
        return "coordinates 'k1' and 'k3' (a gravity_gradient study's scan.k1 and scan.k3)"
    return _missing(ds, "rate", "rate_theory", "kind", "orbit_rate")


def _k_grid(ds):
    """``(k1 values, k3 values, index (B, 2))``: the grid of a ``scan.k1`` x ``scan.k3`` study's bodies."""
    k1, k3 = np.asarray(ds["k1"].values, dtype=float), np.asarray(ds["k3"].values, dtype=float)
    u1, u3 = np.unique(k1), np.unique(k3)
    return u1, u3, np.searchsorted(u1, k1), np.searchsorted(u3, k3)


def _gg_boundaries(ax):
    """The theory's boundaries of the (k1, k3) map: ``k1 = k3``, ``k1 k3 = 0`` and ``1 + 3 k1 + k1 k3 = 4 sqrt(k1 k3)``."""
    ax.plot([-1, 1], [-1, 1], color="k", lw=0.8, label="$k_1 = k_3$ (pitch)")
    ax.axhline(0.0, color="k", lw=0.8, ls="--", label="$k_1 k_3 = 0$")
    ax.axvline(0.0, color="k", lw=0.8, ls="--")
    g1, g3 = np.meshgrid(np.linspace(-1, 1, 801), np.linspace(-1, 1, 801), indexing="ij")
    product = g1 * g3
    with np.errstate(invalid="ignore"):
        f = np.where(product > 0, 1.0 + 3.0 * g1 + product - 4.0 * np.sqrt(np.maximum(product, 0.0)), np.nan)
    ax.contour(g1, g3, f, levels=[0.0], colors="C2", linewidths=1.0)
    ax.plot([], [], color="C2", lw=1.0, label="$1 + 3k_1 + k_1k_3 = 4\\sqrt{k_1k_3}$")


@_figure(_check_debra_delp_map)
def debra_delp_map(ds):
    """The gravity-gradient stability map over ``(k1, k3)``: each body of the grid a cell, coloured by its measured
    growth rate (in units of the orbit rate ``n``) where the orbit-following attitude is unstable, grey where it
    librates (measured frequency), with the theory's boundaries (:func:`tumble.physics.theory.gravity_gradient_stable`)
    and its two stable regions, Lagrange's (``k1 > k3 > 0``) and DeBra-Delp's (``0 > k1 > k3``). A cell whose
    linearisation disagrees with the closed-form region is crossed; cells on ``k1 = k3`` (``I1 = I3``: the pitch
    mode neutral, no kind decided by linear theory) are circled.

    Reads ``rate``, ``kind``, ``orbit_rate`` and the body coordinates ``k1``, ``k3``; other scan dimensions at
    their first value.
    """
    first = {d: 0 for d in ds["rate"].dims if d != "body"}
    scene = ds.isel(first)
    u1, u3, i1, i3 = _k_grid(scene)
    n = float(np.asarray(scene["orbit_rate"]).reshape(-1)[0])
    rate = np.asarray(scene["rate"].values, dtype=float).reshape(-1) / n
    kinds = np.asarray(scene["kind"].values).astype(str).reshape(-1)
    growth = np.full((len(u1), len(u3)), np.nan)
    stable = np.zeros((len(u1), len(u3)))
    growth[i1, i3] = np.where(kinds == "exponential", rate, np.nan)
    stable[i1, i3] = kinds == "periodic"
    edges = [np.concatenate([[-1.0], 0.5 * (u[1:] + u[:-1]), [1.0]]) if len(u) > 1 else np.array([u[0] - 0.05, u[0] + 0.05])
             for u in (u1, u3)]
    fig, (ax,) = _subplots(SINGLE + 0.8, SINGLE - 0.1)
    ax.pcolormesh(edges[0], edges[1], np.where(stable.T > 0, 1.0, np.nan), cmap=ListedColormap([_STABLE]),
                  shading="flat")
    mesh = ax.pcolormesh(edges[0], edges[1], growth.T, cmap="magma_r", shading="flat")
    layout.colorbar(fig, mesh, label="measured growth rate / n")
    region = np.asarray(theory.gravity_gradient_region(u1[i1], u3[i3]))
    neutral = u1[i1] == u3[i3]  # I1 = I3: the pitch mode is neutral (w_p = 0), the linearisation decides no kind
    marginal = neutral | (u1[i1] * u3[i3] == 0)  # on a boundary: neither side is wrong
    wrong = ((region == "unstable") != (kinds == "exponential")) & ~marginal
    if wrong.any():
        ax.plot(u1[i1][wrong], u3[i3][wrong], "x", color="C0", label="kind disagrees with the closed form")
    if neutral.any():
        ax.plot(u1[i1][neutral], u3[i3][neutral], "o", mfc="none", mec="C0", ms=3, mew=0.6,
                label="$k_1 = k_3$: pitch neutral")
    _gg_boundaries(ax)
    ax.text(0.55, 0.15, "Lagrange", ha="center", fontsize=8)
    ax.annotate("DeBra-Delp", xy=(-0.05, -0.7), xytext=(-0.75, -0.85), fontsize=8,
                arrowprops={"arrowstyle": "->", "lw": 0.6})
    ax.set_xlim(-1, 1)
    ax.set_ylim(-1, 1)
    ax.set_xlabel("$k_1 = (I_2 - I_3)/I_1$")
    ax.set_ylabel("$k_3 = (I_2 - I_1)/I_3$")
    ax.set_title(f"gravity gradient, n = {n:g} rad/s: {len(u1)} x {len(u3)} bodies (grey: librates)")
    return _legend(fig, ax.get_legend_handles_labels()[0])


def _check_pitch_libration(ds):
    if "orbit_rate" not in ds.dims:
        return "an 'orbit_rate' dimension (a gravity_gradient study's scan.orbit_rate)"
    return _missing(ds, "rate", "rate_theory", "kind", "I1", "I2", "I3")


@_figure(_check_pitch_libration)
def pitch_libration(ds):
    """A gravity-gradient satellite's libration against the orbit rate ``n``: the measured frequency of the mode
    :func:`tumble.physics.theory.linear` reports, the linearisation's curve, and the pitch frequency
    ``w_p = n sqrt(3 (I1 - I3)/I2)`` (:func:`tumble.physics.theory.gravity_gradient_pitch_frequency`; the dominant
    mode of a DeBra-Delp body). Reads ``rate``, ``kind``, ``orbit_rate`` (a dimension) and the first body's moments.
    """
    first = {d: 0 for d in ds["rate"].dims if d != "orbit_rate"}
    scene = ds.isel(first)
    moments = np.array([float(np.asarray(scene[m]).reshape(-1)[0]) for m in ("I1", "I2", "I3")])
    n = np.asarray(scene["orbit_rate"].values, dtype=float)
    dense = np.linspace(0.0, n.max() * 1.05, 200)[1:]
    kinds, values = zip(*(theory.linear(models.GravityGradient(moments, x), 2) for x in dense))
    pitch_kind, pitch = theory.gravity_gradient_pitch_frequency(moments, dense)
    fig, (ax,) = _subplots(SINGLE, 2.6)
    _theory_lines(ax, dense, *_model_theory(kinds, values))
    ax.plot(dense, np.where(np.asarray(pitch_kind) == "periodic", pitch, np.nan), color="C2", lw=0.8, ls=":",
            label="pitch $w_p = n\\sqrt{3 (I_1 - I_3)/I_2}$")
    _measured(ax, n, scene)
    ax.set_xlabel("orbit rate n (rad/s)")
    ax.set_ylabel("rate (1/s or rad/s)")
    ax.set_title(f"gravity gradient, I = ({', '.join(f'{m:.4g}' for m in moments)}) kg m²")
    return _legend(fig, ax.get_legend_handles_labels()[0])


def _check_flat_spin(ds):
    return _missing(ds, "trace_nutation", "trace_energy", "trace_momentum", "trace_energy_undamped",
                    "trace_flat_energy", "rate", "kind", "damping")


@_figure(_check_flat_spin)
def flat_spin(ds):
    """Explorer 1: a minor-axis spinner with a damper turns over to the flat spin about its major axis. Four panels:
    the nutation angle (spin axis to ``L``) against time; the energy falling to the flat spin's
    ``|L|² / (2 (I_max + J))`` while ``|L|`` is held; the energy lost against the integrator's own drift (the same
    samples at ``c`` ≈ 0) and the drift of ``|L|``; the measured growth rate of the nutation against ``c`` with the
    linearisation and the first-order rate (:func:`tumble.physics.theory.damper_nutation_rate`).

    Reads the ``trace_*`` variables (:func:`tumble.measure.model_scenes.flat_spin_trace`), ``rate``, ``kind``,
    ``damping`` (a dimension or a scalar) and the first body's moments.
    """
    t = np.asarray(ds["trace_time"].values, dtype=float)
    nutation = np.degrees(np.asarray(ds["trace_nutation"].values, dtype=float))
    energy = np.asarray(ds["trace_energy"].values, dtype=float)
    size = np.asarray(ds["trace_momentum"].values, dtype=float)
    undamped = np.asarray(ds["trace_energy_undamped"].values, dtype=float)
    flat = np.asarray(ds["trace_flat_energy"].values, dtype=float)
    fig = Figure(figsize=(DOUBLE, 4.0))
    panels = fig.subplots(2, 2).reshape(-1)
    for k in range(len(nutation)):
        panels[0].plot(t, nutation[k], lw=0.7, color="C3" if k == 0 else "0.6", zorder=3 if k == 0 else 2)
    panels[0].axhline(90.0, color="k", lw=0.6, ls=":")
    panels[0].set_ylabel("nutation angle (deg)")
    panels[0].set_title(f"c = {float(ds['trace_damping']):g} N m s: minor axis to flat spin")
    panels[1].plot(t, energy[0] / energy[0, 0], color="C3", lw=1.0, label="E / E(0)")
    panels[1].axhline(flat[0] / energy[0, 0], color="k", lw=0.7, ls="--", label="$|L|^2 / (2 (I_{max} + J))$")
    panels[1].plot(t, size[0] / size[0, 0], color="C0", lw=1.0, label="|L| / |L(0)|")
    panels[1].set_ylabel("relative to t = 0")
    panels[1].legend(fontsize=7, loc="center right")
    lost = np.abs(energy / energy[:, :1] - 1.0)
    drift = np.abs(undamped / undamped[:, :1] - 1.0)
    spread = np.abs(size / size[:, :1] - 1.0)
    floor = 1e-17
    panels[2].plot(t[1:], lost[0, 1:] + floor, color="C3", label="energy lost, |E/E(0) - 1|")
    panels[2].plot(t[1:], drift.max(axis=0)[1:] + floor, color="0.4", label="integrator: c ≈ 0, |E/E(0) - 1|")
    panels[2].plot(t[1:], spread.max(axis=0)[1:] + floor, color="C0", lw=0.8, label="| |L|/|L(0)| - 1 |")
    layout.log_scale(panels[2], "y")
    panels[2].set_ylabel("relative change")
    panels[2].legend(fontsize=7, loc="center right")  # the relative changes lie near 1 and below 1e-12
    for ax in panels[:3]:
        ax.set_xlabel("time (s)")
    moments = np.array([float(np.asarray(ds[m]).reshape(-1)[0]) for m in ("I1", "I2", "I3")])
    inertia = float(np.asarray(ds["damper_inertia"]).reshape(-1)[0]) if "damper_inertia" in ds else None
    first = {d: 0 for d in ds["rate"].dims if d != "damping"}
    scene = ds.isel(first)
    c = np.atleast_1d(np.asarray(scene["damping"].values, dtype=float))
    axis = int(np.asarray(scene["axis"]).reshape(-1)[0]) if "axis" in scene else 3
    spin = float(np.asarray(scene["spin"]).reshape(-1)[0]) if "spin" in scene else 1.0
    if inertia is not None:
        dense = np.linspace(0.0, c.max() * 1.1, 120)[1:]
        kinds, values = zip(*(theory.linear(models.Damper(moments, inertia, x), axis, spin) for x in dense))
        _theory_lines(panels[3], dense, *_model_theory(kinds, values))
        panels[3].plot(dense, theory.damper_nutation_rate(moments, inertia, dense, axis), color="C2", lw=0.8, ls=":",
                       label="first order in c")
    rate = np.atleast_1d(np.asarray(scene["rate"].values, dtype=float))
    panels[3].plot(c, rate, "^", color=_KIND_STYLE["exponential"][0], mfc="none", ls="none", label="measured")
    panels[3].set_xlabel("damping c (N m s)")
    panels[3].set_ylabel("nutation growth rate (1/s)")
    panels[3].legend(fontsize=7, loc="upper left")  # the rates rise from c = 0 to the right; "best" scans them all
    return layout.fit(fig)


# ----------------------------------------------------------------------------------------------- attitude


@_figure(attitude_plots.missing_attitude)
def flip_strip(ds):
    """A row of eight snapshots of the body through its first flip, in the invariable frame (``L`` up), the
    intermediate axis red; each panel gives its time and the angle between that axis and ``L``.

    Reads ``attitude_quaternion``, ``attitude_omega``, ``attitude_moments`` along ``attitude_time`` (s) and the
    attributes of ``attitude_quaternion`` (see :mod:`tumble.output.attitude_figures`). The body is the box with the same
    principal moments, or the T-handle when ``body_shape`` is ``"t_handle"``.
    """
    return attitude_plots.flip_strip(ds, width=DOUBLE)


@_figure(attitude_plots.missing_attitude)
def flip_animation(ds):
    """The body turning in the invariable frame (``L`` up, the intermediate axis red), one frame per stored time
    nearest to 160 times evenly spaced over the trace, at 20 frames per second.

    Reads what :func:`flip_strip` reads. Returns a :class:`~tumble.output.attitude_figures.FlipAnimation` (a
    :class:`matplotlib.animation.FuncAnimation`), not a Figure; :func:`save_figures` writes it as a movie.
    """
    return attitude_plots.flip_animation(ds)


@_figure(attitude_plots.missing_attitude)
def polhode(ds):
    """The polhode: body-frame ``ω(t)`` on the energy ellipsoid ``Σ I ω² = 2T`` (light wireframe), with the
    polhodes of other ``|L|²`` at the same energy and the separatrix (Landau & Lifshitz §37).

    Reads what :func:`flip_strip` reads.
    """
    return attitude_plots.polhode(ds, width=SINGLE)


@_figure(attitude_plots.missing_attitude)
def herpolhode(ds):
    """The herpolhode: the tip of the space-frame ``ω(t) = R(t) ω_body(t)`` in the invariable plane
    ``ω · L̂ = 2T/|L|``, in the plane's own coordinates, with the circles bounding it.

    Reads what :func:`flip_strip` reads.
    """
    return attitude_plots.herpolhode(ds, width=SINGLE)


# ------------------------------------------------------------------------------------------------ chaos maps


def _check_megno_map(ds):
    reason = _missing(ds, "megno", "status")
    scan = str(ds.attrs.get("scan_dims", "")).split()
    if not reason and not [d for d in ds["megno"].dims if d not in scan]:
        reason = "a map: 'megno' over at least one initial-state coordinate"
    return reason


@_figure(_check_megno_map)
def megno_map(ds):
    """MEGNO over a chaos study's map of initial states (:func:`tumble.output.chaos_figures.megno_map`)."""
    return chaos_plots.megno_map(ds, width=DOUBLE)


def _check_lyapunov(ds):
    return _missing(ds, "exponent", "finite_time", "time", "index")


@_figure(_check_lyapunov)
def finite_time(ds):
    """Finite-time Lyapunov exponents against time (:func:`tumble.output.chaos_figures.finite_time`)."""
    return chaos_plots.finite_time(ds, width=SINGLE)


@_figure(_check_lyapunov)
def spectrum(ds):
    """The Lyapunov spectrum per orbit (:func:`tumble.output.chaos_figures.spectrum`)."""
    return chaos_plots.spectrum(ds, width=SINGLE)


def _check_section(ds):
    return _missing(ds, "section_point", "crossings")


@_figure(_check_section)
def section(ds):
    """A section study's Poincaré section (:func:`tumble.output.chaos_figures.section`)."""
    return chaos_plots.section(ds, width=DOUBLE)


# ------------------------------------------------------------------------------------------------ public


_DRAW = {"stability_map": stability_map, "norm_growth": norm_growth, "flip_law": flip_law,
         "flip_components": flip_components, "invariant_drift": invariant_drift, "work_precision": work_precision,
         "summary": summary, "flip_strip": flip_strip, "flip_animation": flip_animation, "polhode": polhode,
         "herpolhode": herpolhode, "gyrostat_map": gyrostat_map, "sleeping_top": sleeping_top,
         "debra_delp_map": debra_delp_map, "pitch_libration": pitch_libration, "flat_spin": flat_spin,
         "megno_map": megno_map, "finite_time": finite_time, "spectrum": spectrum, "section": section}


def _check_name(name):
    if name not in _DRAW:
        raise ValueError(f"unknown figure {name!r}; figures are {', '.join(FIGURES)}")


def can_draw(ds, name):
    """Whether ``ds`` holds what figure ``name`` reads, without drawing.

    Parameters
    ----------
    ds : xarray.Dataset
    name : str
        One of :data:`FIGURES`.

    Returns
    -------
    (bool, str)
        ``(True, "")``, or ``(False, reason)`` with the message the figure function would raise.

    Raises
    ------
    ValueError
        Unknown figure name.
    """
    _check_name(name)
    reason = _CHECKS[name](ds)
    return not reason, reason


#: zlib level of PNG files: PIL's default, 6, takes 25 ms a figure; 3 takes 16 ms for files 5 % larger (lossless).
PNG_COMPRESSION = 3


def _save_atomic(fig, path, fmt, dpi):
    """Write ``fig`` to ``path`` atomically (:func:`tumble.output.io.replaced_atomically`)."""
    options = ({"metadata": {"CreationDate": None}} if fmt == "pdf"
               else {"pil_kwargs": {"compress_level": PNG_COMPRESSION}} if fmt == "png" else {})
    with io.replaced_atomically(path) as tmp, matplotlib.rc_context(_STYLE):
        fig.savefig(tmp, format=fmt, dpi=dpi, **options)


def check_request(ds, names, formats=("png",), dpi=200):
    """Check :func:`save_figures`' request without drawing: every figure can be drawn from ``ds``, every format is
    known, ``dpi`` is positive. Returns ``(names, formats)`` as lists.

    Raises
    ------
    ValueError
        As :func:`save_figures`.
    """
    names = [names] if isinstance(names, str) else list(names)
    formats = [formats] if isinstance(formats, str) else list(formats)
    for name in names:
        drawable, reason = can_draw(ds, name)
        if not drawable:
            raise ValueError(reason)
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise ValueError(f"unknown figure format {bad[0]!r}; formats are {', '.join(FORMATS)}")
    if not np.isfinite(dpi) or dpi <= 0:
        raise ValueError(f"dpi must be a positive number, got {dpi!r}")
    return names, formats


def save_figures(ds, names, directory, stem, formats=("png",), dpi=200):
    """Draw figures of ``ds`` and write each to ``<directory>/<stem>_<name>.<format>`` atomically.

    Every name is checked (:func:`can_draw`) before anything is drawn, so an unsuitable request writes no file.
    An animation (:data:`ANIMATIONS`) is written once, as ``<stem>_<name>.gif`` or, when matplotlib finds
    ffmpeg, ``.mp4`` (:func:`tumble.output.attitude_figures.animation_format`), at its own small resolution, whatever
    ``formats`` and ``dpi`` say.

    Parameters
    ----------
    ds : xarray.Dataset
    names : str or sequence of str
        Figures from :data:`FIGURES`.
    directory : path-like
        Output folder; created if missing.
    stem : str
        File name prefix.
    formats : sequence of str
        From :data:`FORMATS` ("png", "pdf").
    dpi : float
        Resolution of raster formats, dots per inch (not of animations).

    Returns
    -------
    list of pathlib.Path
        The files written, by name then format.

    Raises
    ------
    ValueError
        Unknown figure or format, a figure the dataset cannot give, or a non-positive dpi.
    """
    names, formats = check_request(ds, names, formats, dpi)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for name in names:
        if name in ANIMATIONS:
            path = directory / f"{stem}_{name}.{attitude_plots.animation_format()}"
            anim = _DRAW[name](ds)
            try:
                with matplotlib.rc_context(_STYLE):
                    attitude_plots.save_animation(anim, path)
            finally:
                anim.figure.clear()
            written.append(path)
            continue
        fig = _DRAW[name](ds)
        try:
            for fmt in formats:
                path = directory / f"{stem}_{name}.{fmt}"
                _save_atomic(fig, path, fmt, dpi)
                written.append(path)
        finally:
            fig.clear()  # pyplot never saw the figure: clearing it frees its artists, nothing else holds it
    return written
