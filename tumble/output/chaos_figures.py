"""The figures of a chaos study, drawn from its Dataset alone (:func:`tumble.measure.records.chaos_dataset`).

- :func:`megno_map`: ``<Y>`` over the map of initial states, a diverging colour scale centred at 2 (the regular
  value: blue below, towards 0 near stable periodic orbits; red above, chaotic);
- :func:`finite_time`: the largest finite-time Lyapunov exponent against time on log axes for the map's most
  chaotic, median and most regular orbits, with ``ln t / t``, the decay of a regular orbit's, for reference;
- :func:`section`: a section study's Poincaré section, each orbit's crossings in the two coordinates it asks for,
  coloured by orbit or by the orbit's ``<Y>``;
- :func:`spectrum`: the Lyapunov spectrum (exponent against its index) of the same orbits, and each index's range
  over the map.

:mod:`tumble.output.figures` registers them (``outputs.figures``); each returns a matplotlib Figure.
"""

from __future__ import annotations

import numpy as np
from matplotlib import colors
from matplotlib.figure import Figure

from . import layout

__all__ = ["MAX_PANELS", "MEGNO_TOP", "finite_time", "megno_map", "picked_orbits", "section", "spectrum"]

#: The top of the MEGNO colour scale at most (above: the darkest red): a chaotic orbit's <Y> grows like lambda t / 2
#: without bound, and a scale stretched to it would wash out the regular side.
MEGNO_TOP = 8.0

#: Panels of a map at most: the scan's scenes along its first dimension (the others at their first value).
MAX_PANELS = 4

_LABELS = {"tilt": "release tilt (rad)", "rate": "initial spin (rad/s)", "angle": "angle θ (rad)"}

#: The section figure's axis labels: the coordinates at a crossing (not the initial ones); a state component by name.
_SECTION_LABELS = {"tilt": "tilt of axis 3, atan2(g₂, g₃) (rad)", "rate": "spin rate θ̇ (rad/s)",
                   "angle": "angle mod π (rad; about axis 2: −θ)"}


def _scenes(ds, name):
    """``[(label, selection)]``: the scan's scenes (``attrs["scan_dims"]``) along its first dimension (at most
    :data:`MAX_PANELS`, the other scan dimensions at their first value), or the one scene."""
    scan = [d for d in str(ds.attrs.get("scan_dims", "")).split() if d in ds[name].dims]
    if not scan:
        return [("", {})]
    first, rest = scan[0], {d: 0 for d in scan[1:]}
    values = ds[first].values
    picks = np.unique(np.linspace(0, len(values) - 1, min(len(values), MAX_PANELS)).round().astype(int))
    return [(f"{first} = {values[i]}", {first: int(i), **rest}) for i in picks]


def megno_map(ds, width=7.0):
    """``<Y>`` over the map: one panel per scene (:func:`_scenes`), colour centred at 2 (a map of one coordinate:
    ``<Y>`` against it, with the regular value 2 dashed)."""
    scenes = _scenes(ds, "megno")
    fig = Figure(figsize=(min(width, 2.6 * len(scenes) + 1.2), 2.9))
    axes = fig.subplots(1, len(scenes), squeeze=False)[0]
    values = np.asarray(ds["megno"].values, dtype=float)
    norm = _megno_norm(values)
    top = norm.vmax
    mesh = None
    for ax, (label, where) in zip(axes, scenes):
        scene = ds["megno"].isel(where)
        x = scene.dims[0]
        xs = np.asarray(ds[x].values, dtype=float)
        ax.set_xlabel(_LABELS.get(x, x))
        ax.set_title(label or f"{ds.attrs.get('model', '')}, T = {ds.attrs.get('t_end', float('nan')):g} s")
        if scene.ndim == 1:  # a line of initial states: <Y> against its coordinate, coloured on the same scale
            ax.plot(xs, scene.values, color="0.6", lw=0.6)
            ax.scatter(xs, scene.values, c=scene.values, cmap="RdBu_r", norm=norm, s=12, zorder=3)
            ax.axhline(2.0, color="k", lw=0.6, ls="--", label="2: regular")
            ax.set_ylabel("MEGNO ⟨Y⟩")
            continue
        y = scene.dims[1]
        ys = np.asarray(ds[y].values, dtype=float)
        mesh = ax.pcolormesh(xs, ys, np.asarray(scene.transpose(x, y).values, dtype=float).T, shading="nearest",
                             cmap="RdBu_r", norm=norm, rasterized=True)
        ax.set_ylabel(_LABELS.get(y, y))
    if mesh is not None:
        bar = layout.colorbar(fig, mesh, label="MEGNO ⟨Y⟩ (2: regular)",
                              extend="max" if np.nanmax(values) > top else "neither")
        bar.ax.axhline(2.0, color="k", lw=0.6)
    return layout.fit(fig)


def _megno_norm(values):
    """The MEGNO colour scale: centred at 2, to the 98th percentile (within 4 ... :data:`MEGNO_TOP`)."""
    top = min(max(4.0, float(np.nanpercentile(values, 98)) if np.isfinite(values).any() else 4.0), MEGNO_TOP)
    return colors.TwoSlopeNorm(vmin=0.0, vcenter=2.0, vmax=top)


def _section_label(ds, name):
    """A section axis's label: a start's coordinate's, or a state component's name with its unit."""
    if name in _SECTION_LABELS:
        return _SECTION_LABELS[name]
    units = dict(zip(ds["component"].values.tolist(), ds["component_units"].values.tolist()))
    return f"{name} ({units[name]})" if name in units else name


