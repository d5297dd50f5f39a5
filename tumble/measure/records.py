"""Scene records and the xarray Datasets built from them: NumPy and xarray only, no kernel.

A scene record (:func:`tumble.measure.reduction.scene_records`) is a flat dict of NumPy values: every variable,
coordinate and ``@attribute`` of the scene's dataset. This module holds what a record's names mean (units, long
names, dimensions: :func:`variable_metadata`) and builds the datasets: one scene (:func:`scene_dataset`) or a scan
(:func:`assemble_scan`). It imports no numba, so the process that writes a study's results (the figure process of
``tumble run``) builds them without loading the kernels; and xarray only where a dataset is made, so the process
that runs the scenes never loads it.
"""

from __future__ import annotations

import numpy as np

from ..registry import ADAPTIVE_STATUSES, MODEL_PARAMETERS, SAMPLE_STATUS_NAMES, STATE_BLOCKS

__all__ = ["CHAOS_VARIABLES", "CONFIDENCE", "COORDS", "INTERVAL_TEXT", "KIND_UNITS", "assemble_scan", "chaos_dataset", "record_variables", "scene_dataset",
           "stack_records", "unstack_records", "variable_metadata"]

#: Level of a scene's confidence interval of the median (distribution-free, from order statistics:
#: :func:`tumble.measure.estimators.summarize`).
CONFIDENCE = 0.95

#: Unit of a rate of each kind.
KIND_UNITS = {"periodic": "rad/s", "exponential": "1/s", "neutral": "rad/s"}

#: The ``median_interval`` attribute of a scene: how its interval is made.
INTERVAL_TEXT = (f"{CONFIDENCE:.0%} distribution-free interval of the median: order statistics x_(l), x_(n+1-l) with "
                 "l from Binomial(n, 1/2)")


