"""The scenes of a chaos study: maps of chaos indicators over initial states, planned, run and reduced to records.

A chaos study (``chaos.indicators`` not empty) maps :func:`tumble.megno`, :func:`tumble.lyapunov` and
:func:`tumble.gali` over a grid of initial states. The grid's coordinates are those of a physical parametrisation
(``chaos.start``, :data:`tumble.registry.CHAOS_STARTS`): a heavy top's release tilt and spin (``"release"``), a
satellite's angle and rate about the orbit normal (``"spin_orbit"``). One *scene* is one combination of the study's
other scan keys (the model's parameters, the method); its *samples* are the points of the map, one orbit each, run
together through one tangent loop (vectorised across the points, in parallel). :func:`scene_samples` runs a range
of them (what a split scene's chunk or a dask task runs); :func:`scene_records` joins the ranges into one record per
scene, a flat dict of NumPy values that :func:`tumble.measure.records.chaos_dataset` turns into the map's Dataset.

Initial states (the choices the issue leaves open; docs/explanation/chaos-maps.md says why):

- ``release``: ``w = (0, 0, rate)`` and the upward vertical in body axes ``g = (0, sin tilt, cos tilt)``: body axis
  3 tilted by ``tilt`` from the vertical by a turn about body axis 1.
- ``state``: any model's state ``chaos.state`` with the components that ``scan.state`` names replaced by each
  point of their grid (values as given: nothing is normalised).
- ``swing``: the upward vertical ``g = (0, sin tilt, cos tilt)`` as ``release``'s, turning about body axis 1 alone,
  ``w = (w1, 0, 0)`` with ``w1 = sqrt(2 (energy − mgl c·g) / I1) >= 0`` (:func:`swing_potential`): every orbit on the
  energy level ``chaos.energy`` with ``L·g = 0`` (``g1 = 0``), as a Poincaré section of the asymmetric top asks
  (Arnold's reduction leaves two degrees of freedom on a level of the energy and of ``L·g``).
- ``spin_orbit``: the body turned by ``angle`` about its pitch axis 2 (the orbit normal's line) from the orbit frame
  at perigee, ``q = (cos(angle/2), 0, sin(angle/2), 0)``, spinning at ``rate`` (inertial) about the orbit normal:
  ``w = (0, -rate, 0)`` (axis 2 is the negative orbit normal, so the synchronous spin of a circular orbit is
  ``w2 = -n``). The planar motion is an invariant subspace; the tangent vectors also probe the motion out of it.

A section study (a ``[section]`` table) runs each orbit with :func:`tumble.section` too and keeps its crossings, with
their coordinates in the start's terms (:func:`start_coordinates`: the inverse of the start, at the crossing).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import registry
from ..engine import chaos, sections
from ..physics import models

__all__ = ["ChaosScene", "initial_states", "map_grid", "scene_plan", "scene_records", "scene_samples",
           "start_coordinates", "swing_potential"]


class ChaosScene(NamedTuple):
    """One scene of a chaos study: the model, the map's initial states and what to compute (trusted: the study's
    config checked every value)."""

    model: object  # a built-in model (tumble.models)
    states: np.ndarray  # (N, n) the map's initial states, in the map's C order
    indicators: tuple  # of registry.CHAOS_INDICATORS
    method: str
    dt: float
    horizon: float
    renormalise: float
    transient: float
    exponents: int  # 0: the whole spectrum
    gali_k: int
    points: int
    device: str
    coords: dict  # the scene's scan values (name -> scalar), for its record
    rtol: float  # an error-controlled method's tolerance
    atol: float
    section: dict | None  # the study's [section] table (None: no section)
    start: str  # chaos.start
    max_steps: int  # an error-controlled method's steps per orbit


def map_grid(start, values):
    """``(dims, coordinates, points)`` of the map of ``chaos.start`` ``start``: ``dims`` the scanned coordinates in
    the order of the start's keys, ``coordinates`` ``{name: 1-D array}`` of them, ``points`` ``{key: (N,) array}`` of
    every key of the start at each point of the grid (C order; N = 1 with no key scanned). ``values``: each key's one
    value or list of values."""
    keys = next(s for s in registry.CHAOS_STARTS if s.name == start).keys or tuple(values)  # "state": as named
    dims = tuple(key for key in keys if isinstance(values[key], (list, tuple, np.ndarray)))
    coordinates = {key: np.asarray(values[key], dtype=float) for key in dims}
    mesh = np.meshgrid(*coordinates.values(), indexing="ij") if dims else []
    points = {key: (mesh[dims.index(key)].ravel() if key in dims else np.array([float(values[key])]))
              for key in keys}
    size = max((len(v) for v in points.values()), default=1)
    points = {key: np.broadcast_to(v, (size,)).copy() for key, v in points.items()}
    return dims, coordinates, points


def initial_states(start, points, base=None, names=None):
    """The initial states ``(N, n)`` of the map's points (``points`` from :func:`map_grid`); see the module
    docstring. ``"state"``: the state ``base`` (components ``names``) with the named components of each point."""
    if start == "state":
        y = np.tile(np.asarray(base, dtype=float), (len(next(iter(points.values()))), 1))
        for name, values in points.items():
            y[:, list(names).index(name)] = values
        return y
    if start == "release":
        tilt, rate = points["tilt"], points["rate"]
        y = np.zeros((len(tilt), 6))
        y[:, 2] = rate
        y[:, 4], y[:, 5] = np.sin(tilt), np.cos(tilt)
        return y
    if start == "swing":
        tilt = points["tilt"]
        y = np.zeros((len(tilt), 6))
        y[:, 4], y[:, 5] = np.sin(tilt), np.cos(tilt)
        y[:, 0] = np.sqrt(np.maximum(2.0 * (points["energy"] - points["potential"]) / points["I1"], 0.0))
        return y
    if start == "spin_orbit":
        angle, rate = points["angle"], points["rate"]
        y = np.zeros((len(angle), 7))
        y[:, 1] = -rate
        y[:, 3], y[:, 5] = np.cos(angle / 2), np.sin(angle / 2)
        return y
    raise ValueError(f"chaos.start must be one of {', '.join(s.name for s in registry.CHAOS_STARTS)}, got {start!r}")


def swing_potential(tilt, mgl, centre):
    """The heavy top's potential ``mgl c·g`` (J) at ``g = (0, sin tilt, cos tilt)``, ``c`` the unit direction of
    ``centre``."""
    c = np.asarray(centre, dtype=float) / np.linalg.norm(centre)
    return mgl * (c[1] * np.sin(tilt) + c[2] * np.cos(tilt))


def start_coordinates(start, names, states):
    """The coordinates of chaos.start ``start`` at the states ``states`` (..., n) of a model (components ``names``):
    its inverse (``release``: ``tilt = atan2(g2, g3)`` in [0, 2π), ``rate = w3``; ``swing``: the tilt; ``spin_orbit``: ``angle =
    2 atan2(q2, q0)`` mod π in [−π/2, π/2), the gravity-gradient torque's period in the angle, and ``rate = −w2``),
    and every state component by its name: ``{name: array (...)}``."""
    y = {name: states[..., i] for i, name in enumerate(names)}
    if start in ("release", "swing"):
        y["tilt"] = np.mod(np.arctan2(y["g2"], y["g3"]), 2.0 * np.pi)
        if start == "release":
            y["rate"] = y["w3"]
    elif start == "spin_orbit":
        y["angle"] = np.mod(2.0 * np.arctan2(y["q2"], y["q0"]) + 0.5 * np.pi, np.pi) - 0.5 * np.pi
        y["rate"] = -y["w2"]
    return y


def scene_plan(kind, moments, parameters, start, points, options, method, coords):
    """The :class:`ChaosScene` of a model ``kind`` (its ``parameters`` by study key, extras included), the map's
    ``points`` and the study's ``options`` (``chaos`` table with ``dt``, ``horizon``, ``device``, ``rtol``, ``atol``,
    ``max_steps`` and the ``section`` table or None)."""
    model = models.from_kind(kind, moments, **parameters)
    if start == "swing":  # the energy level: each tilt's potential, and I1
        points = {**points, "energy": options["energy"], "I1": model.moments[0],
                  "potential": swing_potential(points["tilt"], model.mgl, model.centre)}
    return ChaosScene(model, initial_states(start, points, options["state"], model.spec.state),
                      tuple(options["indicators"]), method, options["dt"], options["horizon"], options["renormalise"],
                      options["transient"], options["exponents"], options["gali_k"], options["points"],
                      options["device"], dict(coords), options["rtol"], options["atol"], options["section"], start,
                      options["max_steps"])


def _save_every(scene):
    n_steps = max(1, round(scene.horizon / scene.dt))
    return max(1, n_steps // scene.points)


def _curve_times(scene):
    """An error-controlled run's times of the finite-time exponents and GALI: :attr:`ChaosScene.points` of them, evenly
    after the transient, the last at the horizon."""
    return scene.transient + (scene.horizon - scene.transient) * np.arange(1, scene.points + 1) / scene.points


def _section(scene, y):
    """The section of the orbits ``y``: crossing times, states and the start's coordinates, padded with NaN to
    ``section.crossings``, the counts, steps and statuses."""
    section = scene.section
    where = ({"surface": (section["surface"], section["value"]), "direction": section["direction"]}
             if section["surface"] else {"period": section["period"], "phase": section["phase"]})
    ds = sections.section(scene.model, y, scene.horizon, max_crossings=section["crossings"], method=scene.method,
                          rtol=scene.rtol, atol=scene.atol, dt=scene.dt or None, max_steps=scene.max_steps,
                          device=scene.device, **where)
    most, count = section["crossings"], ds["crossing"].size
    times = np.full((len(y), most), np.nan)
    states = np.full((len(y), most, len(scene.model.spec.state)), np.nan)
    times[:, :count], states[:, :count] = ds["time"].values, ds["state"].values
    coordinates = start_coordinates(scene.start, scene.model.spec.state, states)
    return {"section_time": times, "section_state": states,
            "section_point": np.stack([coordinates[name] for name in section["axes"]], axis=-1),
            "crossings": ds["count"].values, "steps": ds["steps"].values + ds["rejected_steps"].values}, ds["status"]


def scene_samples(scene, start, stop):
    """Run points ``[start, stop)`` of the map: ``{name: array with the points first}`` of every indicator asked for,
    the times of the curves (``*_time``), the section's crossings, the worst status of each point (0: ok) and
    ``start``."""
    y = scene.states[start:stop]
    adaptive = scene.method in registry.ERROR_CONTROLLED
    common = ({"method": scene.method, "device": scene.device, "rtol": scene.rtol, "atol": scene.atol,
               "max_steps": scene.max_steps} if adaptive else {"method": scene.method, "device": scene.device})
    step = (scene.dt or None) if adaptive else scene.dt
    curves = {"times": _curve_times(scene)} if adaptive else {"save_every": _save_every(scene)}
    out = {}
    status = np.zeros(len(y), dtype=np.int8)
    if scene.section is not None:
        crossings, section_status = _section(scene, y)
        out.update(crossings)
        status = np.maximum(status, section_status.values)
    if "megno" in scene.indicators:
        ds = chaos.megno(scene.model, y, scene.horizon, step, **common)
        out["megno"] = ds["megno"].values
        out["megno_lyapunov"] = ds["lyapunov"].values
        status = np.maximum(status, ds["status"].values)
    if "lyapunov" in scene.indicators:
        ds = chaos.lyapunov(scene.model, y, scene.horizon, step, exponents=scene.exponents or None,
                            renormalise=scene.renormalise, transient=scene.transient, **curves, **common)
        out["exponent"] = ds["exponent"].values
        out["finite_time"] = ds["finite_time"].values
        out["finite_time_time"] = ds["time"].values
        status = np.maximum(status, ds["status"].values)
    if "gali" in scene.indicators:
        ds = chaos.gali(scene.model, y, scene.horizon, step, k=scene.gali_k, **curves, **common)
        out["gali"] = ds["gali"].values
        out["gali_time"] = ds["time"].values
        status = np.maximum(status, ds["status"].values)
    out["status"] = status
    out["start"] = np.asarray(start, dtype=np.int64)  # where the range begins (a checkpoint's chunk says so)
    return out


_SHARED = ("finite_time_time", "gali_time")  # the same in every range of a scene


def scene_records(scenes, parts):
    """One record per scene from its ranges (``parts``: per scene, the :func:`scene_samples` of its ranges in
    order): the points' arrays joined, the curves' times, the scene's coordinates and its attributes."""
    records = []
    for scene, ranges in zip(scenes, parts):
        ranges = list(ranges)
        record = {}
        ranges.sort(key=lambda part: int(part["start"]))
        for name in ranges[0]:
            if name == "start":
                continue
            record[name] = (np.asarray(ranges[0][name]) if name in _SHARED
                            else np.concatenate([np.asarray(r[name]) for r in ranges]))
        for name, value in scene.coords.items():
            record[name] = np.asarray(value)
        model = scene.model
        record["@model"] = np.asarray(model.kind)
        record["@method"] = np.asarray(registry.AUTO_STEPPING if scene.method == registry.AUTO else scene.method)
        record["@dt"] = np.asarray(scene.dt)
        if scene.method in registry.ERROR_CONTROLLED:
            record["@rtol"], record["@atol"] = np.asarray(scene.rtol), np.asarray(scene.atol)
        record["@start"] = np.asarray(scene.start)
        if scene.section is not None:
            section = scene.section
            record["@section"] = np.asarray(f"{section['surface']} = {section['value']:g}" if section["surface"] else
                                            f"t = {section['phase']:g} + k {section['period']:g} s")
            record["@section_axes"] = np.asarray(" ".join(section["axes"]))
            record["@section_colour"] = np.asarray(section["colour"])
            if section["surface"]:
                record["@direction"] = np.asarray(section["direction"])
        record["@t_end"] = np.asarray(scene.horizon)
        record["@indicators"] = np.asarray(" ".join(scene.indicators))
        record["@state"] = np.asarray(" ".join(model.spec.state))
        record["@moments"] = np.asarray(model.moments, dtype=float)
        for key, value in model.parameters.items():
            record[f"@parameter_{key}"] = np.asarray(value, dtype=float)
        if "lyapunov" in scene.indicators:
            record["@renormalise"] = np.asarray(scene.renormalise)
            record["@transient"] = np.asarray(scene.transient)
        if "gali" in scene.indicators:
            record["@gali_k"] = np.asarray(scene.gali_k)
        record["@title"] = np.asarray(f"tumble chaos map: {model.kind}, {', '.join(scene.indicators)}")
        records.append(record)
    return records

