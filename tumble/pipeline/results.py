"""A study's result from its scene records: the dataset, the files it is written to, the summary printed.

NumPy, xarray, netCDF4 and matplotlib, no kernel: besides :mod:`tumble.pipeline.runner`, the figure process of
``tumble run`` (:mod:`tumble.pipeline.figure_process`) imports this module, and builds and writes a study's result
from the scene records the command's process sends it. That process runs the scenes without importing xarray
(pandas included, 0.3 s of the command's start-up on 2 cores).
"""

from __future__ import annotations

import numpy as np

from .. import registry
from ..measure import records as scene_records
from ..output import io
from . import checkpoint

__all__ = ["CHAOTIC_MEGNO", "PER_SAMPLE", "chaos_summary", "result_dataset", "stage_result", "summary_table"]

#: Per-sample variables a result may keep (``outputs.arrays``); the rest are dropped after the fit.
PER_SAMPLE = registry.PER_SAMPLE_ARRAYS


def result_dataset(records, *, layout, scanned, body_coords, resolved, extras=(), grid=None):
    # size: the records and what places them (the scan's layout, whether it is one, its body coordinates)
    """The result dataset of a study from its scene records (:func:`tumble.pipeline.runner.run_scenes`).

    Parameters
    ----------
    records : list of dict
        Every scene's record, in the scan's order (one for a study of one scene).
    layout, scanned, body_coords
        The study's :class:`~tumble.pipeline.runner.Job` fields of the same names.
    resolved : dict
        The resolved study: its ``outputs.arrays`` (the per-sample arrays kept) and ``title``.
    extras : sequence of xarray.Dataset
        Merged in (the traces some figures draw: invariant drift, attitude, flat spin, work-precision).
    grid : dict, optional
        A chaos study's map (name -> coordinate values, :meth:`tumble.pipeline.runner.ChaosScenes.result_shape`):
        its records hold the indicators of the map's points (:func:`tumble.measure.records.chaos_dataset`).
    """
    if grid is not None:
        ds = checkpoint.normalise_scene(scene_records.chaos_dataset(layout, records, grid))
        ds.attrs["title"] = resolved["title"]
        return ds
    if scanned:
        ds = scene_records.assemble_scan(layout, records, body_coords)
    else:
        ds = scene_records.scene_dataset(records[0])
    ds = checkpoint.normalise_scene(ds)
    keep = resolved["outputs"]["arrays"]
    ds = ds.drop_vars([name for name in PER_SAMPLE if name in ds and name not in keep])
    if "sample" in ds and not any(name in ds for name in PER_SAMPLE):
        ds = ds.drop_vars("sample")
    for extra in extras:
        ds = ds.merge(extra)
    ds.attrs["title"] = resolved["title"]
    return ds


def stage_result(ds, resolved, staging, stem, *, action=None, start_drawing=None):
    """Write ``<staging>/<stem>.nc`` and the study's figures into the folder ``staging``; return ``(stored dataset,
    figure paths)``.

    ``start_drawing(stored, names, staging, stem, formats)`` starts drawing the figures elsewhere while the file is
    written and returns a function that waits for their paths (or gives None: they are then drawn here, by
    :func:`tumble.output.figures.save_figures`, as without it).
    """
    names, formats = resolved["outputs"]["figures"], tuple(resolved["outputs"]["format"])
    stored = io.stored_form(ds, title=resolved["title"], study=resolved, seed_entropy=ds.attrs.get("seed_entropy"),
                            action=action)
    finish = start_drawing(stored, names, staging, stem, formats) if start_drawing is not None and names else None
    io.write_dataset(stored, staging / f"{stem}.nc", stored=True)  # its own lock: no dask scheduler is asked
    drawn = finish() if finish is not None else None
    if drawn is None and names:
        from ..output import figures as plots  # matplotlib: only where figures are drawn

        drawn = plots.save_figures(stored, names, staging, stem, formats=formats)
    return stored, list(drawn or [])


def _scene_label(ds, index):
    """``axis=2 amplitude=0.001``: the scan coordinates of one scene (dimensions of length 1 left out)."""
    if not index:
        return f"axis={int(_only(ds.axis))} spin={_only(ds.spin):g} amplitude={_only(ds.amplitude):g}"
    parts = []
    for dim, i in zip(ds.rate.dims, index):
        if ds.sizes[dim] == 1:
            continue
        value = (ds["body_label"] if dim == "body" and "body_label" in ds.coords else ds[dim]).values[i]
        parts.append(f"{dim}={value:g}" if isinstance(value, float) else f"{dim}={value}")
    return " ".join(parts) or "scene"


def _only(variable):
    """The value of a variable holding one value, whatever its number of (length-1) dimensions."""
    return float(np.asarray(variable).reshape(-1)[0])