def variable_metadata(kind, value):
    # size: a table with one row per variable a scene record may hold (the free body's and the models')
    """``name -> (dims, attrs)`` of every variable and coordinate a scene record may hold."""
    unit = KIND_UNITS[kind]
    flag_names = " ".join(name.replace(" ", "_").replace("-", "_") for name in SAMPLE_STATUS_NAMES)
    table = {
        "rate": (unit, f"measured {kind} rate: median over valid samples"),
        "rate_theory": (unit, f"linear-theory {kind} rate"),
        "rel_error": ("1", "relative error of the measured rate, |rate - rate_theory| / "
                      + ("rate_theory" if value > 0 else "|spin| (neutral: theory is 0)")),
        "kind": ("1", "linear-theory kind: periodic, exponential or neutral"),
        "rate_ci_low": (unit, f"lower bound of the {CONFIDENCE:.0%} confidence interval of the median rate "
                              "(order statistics)"),
        "rate_ci_high": (unit, f"upper bound of the {CONFIDENCE:.0%} confidence interval of the median rate "
                               "(order statistics)"),
        "rate_spread": (unit, "half the interquartile range of the sample rates"),
        "samples_used": ("1", "samples with a valid rate"),
        "samples_excluded": ("1", "samples left out (bad status or failed fit)"),
        "sample_rate": (unit, f"measured {kind} rate of each sample (NaN: excluded)", ("sample",)),
        "sample_status": ("1", "status of each sample", ("sample",),
                          {"flag_values": np.arange(len(SAMPLE_STATUS_NAMES), dtype=np.int8),
                           "flag_meanings": flag_names}),
        "dt": ("s", "time step (closed form: spacing of the evaluation times)"),
        "t_end": ("s", "horizon of the scene"),
        "n_steps": ("1", "fixed steps to the horizon"),
        "sample_steps_computed": ("1", "sample-steps the kernel computed"),
        "sample_steps_skipped": ("1", "sample-steps skipped (closed form, early stop)"),
        "path": ("1", "how the scene ran"),
        "fit_t_start": ("s", "start of the fit window (median over samples)"),
        "fit_t_stop": ("s", "end of the fit window (median over samples)"),
        "fit_norm_start": ("rad/s", "scaled transverse norm at the start of the fit window (median over samples)"),
        "fit_norm_stop": ("rad/s", "scaled transverse norm at the end of the fit window (median over samples)"),
        "fit_saturation": ("rad/s", "end of the linear regime (scaled norm)"),
        "signal_radius": ("rad/s", "median scaled transverse radius (the signal of the phase fit)"),
        "flips_timed": ("1", "samples with at least two flips timed"),
        "flip_first": ("s", "time of the first flip (median over samples)"),
        "flip_first_asymptote": ("s", "linear-theory first flip time (1/lambda) ln(4/k') (median)"),
        "flip_spacing": ("s", "time between flips (median over samples)"),
        "flip_spacing_exact": ("s", "exact time between flips 2K/nu (median)"),
        "flip_spacing_asymptote": ("s", "linear-theory time between flips (2/lambda) ln(4/k') (median)"),
        "flip_spacing_rel_error": ("1", "largest |spacing / (2K/nu) - 1| over samples"),
        "sample_first_flip": ("s", "time of the first flip", ("sample",)),
        "sample_flip_spacing": ("s", "mean time between flips", ("sample",)),
        "growth_time": ("s", "probe time of the transverse norm", ("growth_point",)),
        "growth_norm": ("rad/s", "scaled transverse norm, median over samples", ("growth_point",)),
        "growth_norm_q1": ("rad/s", "scaled transverse norm, lower quartile over samples", ("growth_point",)),
        "growth_norm_q3": ("rad/s", "scaled transverse norm, upper quartile over samples", ("growth_point",)),
        "trace_time": ("s", "time along the traced sample (NaN: padding)", ("trace_point",)),
        "trace_omega": ("rad/s", "body-frame angular velocity of the first sample", ("trace_point", "component")),
        "I1": ("kg m2", "principal moment of inertia 1"),
        "I2": ("kg m2", "principal moment of inertia 2"),
        "I3": ("kg m2", "principal moment of inertia 3"),
        "axis": ("1", "spin axis (1-based principal axis)"),
        "spin": ("rad/s", "unperturbed spin about the axis"),
        "amplitude": ("rad", "tilt of the perturbed spins from the axis"),
        "method": ("1", "integration method asked for"),
        "sample": ("1", "sample index", ("sample",)),
        "component": ("1", "body-frame component (principal axis)", ("component",)),
        "model": ("1", "model kind (registry.MODELS): free, gyrostat, heavy_top, gravity_gradient, damper"),
        **{p.key: (p.units, p.text) for p in MODEL_PARAMETERS},  # the registry holds them once
        "system": ("1", "the measured System's name"),
    }
    return {name: (entry[2] if len(entry) > 2 else (), {"units": entry[0], "long_name": entry[1],
                                                        **(entry[3] if len(entry) > 3 else {})})
            for name, entry in table.items()}


#: Record entries that are coordinates of the scene's dataset (the rest are variables, or ``@`` attributes).
COORDS = ("I1", "I2", "I3", "axis", "spin", "amplitude", "method", "sample", "component", "model", "rotor", "mgl",
          "orbit_rate", "damper_inertia", "damping", "system")


def _record_entries(record):
    """``(data variables, coordinates, attributes)`` of a scene record: ``name -> (dims, ndarray, attrs)`` and a dict."""
    meta = variable_metadata(str(record["kind"]), float(record["rate_theory"]))
    data, coords, attrs = {}, {}, {}
    for name, value in record.items():
        if name.startswith("@"):
            attrs[name[1:]] = value.item() if value.ndim == 0 else value
            continue
        dims, var_attrs = meta[name]
        (coords if name in COORDS else data)[name] = (dims, value, var_attrs)
    return data, coords, attrs