def section(ds, width=7.0):
    """The crossings of every orbit of the map in the section's two coordinates (``section_axis``), one panel per
    scene (:func:`_scenes`): each orbit its own colour, or its ``<Y>``'s on :func:`megno_map`'s scale."""
    scenes = _scenes(ds, "crossings")
    fig = Figure(figsize=(min(width, 3.4 * len(scenes) + 1.2), 3.4))
    axes = fig.subplots(1, len(scenes), squeeze=False)[0]
    by_megno = ds.attrs.get("section_colour") == "megno" and "megno" in ds
    norm = _megno_norm(np.asarray(ds["megno"].values, dtype=float)) if by_megno else None
    names = [str(name) for name in ds["section_axis"].values]
    points = None
    for ax, (label, where) in zip(axes, scenes):
        scene = ds["section_point"].isel(where)
        orbits = scene.stack(orbit=[d for d in scene.dims if d not in ("crossing", "section_axis")])
        xy = np.asarray(orbits.transpose("orbit", "crossing", "section_axis").values, dtype=float)
        if by_megno:
            colour = np.repeat(np.asarray(ds["megno"].isel(where).stack(orbit=orbits.indexes["orbit"].names).values,
                                          dtype=float), xy.shape[1])
            points = ax.scatter(xy[..., 0].ravel(), xy[..., 1].ravel(), c=colour, cmap="RdBu_r", norm=norm, s=0.6,
                                linewidths=0, rasterized=True)
        else:
            colour = np.repeat(np.arange(len(xy)) % 20, xy.shape[1])
            ax.scatter(xy[..., 0].ravel(), xy[..., 1].ravel(), c=colour, cmap="tab20", vmin=0, vmax=19, s=0.6,
                       linewidths=0, rasterized=True)
        ax.set_xlabel(_section_label(ds, names[0]))
        ax.set_ylabel(_section_label(ds, names[1]))
        ax.set_title(label or f"{ds.attrs.get('model', '')}: section {ds.attrs.get('section', '')}")
    if points is not None:
        bar = layout.colorbar(fig, points, label="MEGNO ⟨Y⟩ of the orbit (2: regular)")
        bar.ax.axhline(2.0, color="k", lw=0.6)
    return layout.fit(fig)


def picked_orbits(ds):
    """``[(label, {dim: index})]``: the map's orbits of the largest, the median and the smallest final exponent."""
    largest = ds["exponent"].isel(index=0)
    flat = np.asarray(largest.values, dtype=float).ravel()
    finite = np.flatnonzero(np.isfinite(flat))
    if not len(finite):
        return []
    order = finite[np.argsort(flat[finite])]
    picks = [("most chaotic", order[-1]), ("median", order[len(order) // 2]), ("most regular", order[0])]
    out, seen = [], set()
    for label, i in picks:
        if i in seen:
            continue
        seen.add(i)
        index = dict(zip(largest.dims, (int(k) for k in np.unravel_index(i, largest.shape))))
        where = ", ".join(f"{d} {float(ds[d].values[k]):.3g}" for d, k in index.items() if d in ds.coords)
        out.append((f"{label} ({where})" if where else label, index))
    return out


def finite_time(ds, width=3.4):
    """The largest finite-time exponent against time (log axes) of :func:`picked_orbits`, with ``ln t / t``."""
    fig = Figure(figsize=(width, 2.6))
    ax = fig.subplots()
    t = np.asarray(ds["time"].values, dtype=float)
    transient = float(ds.attrs.get("transient", 0.0))
    for k, (label, where) in enumerate(picked_orbits(ds)):
        curve = np.asarray(ds["finite_time"].isel(where).isel(index=0).values, dtype=float)
        ax.plot(t, np.where(curve > 0, curve, np.nan), color=f"C{k}", lw=1.0, label=label)
    span = t - transient
    with np.errstate(divide="ignore", invalid="ignore"):
        reference = np.where(span > 1.0, np.log(np.maximum(span, 1.0)) / span, np.nan)
    ax.plot(t, reference, color="k", lw=0.8, ls="--", label="ln t / t (a regular orbit)")
    layout.log_scale(ax, "x")
    layout.log_scale(ax, "y")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("finite-time λ₁ (1/s)")
    ax.set_title(f"{ds.attrs.get('model', '')}: largest exponent")
    layout.legend(fig, ax.get_legend_handles_labels()[0], "below")
    return layout.fit(fig)


def spectrum(ds, width=3.4):
    """The Lyapunov spectrum of :func:`picked_orbits` (exponent against index), over the range each index spans on
    the map (shaded)."""
    fig = Figure(figsize=(width, 2.6))
    ax = fig.subplots()
    index = np.asarray(ds["index"].values)
    exponents = ds["exponent"]
    rest = [d for d in exponents.dims if d != "index"]
    low = np.asarray(exponents.min(rest).values, dtype=float)
    high = np.asarray(exponents.max(rest).values, dtype=float)
    ax.fill_between(index, low, high, color="0.85", label="range over the map")
    for k, (label, where) in enumerate(picked_orbits(ds)):
        values = np.asarray(exponents.isel(where).values, dtype=float)
        ax.plot(index, values, "o-", color=f"C{k}", lw=0.8, ms=3, label=f"{label}, sum {np.sum(values):.0e}")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xticks(index)
    ax.set_xlabel("exponent index")
    ax.set_ylabel("Lyapunov exponent (1/s)")
    ax.set_title(f"{ds.attrs.get('model', '')}: spectrum, T = {ds.attrs.get('t_end', float('nan')):g} s")
    layout.legend(fig, ax.get_legend_handles_labels()[0], "below")
    return layout.fit(fig)
