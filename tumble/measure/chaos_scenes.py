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
- ``spin_orbit``: the body turned by ``angle`` about its pitch axis 2 (the orbit normal's line) from the orbit frame
  at perigee, ``q = (cos(angle/2), 0, sin(angle/2), 0)``, spinning at ``rate`` (inertial) about the orbit normal:
  ``w = (0, -rate, 0)`` (axis 2 is the negative orbit normal, so the synchronous spin of a circular orbit is
  ``w2 = -n``). The planar motion is an invariant subspace; the tangent vectors also probe the motion out of it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import registry
from ..engine import chaos
from ..physics import models

__all__ = ["ChaosScene", "initial_states", "map_grid", "scene_plan", "scene_records", "scene_samples"]


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
    if start == "spin_orbit":
        angle, rate = points["angle"], points["rate"]
        y = np.zeros((len(angle), 7))
        y[:, 1] = -rate
        y[:, 3], y[:, 5] = np.cos(angle / 2), np.sin(angle / 2)
        return y
    raise ValueError(f"chaos.start must be one of {', '.join(s.name for s in registry.CHAOS_STARTS)}, got {start!r}")


def scene_plan(kind, moments, parameters, start, points, options, method, coords):
    """The :class:`ChaosScene` of a model ``kind`` (its ``parameters`` by study key, extras included), the map's
    ``points`` and the study's ``options`` (``chaos`` table with ``dt``, ``horizon``, ``device``)."""
    model = models.from_kind(kind, moments, **parameters)
    return ChaosScene(model, initial_states(start, points, options["state"], model.spec.state), tuple(options["indicators"]), method, options["dt"],
                      options["horizon"], options["renormalise"], options["transient"], options["exponents"],
                      options["gali_k"], options["points"], options["device"], dict(coords))


def _save_every(scene):
    n_steps = max(1, round(scene.horizon / scene.dt))
    return max(1, n_steps // scene.points)


def scene_samples(scene, start, stop):
    """Run points ``[start, stop)`` of the map: ``{name: array with the points first}`` of every indicator asked for,
    the times of the curves (``*_time``), the worst status of each point (0: ok) and ``start``."""
    y = scene.states[start:stop]
    common = {"method": scene.method, "device": scene.device}
    out = {}
    status = np.zeros(len(y), dtype=np.int8)
    if "megno" in scene.indicators:
        ds = chaos.megno(scene.model, y, scene.horizon, scene.dt, **common)
        out["megno"] = ds["megno"].values
        out["megno_lyapunov"] = ds["lyapunov"].values
        status = np.maximum(status, ds["status"].values)
    if "lyapunov" in scene.indicators:
        ds = chaos.lyapunov(scene.model, y, scene.horizon, scene.dt, exponents=scene.exponents or None,
                            renormalise=scene.renormalise, transient=scene.transient,
                            save_every=_save_every(scene), **common)
        out["exponent"] = ds["exponent"].values
        out["finite_time"] = ds["finite_time"].values
        out["finite_time_time"] = ds["time"].values
        status = np.maximum(status, ds["status"].values)
    if "gali" in scene.indicators:
        ds = chaos.gali(scene.model, y, scene.horizon, scene.dt, k=scene.gali_k, save_every=_save_every(scene),
                        **common)
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