def record_variables(record):
    """``(data variables, coordinates, attributes)`` of a scene record, as xarray Variables and a dict."""
    import xarray as xr

    data, coords, attrs = _record_entries(record)
    return ({name: xr.Variable(*entry) for name, entry in data.items()},
            {name: xr.Variable(*entry) for name, entry in coords.items()}, attrs)


def scene_dataset(record):
    """The dataset of one scene (:func:`tumble.measure`) from its record
    (:func:`~tumble.measure.reduction.scene_records`): what ``xr.Dataset(data, coords, attrs)`` builds, from the
    record's numpy arrays directly (:func:`tumble.engine.integration.indexed_dataset`), so that xarray does not import
    dask to look for its arrays in a new process."""
    from ..engine.integration import indexed_dataset

    data, coords, attrs = _record_entries(record)
    return indexed_dataset({**data, **coords}, attrs, coords=list(coords))


def assemble_scan(layout, records, body_coords=None):
    """The scan's dataset from the records (:func:`~tumble.measure.reduction.scene_records`) of every scene of a
    :func:`~tumble.measure.scans.scan_layout`, in order.

    Every variable and coordinate that differs between scenes (the swept parameters) gains the scan dimensions
    ``(body, *swept)`` in front of its own; a variable some scenes lack (a periodic scene has no growth fit window)
    is NaN there; attributes are the first scene's. The values are stacked from the records with NumPy, once per
    variable; the variables' metadata comes from the first scene holding each (no per-scene dataset is made).
    """
    import xarray as xr

    moments, swept = layout["moments"], layout["swept"]
    if len(records) != layout["scenes"]:
        raise ValueError(f"a scan of {layout['scenes']} scenes cannot be assembled from {len(records)}")
    shape, dims = (len(moments), *(len(v) for v in swept.values())), ("body", *swept)
    owners, seen = {}, set()
    for record in records:  # one set of Variables per distinct layout of record (kind, fields)
        key = (record["kind"].item(), tuple(record))
        if key not in seen:
            seen.add(key)
            data, coords, attrs = record_variables(record)
            for name, var in (*data.items(), *coords.items()):
                owners.setdefault(name, (var, name in coords))
    first_attrs = record_variables(records[0])[2]
    data, coords = {}, {}
    for name, (var, is_coord) in owners.items():
        if name in ("I1", "I2", "I3"):
            continue
        values = [record.get(name) for record in records]
        missing = any(v is None for v in values)
        if missing:
            if var.dtype.kind not in "biuf":
                raise ValueError(f"scene variable {name!r} ({var.dtype}) is missing from some scenes")
            dtype = np.result_type(var.dtype, np.float64) if var.dtype.kind in "biu" else var.dtype
            gap = np.full(var.shape, np.nan, dtype)
            values = [gap if v is None else v for v in values]
        stacked = np.stack(values)
        if is_coord and name not in swept and not missing and (stacked == var.values).all():
            coords[name] = var  # the same in every scene (the sample index, a fixed parameter)
            continue
        stacked = stacked.reshape(shape + var.shape)
        if name in swept:  # a swept parameter: the coordinate of its dimension
            axis = dims.index(name)
            coords[name] = xr.Variable((name,), stacked[(0,) * axis + (slice(None),) + (0,) * (len(dims) - axis - 1)],
                                       var.attrs)
            continue
        (coords if is_coord else data)[name] = xr.Variable(dims + var.dims, stacked, var.attrs)
    out = xr.Dataset(data, coords=coords, attrs=first_attrs)
    meta = variable_metadata("periodic", 1.0)  # the moments' entries depend on neither
    out = out.assign_coords(
        {name: ("body", moments[:, k], meta[name][1]) for k, name in enumerate(("I1", "I2", "I3"))}
        | {"body": ("body", np.arange(len(moments), dtype=np.int64), {"units": "1", "long_name": "body index"})})
    for name, v in (body_coords or {}).items():
        v = np.asarray(v)
        if v.shape != (len(moments),):
            raise ValueError(f"body_coords[{name!r}] must have one value per body ({len(moments)}), got shape "
                             f"{v.shape}")
        out = out.assign_coords({name: ("body", v, {"units": "1", "long_name": name.replace("_", " ")})})
    out = out.transpose("body", *swept, ..., "sample", missing_dims="ignore")  # no "sample": no per-sample array kept
    out.attrs["title"] = "tumble scan: measured rates against linear theory"
    return out