def summary_table(ds, limit=24):
    """Measured against theory, as text: one line per scene, or per kind for a scan of more than ``limit``; a chaos
    map's indicators (:func:`chaos_summary`)."""
    if "kind" not in ds:  # no linear-theory kind: a chaos map
        return chaos_summary(ds)
    rate = np.atleast_1d(ds.rate.values)
    kinds, errors = np.atleast_1d(ds.kind.values).astype(str), np.atleast_1d(ds.rel_error.values)
    lines = []
    if rate.size <= limit:
        lines.append(f"{'scene':38s} {'kind':11s} {'measured':>12s} {'theory':>12s} {'rel. error':>10s}")
        for index in np.ndindex(ds.rate.shape):
            lines.append(f"{_scene_label(ds, index)[:38]:38s} {str(ds.kind.values[index]):11s} "
                         f"{float(ds.rate.values[index]):12.6g} {float(ds.rate_theory.values[index]):12.6g} "
                         f"{float(ds.rel_error.values[index]):10.2e}")
    else:
        lines.append(f"{'kind':11s} {'scenes':>7s} {'median rel. error':>18s} {'worst':>10s}  worst scene")
        for kind in sorted(set(kinds.ravel())):
            picked = np.where(kinds == kind, errors, np.nan)
            if np.isfinite(picked).any():
                worst = np.unravel_index(np.nanargmax(picked), picked.shape)
                lines.append(f"{kind:11s} {np.count_nonzero(kinds == kind):7d} {np.nanmedian(picked):18.2e} "
                             f"{picked[worst]:10.2e}  {_scene_label(ds, worst)}")
    if "wp_error" in ds:
        from ..measure import precision

        fast = precision.speedups(ds)
        lines.append(f"\n{'error':>8s} {'best tumble method':>20s} {'x DOP853':>9s} {'exact x DOP853':>15s}")
        for i, error in enumerate(fast.error.values):
            lines.append(f"{error:8.0e} {str(fast.best_tumble.values[i]):>20s} "
                         f"{float(fast.best_tumble_speedup[i]):9.1f} {float(fast.exact_speedup[i]):15.1f}")
        if "heyoka" not in [str(s) for s in ds["solver"].values]:
            lines.append("heyoka not installed: no heyoka curve, errors against the closed form "
                         "(pip install 'tumble[bench]')")
    bad = int(np.count_nonzero(~np.isfinite(rate)))
    if bad:
        lines.append(f"{bad} scene(s) gave no rate: every sample was excluded (see sample_status)")
    if rate.size == 1 and "rate_ci_low" in ds and "samples_used" in ds:  # one scene, perhaps a scan of one value
        lines.append(f"95% interval of the median (order statistics) [{_only(ds.rate_ci_low):.8g}, "
                     f"{_only(ds.rate_ci_high):.8g}] {ds.rate.attrs.get('units', '')}; "
                     f"{int(_only(ds.samples_used))} samples used, "
                     f"{int(_only(ds.samples_excluded))} excluded")
    if "flip_first" in ds and np.isfinite(ds.flip_first.values).any() and ds.flip_first.size == 1:
        lines.append(f"first flip {_only(ds.flip_first):.4g} s (asymptote {_only(ds.flip_first_asymptote):.4g} s), "
                     f"then every {_only(ds.flip_spacing):.6g} s (exact 2K/nu {_only(ds.flip_spacing_exact):.6g} s)")
    return "\n".join(lines)


#: MEGNO above which a chaos map's summary counts an orbit chaotic (2 is the regular value; the threshold leaves
#: room for the slow approach to 2 over a finite horizon).
CHAOTIC_MEGNO = 4.0


def chaos_summary(ds):
    """A chaos map as text: its size, the share of chaotic orbits (``<Y>`` > :data:`CHAOTIC_MEGNO`), the range of the
    largest exponent, the orbits that stopped."""
    lines = [f"chaos map of {ds.attrs.get('model', 'a model')}: " + " x ".join(
        f"{dim} ({ds.sizes[dim]})" for dim in ds["status"].dims) + f", T = {ds.attrs.get('t_end', float('nan')):g} s"]
    if "megno" in ds:
        megno = np.asarray(ds["megno"].values, dtype=float)
        lines.append(f"MEGNO <Y>: median {np.nanmedian(megno):.3g}, {np.mean(megno > CHAOTIC_MEGNO):.0%} of the orbits "
                     f"above {CHAOTIC_MEGNO:g} (chaotic), {np.mean(megno <= CHAOTIC_MEGNO):.0%} regular")
    if "exponent" in ds:
        largest = np.asarray(ds["exponent"].isel(index=0).values, dtype=float)
        lines.append(f"largest Lyapunov exponent: {np.nanmin(largest):.3g} to {np.nanmax(largest):.3g} 1/s "
                     f"(median {np.nanmedian(largest):.3g}); spectrum sum (median) "
                     f"{np.nanmedian(ds['exponent'].sum('index').values):.2e} 1/s")
    if "gali" in ds:
        final = np.asarray(ds["gali"].isel(gali_time=-1).values, dtype=float)
        lines.append(f"GALI at the end: median {np.nanmedian(final):.3g}")
    status = np.asarray(ds["status"].values)
    stopped = status != registry.STATUS_OK
    if stopped.any():  # by status (the codes of registry.ADAPTIVE_STATUSES, every chaos map's)
        reasons = {registry.STATUS_NONFINITE: "non-finite or a lost tangent direction"}
        counts = ", ".join(f"{np.count_nonzero(status == code)} "
                           f"{reasons.get(code, registry.ADAPTIVE_STATUSES[code].name)}"
                           for code in np.unique(status[stopped]))
        lines.append(f"{int(stopped.sum())} orbit(s) stopped early ({counts}; see status)")
    return "\n".join(lines)