def stack_records(records):
    """Scene records as a few stacked arrays, to send to another process (:func:`unstack_records` gives them back
    exactly: names, dtypes, shapes and values). Pickling a 1200-scene scan's records one small array at a time
    takes 0.3 s on each side; its stacked columns a few milliseconds.

    Returns ``(number of records, groups)``: a group is ``(positions, numeric, text, names)`` for the records with
    the same names (in the same order), numeric dtypes and shapes — ``numeric`` maps a name to its values stacked
    along a new first axis, ``text`` a name to its strings and their dtypes (a string's dtype holds its length,
    which differs between records)."""
    groups = {}
    for i, record in enumerate(records):  # 5 ms for 1200 records of 31 values (a key per value: 13 ms)
        values = record.values()
        key = (tuple(record), tuple(["U" if value.dtype.kind == "U" else value.dtype for value in values]),
               tuple([value.shape for value in values]))
        groups.setdefault(key, []).append(i)
    stacked = []
    for (names, dtypes, _), positions in groups.items():
        numeric, text = {}, {}
        for name, dtype in zip(names, dtypes):
            values = [records[i][name] for i in positions]
            if isinstance(dtype, str):
                text[name] = ([value.tolist() for value in values],  # a str (0-d) or a list of them
                              [value.dtype.str for value in values])
            else:  # one dtype and shape in the group: np.array stacks them as np.stack does, 10x faster
                numeric[name] = np.array(values, dtype=dtype)
        stacked.append((positions, numeric, text, list(names)))
    return len(records), stacked


def unstack_records(stacked):
    """The records :func:`stack_records` was given."""
    count, groups = stacked
    records = [None] * count
    for positions, numeric, text, names in groups:
        for j, i in enumerate(positions):
            record = {}
            for name in names:
                if name in numeric:
                    record[name] = numeric[name][j, ...]  # `...`: a 0-d array, not a NumPy scalar
                else:
                    strings, dtypes = text[name]
                    record[name] = np.asarray(strings[j], dtype=dtypes[j])
            records[i] = record
    return records


#: A chaos record's entries (:func:`tumble.measure.chaos_scenes.scene_records`): ``name -> (units, long name, the
#: dimensions after the map's)``; ``None`` dimensions: a coordinate of its own.
CHAOS_VARIABLES = {
    "megno": ("1", "mean MEGNO <Y> at the end (2: quasi-periodic, 0: near a stable periodic orbit, ~ lambda t / 2: "
                   "chaotic)", ()),
    "megno_lyapunov": ("1/s", "maximal Lyapunov exponent from the slope of <Y> (2 x slope)", ()),
    "exponent": ("1/s", "Lyapunov exponent, sorted descending", ("index",)),
    "finite_time": ("1/s", "finite-time Lyapunov exponent since the transient, sorted descending",
                    ("time", "index")),
    "gali": ("1", "GALI_k, the generalised alignment index", ("gali_time",)),
    "status": ("1", "worst status of the orbit over the indicators and the section (0: ok)", ()),
    "crossings": ("1", "crossings of the orbit's section (NaN past them)", ()),
    "steps": ("1", "steps of the orbit's section run, accepted and rejected", ()),
    "section_time": ("s", "time of the crossing", ("crossing",)),
    "section_state": ("see component_units", "state at the crossing", ("crossing", "component")),
    "section_point": ("see section_axis", "the section figure's coordinates at the crossing (chaos.start's inverse "
                                          "or a component)", ("crossing", "section_axis")),
    "finite_time_time": ("s", "time of the finite-time exponents", None),
    "gali_time": ("s", "time of GALI", None),
}


def _component_unit(name):
    """The unit of a built-in model's state component (``w1``: rad/s), by its letter."""
    return next((unit for letter, _, unit in STATE_BLOCKS if name[0] == letter and name[1:].isdigit()), "1")


def chaos_dataset(layout, records, grid):
    """The Dataset of a chaos study from its scene records: every indicator over the map's dimensions (``grid``:
    ``{name: coordinate values}``, the map's coordinates in order) after the scan's (``layout["swept"]``: the model's
    parameters, the method), with the curves' dimensions last; the map's and the scan's values as coordinates;
    attributes from the first scene (its parameters, method, step, horizon)."""
    import xarray as xr

    swept = layout["swept"]
    scan_shape = tuple(len(v) for v in swept.values())
    map_shape = tuple(len(v) for v in grid.values())
    dims = (*swept, *grid)
    units = {"tilt": "rad", "angle": "rad", "rate": "rad/s", **{name: _component_unit(name) for name in grid}}
    names = {"tilt": "release tilt of body axis 3 from the vertical", "rate": "initial spin rate",
             "angle": "angle of the roll axis from the orbit frame about the orbit normal"}
    first = records[0]
    data, coords = {}, {}
    for name, (unit, long_name, extra) in CHAOS_VARIABLES.items():
        if name not in first:
            continue
        attrs = {"units": unit, "long_name": long_name}
        if extra is None:
            dim = "time" if name == "finite_time_time" else name  # the finite-time exponents' times: "time"
            coords[dim] = xr.Variable((dim,), first[name], attrs)
            continue
        stacked = np.stack([np.asarray(r[name]) for r in records])
        stacked = stacked.reshape(scan_shape + map_shape + stacked.shape[2:])
        if name == "status":
            attrs.update(flag_values=np.arange(len(ADAPTIVE_STATUSES), dtype=np.int8),
                         flag_meanings=" ".join(s.name.replace(" ", "_") for s in ADAPTIVE_STATUSES))
            stacked = stacked.astype(np.int8)
        data[name] = xr.Variable(dims + extra, stacked, attrs)
    for name, values in grid.items():
        coords[name] = xr.Variable((name,), np.asarray(values, dtype=float),
                                   {"units": units.get(name, "1"), "long_name": names.get(name, name)})
    for name, values in swept.items():
        meta = variable_metadata("periodic", 1.0).get(name, ((), {"units": "1", "long_name": name}))[1]
        coords[name] = xr.Variable((name,), np.asarray(values), meta)
    if "section_time" in first:
        names = str(first["@state"]).split()
        coords["crossing"] = xr.Variable(("crossing",), np.arange(first["section_time"].shape[-1]),
                                         {"long_name": "crossing, in time order"})
        coords["component"] = xr.Variable(("component",), np.array(names), {"long_name": "state component"})
        coords["component_units"] = xr.Variable(("component",), np.array([_component_unit(n) for n in names]),
                                                {"long_name": "units of each state component"})
        coords["section_axis"] = xr.Variable(("section_axis",), np.array(str(first["@section_axes"]).split()),
                                             {"long_name": "coordinate of the section figure"})
    if "exponent" in first:
        coords["index"] = xr.Variable(("index",), np.arange(1, first["exponent"].shape[-1] + 1),
                                      {"units": "1", "long_name": "exponent index (1: the largest)"})
    attrs = {name[1:]: (value.item() if value.ndim == 0 else value) for name, value in first.items()
             if name.startswith("@")}
    attrs.update(map_dims=" ".join(grid), scan_dims=" ".join(swept))
    for name, value in first.items():  # a parameter the scan fixed: a scalar coordinate
        if not name.startswith("@") and name not in CHAOS_VARIABLES and name not in swept:
            meta = variable_metadata("periodic", 1.0).get(name, ((), {"units": "1", "long_name": name}))[1]
            coords[name] = xr.Variable((), value, meta)
    return xr.Dataset(data, coords=coords, attrs=attrs)
