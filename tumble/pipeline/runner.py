"""Run a study: resolve it, plan what its outputs need, run its scenes, write the netCDF file and figures.

The planner computes only what the study's ``outputs`` ask for: the per-sample arrays it keeps, the norm
curves only for ``norm_growth``, one traced sample only for ``flip_components``, the per-method invariant
record only for ``invariant_drift``, the work-precision runs only for ``work_precision`` and one spin's
orientation in space only for the attitude figures (``flip_animation``, ``flip_strip``, ``polhode``,
``herpolhode``).

Every check that can fail on the study's input runs before anything is computed or written, and every file
is written atomically (:func:`tumble.output.io.write_dataset`, :func:`tumble.output.figures.save_figures`), so invalid input
never leaves a file behind.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import shutil
import re
import sys
import time
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .. import _disk, registry
from ..engine.device import DeviceError, resolve_device
from ..engine.ensemble import torque_spec
from ..engine.sampling import CHUNK
from ..engine import cost
from ..engine.progress import tqdm
from ..measure import chaos_scenes, model_scenes
from ..measure import planning, reduction, running, scans, traces
from ..physics import exact, models, theory
from ..registry import STEPPING
from . import checkpoint, config, results, schema
from .config import StudyError

__all__ = ["DEFAULT_CHUNK_SAMPLES", "PER_SAMPLE", "TRACE_FIGURES", "ChaosScenes", "FreeScenes", "ModelSceneOptions", "ModelScenes",
           "Outputs", "PreparedStudy", "SceneOptions", "Task",
           "chunk_samples_size", "compute_samples", "compute_scenes", "compute_task", "default_chunk_scenes",
           "execute_study", "needs_traces", "open_checkpoint", "output_stem", "plan", "plan_tasks", "prepare_study",
           "run_scenes", "run_study", "sample_ranges", "scene_job", "write_outputs", "write_records"]

#: Per-sample variables a result may keep (``outputs.arrays``): :data:`tumble.pipeline.results.PER_SAMPLE`.
PER_SAMPLE = results.PER_SAMPLE

#: Figures that need curves :func:`tumble.measure.scene.measure` keeps only on request.
_CURVES = {"norm_growth": "norm", "flip_components": "trace"}

#: Samples of the per-method invariant record (``invariant_drift``).
_DRIFT_SAMPLES = 16


def output_stem(source, resolved):
    """File stem of a study's outputs: the study file's stem, else its title made file-safe."""
    if isinstance(source, (str, Path)) and not isinstance(source, Mapping):
        return Path(source).stem
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", resolved["title"]).strip("_.") or "study"


class _Options(Mapping):
    """Typed scene options that read as the keyword arguments of the scene function they go to (``**options``)."""

    def __getitem__(self, key):
        if key not in self._names():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(self._names())

    def __len__(self):
        return len(self._names())

    @classmethod
    def _names(cls):
        return tuple(f.name for f in dataclasses.fields(cls))

    @classmethod
    def of(cls, resolved, **others):
        """The record of a resolved study: the fields the study's description marks as scene options
        (:func:`tumble.pipeline.schema.scene_options`), and ``others``."""
        described = schema.scene_options(resolved)
        return cls(**{name: described[name] for name in cls._names() if name not in others}, **others)


@dataclass(frozen=True, eq=False)
class SceneOptions(_Options):
    """What every scene of a free-body study shares, checked by the study's config: the keywords of
    :func:`tumble.measure` and :func:`tumble.scan` (``dt`` and ``horizon`` None: the planner's)."""

    dt: float | None
    flips: int
    horizon: float | None
    distribution: str
    torque: dict | None  # the study's [torque] table; None when torque-free
    curves: tuple  # the curves the figures draw (norm, trace)
    device: str


@dataclass(frozen=True, eq=False)
class ModelSceneOptions(_Options):
    """What every scene of a model study shares: the keywords of :func:`tumble.measure.model_scenes.scene_plan`."""

    dt: float | None
    horizon: float | None
    distribution: str
    device: str


class StudyPlan(NamedTuple):
    """What a resolved study runs (:func:`plan`): the arguments of :func:`tumble.measure.scans.scan` (or of one
    ``measure``)."""

    moments: np.ndarray  # (B, 3) the scan's bodies, or (3,) the study's one body, kg m²
    body_coords: dict | None  # coordinates of the body dimension (triangle fractions, labels)
    values: dict  # axis, spin, amplitude, method: one value or a list (the scanned keys)
    options: SceneOptions | ModelSceneOptions  # the scenes' shared options (keyword arguments of measure)
    scanned: list  # the scan keys the study sets
    samples: int
    seed: int
    scenes: FreeScenes | ModelScenes  # what plans, runs and reduces the study's scenes


class Job(NamedTuple):
    """The scenes of a study as plain data that pickles to a dask worker (:func:`scene_job`)."""

    layout: dict  # tumble.measure.scans.scan_layout; layout["scenes"] scenes
    scanned: bool  # False: one measure
    samples: int
    seed: int
    options: SceneOptions | ModelSceneOptions
    body_coords: dict | None
    plan: StudyPlan
    scenes: FreeScenes | ModelScenes  # the plan's: chosen once per study (:func:`_scene_kind`)
    file: str = "<mapping>"
    arrays: tuple = tuple(PER_SAMPLE)  # the per-sample arrays the result keeps (outputs.arrays)


def _bodies(resolved):
    """``(moments (B, 3) or (3,), body coordinates or None)``: the scan's bodies, or the study's one body."""
    scan = resolved["scan"]
    if "triangle" in scan:
        moments, coords = scans.inertia_triangle(scan["triangle"])
        return moments, coords
    listed = config.scan_bodies(resolved)
    if listed is not None:
        moments, labels = listed
        moments = np.asarray(moments, dtype=float)
        if "moments" in scan:  # unnamed bodies: their moments say most
            labels = ["I=(" + ", ".join(f"{x:.7g}" for x in m) + ")" for m in moments]
        coords = {"body_label": np.array(labels)}
        if "k1" in scan:  # the gravity-gradient grid: its ratios, exactly as given
            k1, k3 = np.meshgrid(scan["k1"], scan["k3"], indexing="ij")
            coords.update(k1=k1.ravel().astype(float), k3=k3.ravel().astype(float))
        return moments, coords
    return config.resolve_body(resolved).moments, None


def plan(resolved, file="<mapping>"):
    """What a resolved study will run: a :class:`StudyPlan` of :func:`tumble.measure.scans.scan` / ``measure``
    arguments.

    Raises :class:`~tumble.pipeline.config.StudyError` for combinations that are valid field by field but cannot
    give what the study asks (a figure the scan cannot draw, a torque about an unstable axis).
    """
    return _scene_kind(resolved).plan(resolved, file)


def _scene_kind(resolved):
    """What plans, runs and reduces the scenes of a resolved study: the one switch between free-body scenes, model
    scenes (a study with a ``[model]`` table) and chaos maps (a study with ``chaos.indicators``)."""
    if "chaos" in resolved:
        return ChaosScenes(resolved.get("model", {"kind": registry.DEFAULT_MODEL})["kind"], resolved["chaos"]["start"])
    return ModelScenes(resolved["model"]["kind"]) if "model" in resolved else FreeScenes()


def _values(resolved):
    """The scene values a study scans or fixes: axis, spin, amplitude, method (one value or the scan's list)."""
    scan = resolved["scan"]
    return {"axis": scan.get("axis", resolved["spin"]["axis"]), "spin": scan.get("rate", resolved["spin"]["rate"]),
            "amplitude": scan.get("amplitude", resolved["perturbation"]["amplitude"]),
            "method": scan.get("method", resolved["integration"]["method"])}


def _refuse(file, field, problem):
    raise StudyError(file, field, problem)


@dataclass(frozen=True)
class FreeScenes:
    """The scenes of a free-body study: planned by :mod:`tumble.measure.scans` and :mod:`tumble.measure.planning`, run
    by :mod:`tumble.measure.running`, reduced by :mod:`tumble.measure.reduction`.

    A scene kind (this and :class:`ModelScenes`) is chosen once per study (:func:`_scene_kind`) and answers
    ``plan``, ``layout``, ``planner``, ``scene``, ``batch``, ``samples``, ``records`` and ``first_samples``, and for the
    study's cost estimate (:func:`study_cost`) ``always_steps`` and ``only_exponential``."""

    #: Whether every scene steps whatever its method: a free body's torque-free scenes may take the closed form.
    always_steps = False

    def only_exponential(self, resolved):
        """Whether every scene of the study spins about its body's intermediate axis (known from the fields for a
        study of one body; a scan of bodies may hold periodic scenes)."""
        scan = resolved["scan"]
        if any(key in scan for key in ("triangle", "k1", "moments", "body")):
            return False
        moments = list(resolved["body"]["moments"])
        if len(set(moments)) < 3:  # a symmetric body: neutral or periodic scenes
            return False
        middle = moments.index(sorted(moments)[1]) + 1
        return all(axis == middle for axis in scan.get("axis", [resolved["spin"]["axis"]]))

    def plan(self, resolved, file):
        """:func:`plan` of a free-body study."""
        scan = resolved["scan"]
        figures = resolved["outputs"]["figures"]
        moments, body_coords = _bodies(resolved)
        values = _values(resolved)
        torque = resolved["torque"] if resolved["torque"]["profile"] != "none" else None
        integ = resolved["integration"]
        options = SceneOptions.of(resolved, torque=torque,
                                  curves=tuple(sorted({_CURVES[f] for f in figures if f in _CURVES})))
        bodies = np.atleast_2d(moments)
        axes = values["axis"] if isinstance(values["axis"], list) else [values["axis"]]
        kinds = set(np.atleast_1d(theory.linear(bodies[:, None, :], np.asarray(axes)[None, :], 1.0)[0]).ravel()
                    .tolist())
        if torque is not None and kinds != {"periodic"}:
            _refuse(file, "spin.axis", f"a torque scene is compared with linear theory about a stable (largest or "
                                       f"smallest) axis only; axis {axes[0]} of this body is "
                                       f"{', '.join(sorted(kinds - {'periodic'}))}")
        for i, name in enumerate(figures):
            field = f"outputs.figures[{i}]"
            if name == "stability_map" and not ("triangle" in scan and isinstance(values["axis"], list)):
                _refuse(file, field, "stability_map needs scan.triangle (the inertia triangle) and scan.axis (e.g. "
                                     "[1, 2, 3])")
            if name == "flip_law" and not (isinstance(values["amplitude"], list) and len(values["amplitude"]) >= 2
                                           and integ["flips"] >= 1 and "exponential" in kinds):
                _refuse(file, field, "flip_law needs scan.amplitude with at least 2 values, integration.flips >= 1 "
                                     "and a spin about the intermediate axis")
            if name == "norm_growth" and "exponential" not in kinds:
                _refuse(file, field, "norm_growth needs a spin about the intermediate axis (no scene grows "
                                     "exponentially)")
            if name in ("invariant_drift", "work_precision") and torque is not None:
                _refuse(file, field, f"{name} measures torque-free invariants; set torque.profile = 'none'")
        scanned = [key for key in ("moments", "triangle", "body", "axis", "rate", "amplitude", "method") if key in scan]
        return StudyPlan(moments, body_coords, values, options, scanned, resolved["perturbation"]["samples"],
                         resolved["perturbation"]["seed"], self)

    def layout(self, p):
        """:func:`tumble.measure.scans.scan_layout` of a :class:`StudyPlan`."""
        values = p.values
        return scans.scan_layout(p.moments, values["axis"], values["spin"], values["amplitude"], values["method"])

    def planner(self, job):
        """A :class:`tumble.measure.scans.ScenePlanner` of the job's scenes (its options checked once)."""
        return scans.ScenePlanner(job.layout, samples=job.samples, seed=job.seed, **job.options)

    def scene(self, job, index, moments, params, planner=None):
        """The :class:`tumble.measure.planning.Scene` of scene ``index``; a planned step that cannot resolve the
        study's sine or pulse (the planner's :class:`tumble.measure.planning.TorqueStepError`) is the study's fault
        (issue 17, cause 8), named at ``torque.<period|duration>`` with the study's name of the step."""
        planner = planner or self.planner(job)
        try:
            return planner(index)
        except planning.TorqueStepError as err:
            problem = registry.profile_step_problem(err.profile, err.tau, err.dt, "integration.dt")
            raise StudyError(job.file, f"torque.{err.key}", f"{problem} (the step planned for scene {index})") from None

    def batch(self, job, indices, *, progress=False):
        """The records of whole scenes (:func:`tumble.measure.scans.scene_batch`: closed-form ones together)."""
        planner = self.planner(job)
        return scans.scene_batch([_scene_plan(job, i, planner) for i in indices], progress=progress)

    def samples(self, scene, start, stop, *, progress=False):
        """Samples ``[start, stop)`` of a scene (:func:`tumble.measure.running.scene_samples`)."""
        return running.scene_samples(scene, start, stop, progress=progress)

    def records(self, scenes, parts):
        """:func:`tumble.measure.reduction.scene_records`."""
        return reduction.scene_records(scenes, parts)

    def first_samples(self, job):
        """Samples the first range of a split scene holds at least: the norm curve's (:data:`planning.SLICE`)."""
        return min(planning.SLICE, job.samples) if "norm" in job.options.curves else 0

    def cost(self, resolved, flips=None):
        """:func:`study_cost` of a stability study (:func:`_stability_cost`)."""
        return _stability_cost(resolved, self, flips)

    def result_shape(self, job):
        """What places the records in the result besides the scan's layout: nothing more."""
        return {}


@dataclass(frozen=True)
class ModelScenes:
    """The scenes of a model study (``[model]`` of kind ``kind``): planned, run and reduced by
    :mod:`tumble.measure.model_scenes`. The same methods as :class:`FreeScenes`."""

    kind: str

    #: A model always steps (rk4 for ``"auto"``): no closed form.
    always_steps = True

    def only_exponential(self, resolved):
        """False: the study's estimate does not tell a model's kinds from its fields (its linearisation does)."""
        return False

    def plan(self, resolved, file):
        """:func:`plan` of a model study: its values include the model's parameters (``rotor``, ``mgl``)."""
        scan, model = resolved["scan"], resolved["model"]
        moments, body_coords = _bodies(resolved)
        values = _values(resolved)
        for key in registry.model_kind(self.kind).parameters:
            values[key] = scan.get(key, model[key])
        for i, name in enumerate(resolved["outputs"]["figures"]):
            need = registry.FIGURE_MODELS.get(name)  # the model and the scan the figure needs
            if need and (need.kind != self.kind or (need.scan and need.scan not in scan)):
                _refuse(file, f"outputs.figures[{i}]", f"{name} needs model.kind = {need.kind!r}"
                                                       + (f" and {need.text}" if need.text else ""))
        scanned = [key for key in ("moments", "triangle", "body", "k1", "k3", "axis", "rate", "amplitude", "method",
                                   *values) if key in scan]
        return StudyPlan(moments, body_coords, values, ModelSceneOptions.of(resolved), list(dict.fromkeys(scanned)),
                         resolved["perturbation"]["samples"], resolved["perturbation"]["seed"], self)

    def layout(self, p):
        """:func:`tumble.measure.model_scenes.scan_layout` of a :class:`StudyPlan` (``spin`` swept with scan.rate)."""
        swept = [key for key in p.values if key in p.scanned or (key == "spin" and "rate" in p.scanned)]
        return model_scenes.scan_layout(p.moments, p.values, swept)

    def planner(self, job):
        """None: a model scene is planned on its own (:meth:`scene`)."""

    def scene(self, job, index, moments, params, planner=None):
        """:func:`tumble.measure.model_scenes.scene_plan` of one scene (``params``: its values)."""
        parameters = {key: params[key] for key in registry.model_kind(self.kind).parameters}
        model = model_scenes.model_of(self.kind, moments, params["axis"], parameters)
        return model_scenes.scene_plan(model, params["axis"], params["spin"], params["amplitude"], job.samples,
                                       job.seed, params["method"], **job.options)

    def batch(self, job, indices, *, progress=False):
        """The records of whole scenes (:func:`tumble.measure.model_scenes.scene_batch`)."""
        return model_scenes.scene_batch([_scene_plan(job, i) for i in indices])

    def samples(self, scene, start, stop, *, progress=False):
        """Samples ``[start, stop)`` of a scene (:func:`tumble.measure.model_scenes.scene_samples`)."""
        return model_scenes.scene_samples(scene, start, stop)

    def records(self, scenes, parts):
        """:func:`tumble.measure.model_scenes.scene_records`."""
        return model_scenes.scene_records(scenes, parts)

    def first_samples(self, job):
        """0: a model scene keeps no norm curve."""
        return 0

    cost = FreeScenes.cost
    result_shape = FreeScenes.result_shape


@dataclass(frozen=True)
class ChaosScenes:
    """The scenes of a chaos study (``chaos.indicators``; model ``kind``, initial states by ``start``): maps of chaos
    indicators, planned, run and reduced by :mod:`tumble.measure.chaos_scenes`. The same methods as
    :class:`FreeScenes`: a scene is one combination of the scanned model parameters and methods, its samples the
    points of the map of initial states (:func:`tumble.measure.chaos_scenes.map_grid`)."""

    kind: str
    start: str

    #: Every orbit steps (with its tangent vectors).
    always_steps = True

    def only_exponential(self, resolved):
        """False: a chaos map has no linear-theory kind."""
        return False

    def _values(self, resolved):
        """The map's coordinates, the model's parameters and the method: one value each or the scan's list."""
        scan, model, chaos = resolved["scan"], resolved.get("model"), resolved["chaos"]
        keys = next(s for s in registry.CHAOS_STARTS if s.name == self.start).keys
        values = {key: scan.get(key, resolved["spin"]["rate"] if key == "rate" else chaos[key]) for key in keys}
        if not keys:  # chaos.start = "state": the components scan.state names
            values = dict(scan["state"])
        model = model or {}
        params = {key: scan.get(key, model[key]) for key in registry.model_kind(self.kind).parameters}
        extras = {key: model[key] for key in models.CLASSES[self.kind].extras if key in model}
        return values, params, extras

    def plan(self, resolved, file):
        """:func:`plan` of a chaos study: the model's parameters (and the method) are the scan's dimensions, the
        map's coordinates its samples."""
        scan = resolved["scan"]
        points, params, extras = self._values(resolved)
        values = {"method": scan.get("method", resolved["integration"]["method"]), **params}
        options = {**resolved["chaos"], "dt": resolved["integration"]["dt"],
                   "horizon": resolved["integration"]["horizon"], "device": resolved["integration"]["device"],
                   "rtol": resolved["integration"]["rtol"], "atol": resolved["integration"]["atol"],
                   "max_steps": resolved["integration"]["max_steps"],
                   "section": resolved.get("section"), "extras": extras, "points_of_map": points}
        scanned = [key for key in values if key in scan]
        n = len(next(iter(chaos_scenes.map_grid(self.start, points)[2].values())))
        moments = config.resolve_body(resolved).moments
        return StudyPlan(moments, None, values, options, scanned, n, resolved["perturbation"]["seed"], self)

    def layout(self, p):
        """:func:`tumble.measure.model_scenes.scan_layout` of the scanned parameters and methods."""
        return model_scenes.scan_layout(p.moments, p.values, p.scanned)

    def planner(self, job):
        """None: a chaos scene is planned on its own (:meth:`scene`)."""

    def scene(self, job, index, moments, params, planner=None):
        """:func:`tumble.measure.chaos_scenes.scene_plan` of one scene (``params``: its method and parameters)."""
        options = job.options
        parameters = {key: params[key] for key in registry.model_kind(self.kind).parameters}
        _, _, points = chaos_scenes.map_grid(self.start, options["points_of_map"])
        coords = {key: params[key] for key in job.plan.scanned}
        return chaos_scenes.scene_plan(self.kind, moments, {**parameters, **options["extras"]}, self.start, points,
                                       options, params["method"], coords)

    def batch(self, job, indices, *, progress=False):
        """The records of whole scenes: each scene's points in one run."""
        scenes = [_scene_plan(job, i) for i in indices]
        return chaos_scenes.scene_records(scenes, [[self.samples(s, 0, len(s.states))] for s in scenes])

    def samples(self, scene, start, stop, *, progress=False):
        """Points ``[start, stop)`` of a scene's map (:func:`tumble.measure.chaos_scenes.scene_samples`)."""
        return chaos_scenes.scene_samples(scene, start, stop)

    def records(self, scenes, parts):
        """:func:`tumble.measure.chaos_scenes.scene_records`."""
        return chaos_scenes.scene_records(scenes, parts)

    def first_samples(self, job):
        """0: a map's ranges may start anywhere."""
        return 0

    def cost(self, resolved, flips=None):
        """:class:`tumble.engine.cost.Cost` of the maps: every point of every scene with its tangent vectors over the
        horizon, the finite-time curves kept."""
        points, params, _ = self._values(resolved)
        chaos, integ, scan = resolved["chaos"], resolved["integration"], resolved["scan"]
        n_points = len(next(iter(chaos_scenes.map_grid(self.start, points)[2].values())))
        scenes = math.prod(len(scan[key]) for key in ("method", *params) if key in scan)
        size = len(registry.model_kind(self.kind).state)
        vectors = 1 * ("megno" in chaos["indicators"]) + (chaos["exponents"] or size) * (
            "lyapunov" in chaos["indicators"]) + chaos["gali_k"] * ("gali" in chaos["indicators"])
        section = resolved.get("section")
        if integ["dt"] > 0:
            steps = integ["horizon"] / integ["dt"] * (1 + vectors)
        else:  # error-controlled, its steps unknown before it runs: an eighth-order method's at the fastest spin
            rate = max(abs(r) for r in scan.get("rate", [resolved["spin"]["rate"]]))
            steps = integ["horizon"] * rate * planning.STEPS_PER_RADIAN[8] * (1 + vectors + (section is not None))
        stored = chaos["points"] * size + (section["crossings"] * (size + 3) if section is not None else 0)
        estimate = cost.run_cost(n_points * scenes, steps, stored=stored)
        return estimate._replace(peak_bytes=estimate.peak_bytes + cost.RUN_FOOTPRINT)

    def result_shape(self, job):
        """The map's coordinates (``grid``: name -> values), which shape each record's points."""
        dims, coordinates, _ = chaos_scenes.map_grid(self.start, job.options["points_of_map"])
        return {"grid": {name: coordinates[name].tolist() for name in dims}}


#: The study field a refusal names, by the bound it broke (:class:`tumble.engine.cost.TooLarge`).
_BOUND_FIELDS = {"scenes": "scan", "steps": "integration", "memory": "perturbation.samples",
                 "time": "perturbation.samples", "size": "perturbation.samples"}


def study_cost(resolved, *, flips=None):
    """:class:`tumble.engine.cost.Cost` of a resolved study, from its fields alone: its scene kind's estimate
    (:func:`_stability_cost` for the stability scenes)."""
    return _scene_kind(resolved).cost(resolved, flips)


def _stability_cost(resolved, scenes_kind, flips=None):
    """:class:`tumble.engine.cost.Cost` of a resolved study, from its fields alone (no scene is planned, so
    this takes microseconds whatever the study's size; ``flips`` replaces ``integration.flips``). Its memory is
    the model of :func:`tumble.measure.planning.scene_estimate` (the worst kind the study may hold) plus the run's
    fixed :data:`tumble.engine.cost.RUN_FOOTPRINT`: the peak resident memory above an idle ``import tumble``."""
    scan, integ = resolved["scan"], resolved["integration"]
    if "triangle" in scan:
        bodies = scan["triangle"] ** 2
    elif "k1" in scan:
        bodies = len(scan["k1"]) * len(scan["k3"])
    else:
        bodies = len(scan.get("moments", scan.get("body", [None])))
    scenes = bodies * math.prod(len(scan[key]) for key in ("axis", "rate", "amplitude", "method") if key in scan)
    scenes *= math.prod(len(scan[key]) for key in config.MODEL_SCAN_KEYS if key in scan)
    methods = scan.get("method", [integ["method"]])
    stepping = [m for m in methods if m in STEPPING]
    if (resolved["torque"]["profile"] != "none" or scenes_kind.always_steps) and not stepping:
        stepping = [registry.AUTO_STEPPING]  # a torque or a model steps (rk4 for "auto")
    rate = abs(max(scan.get("rate", [resolved["spin"]["rate"]]), key=abs))
    # the planner's horizon: a few periods (or growth times and flips) of the scene, about PERIODS turns of the spin
    horizon = integ["horizon"] or planning.PERIODS * 2 * math.pi / rate
    steps = 0.0
    if stepping:
        per_radian = max(planning.STEPS_PER_RADIAN[registry.method(m).order] for m in stepping)
        steps = horizon / integ["dt"] if integ["dt"] else horizon * rate * per_radian
    times = planning.PROBES + 1
    if integ["horizon"]:  # a periodic scene stores SAVES_PER_PERIOD states per period (at most MAX_SAVES)
        times = max(times, min(integ["horizon"] * rate / (2 * math.pi) * planning.SAVES_PER_PERIOD,
                               planning.MAX_SAVES) + 1)
    arrays = resolved["outputs"]["arrays"]
    kept = 2 * (8 * len(arrays) + 8 * bool(arrays))  # the records and the assembled dataset, with the sample index
    estimate = planning.scene_estimate(bool(stepping), scenes_kind.only_exponential(resolved),
                                       resolved["perturbation"]["samples"], times, steps=steps,
                                       flips=integ["flips"] if flips is None else flips, scenes=scenes,
                                       kept_per_sample=kept)
    return estimate._replace(peak_bytes=estimate.peak_bytes + cost.RUN_FOOTPRINT)


def check_cost(resolved, file="<mapping>"):
    """:func:`study_cost`, refused with a :class:`~tumble.pipeline.config.StudyError` past the bounds of
    :func:`tumble.engine.cost.check` (the message holds the estimate; the field named is the one that set the
    size: ``integration.flips`` when the flip times alone overflow the memory)."""
    estimate = study_cost(resolved)
    try:
        return cost.check(estimate, resolved["integration"]["device"])
    except cost.TooLarge as err:
        field = _BOUND_FIELDS[err.bound]
        share = cost.MEMORY_SHARE * cost.physical_memory()
        if resolved.get("chaos") is not None:  # a map: its points (scan) or its section's crossings set the size
            section = resolved.get("section")
            field = "scan" if err.bound != "steps" else field
            if err.bound == "memory" and section is not None and study_cost(
                    {**resolved, "section": {**section, "crossings": 1}}).peak_bytes <= share:
                field = "section.crossings"
        elif err.bound == "memory" and study_cost(resolved, flips=0).peak_bytes <= share:
            field = "integration.flips"
        raise StudyError(file, field, str(err)) from None


def _first(value):
    return value[0] if isinstance(value, list) else value


def scene_job(resolved, file="<mapping>"):
    """The scenes a resolved study runs, as plain data that pickles to a dask worker.

    Returns
    -------
    Job

    Raises
    ------
    tumble.pipeline.config.StudyError
        As :func:`plan`.
    """
    check_cost(resolved, file)
    p = plan(resolved, file)
    resolve_device(resolved["integration"]["device"])  # a device that cannot run: refused before anything runs
    return Job(p.scenes.layout(p), bool(p.scanned), p.samples, p.seed, p.options, p.body_coords, p, p.scenes,
               str(file), tuple(resolved["outputs"]["arrays"]))


class Task(NamedTuple):
    """One chunk of a study — the unit of checkpointing and of dask tasks: the whole scenes ``scenes``, or
    samples ``[start, stop)`` of the one scene in ``scenes``."""

    scenes: tuple
    start: int | None = None
    stop: int | None = None

    @property
    def name(self):
        """File name of the chunk's checkpoint."""
        if self.start is None:
            return checkpoint.scenes_name(self.scenes)
        return checkpoint.samples_name(self.scenes[0], self.start, self.stop)


def _scene_plan(job, index, planner=None):
    """The planned scene ``index`` of a :func:`scene_job` (through ``planner``, the job's scenes' planner, when several
    scenes are planned); a value this scene cannot take is the study's fault, named as such (exit 2)."""
    moments, params = scans.scan_scene_parameters(job.layout, index)
    try:
        return job.scenes.scene(job, index, moments, params, planner)
    except (DeviceError, StudyError):  # the device's own one line (device 'cuda': ...), as every call gives it
        raise
    except ValueError as err:
        label = " ".join(f"{key}={value}" for key, value in params.items())
        raise StudyError(job.file, f"scene {index} ({label})", str(err)) from None


def _kept(job, record):
    """A scene record with only the per-sample arrays the result keeps (``outputs.arrays``; the ``sample`` index
    only with one of them): what a chunk stores and the result is assembled from. The others were a chunk's
    bulk (a 2048-sample stability map's checkpoint was 140 times its result) and the result drops them anyway."""
    dropped = [name for name in PER_SAMPLE if name not in job.arrays]
    if not any(name in PER_SAMPLE for name in job.arrays):
        dropped.append("sample")
    return {name: value for name, value in record.items() if name not in dropped}


def _scene_record(job, scene, parts):
    """The record (:func:`tumble.measure.reduction.scene_records`, :func:`_kept`) of a scene from its sample ranges."""
    return _kept(job, job.scenes.records([scene], [parts])[0])


def compute_scenes(job, indices, *, progress=False):
    """``{index: record}`` of the whole scenes ``indices`` of a :func:`scene_job`: a scan's scenes, or the study's one
    measurement; closed-form scenes run together (:func:`tumble.measure.scans.scene_batch`)."""
    if not indices:  # an empty task (a worker's warm-up) needs no job
        return {}
    records = job.scenes.batch(job, indices, progress=progress)
    return {i: _kept(job, record) for i, record in zip(indices, records)}


def compute_samples(job, index, start, stop, *, progress=False):
    """Samples ``[start, stop)`` of scene ``index`` (:func:`tumble.measure.running.scene_samples`)."""
    return job.scenes.samples(_scene_plan(job, index), start, stop, progress=progress)


def compute_task(job, task, digest="", *, threads=None, progress=False):
    """Run one :class:`Task`; return its chunk file's bytes (:mod:`tumble.pipeline.checkpoint`), stamped with ``digest``.

    This is what a dask worker runs: the result it sends back is the compact archive the client writes as it
    is and reads without unpickling anything. ``threads`` sets numba's thread count for the calling thread
    (1 inside dask workers, so that workers do not oversubscribe the cores); the results do not depend on it.
    """
    return _pack(task, _compute(job, task, threads=threads, progress=progress), digest)


def _compute(job, task, *, threads=None, progress=False):
    """What one :class:`Task` finishes, as a :class:`tumble.pipeline.checkpoint.Finished` (no bytes: a run in this
    process packs a chunk only to write it to a checkpoint)."""
    if threads is not None:
        import numba

        threads = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
        if numba.get_num_threads() != threads:
            numba.set_num_threads(threads)
    if task.start is None:
        return checkpoint.Finished(compute_scenes(job, task.scenes, progress=progress), {})
    index = task.scenes[0]
    part = compute_samples(job, index, task.start, task.stop, progress=progress)
    return checkpoint.Finished({}, {index: {(task.start, task.stop): part}})


class _Unwritten:
    """A run's finished chunks not yet in its checkpoint ``store`` (None: nothing is written): those that finish in
    the first :func:`checkpoint_after` seconds are held, and written with the first that finishes later."""

    def __init__(self, store):
        self.store, self.held = store, []
        self.due = time.monotonic() + checkpoint_after()

    def add(self, task, finished, data=None):
        """``task`` finished (``data``: its chunk file's bytes, where a dask worker packed them)."""
        if self.store is not None:
            self.held.append((task, finished, data))
            self.save(now=False)

    def save(self, now=True):
        if not (now or time.monotonic() >= self.due):
            return
        while self.held:
            task, finished, data = self.held[0]
            self.store.write(task.name, data if data is not None else _pack(task, finished, self.store.digest))
            del self.held[0]

    def save_before_stopping(self):
        """Write what is held as the run stops on an error, which says more than a failed write would (a full disk,
        a lost scheduler)."""
        with contextlib.suppress(Exception):
            self.save()


def _pack(task, finished, digest):
    """The chunk file's bytes of what ``task`` finished."""
    if task.start is None:
        return checkpoint.pack_scenes(finished.scenes, digest)
    index = task.scenes[0]
    return checkpoint.pack_samples(index, task.stop, finished.parts[index][(task.start, task.stop)], digest)


#: Seconds the scenes of a run may take before their finished chunks are written to the checkpoint: the chunks
#: that finish sooner are held and written with the first chunk that finishes later (then each as it finishes), so
#: a run that ends sooner writes none (a chunk file costs 1-2 ms to pack and write durably: 7 % of a one-second
#: scan of 32 chunks). A run that is interrupted (Ctrl-C, SIGTERM, an error) writes what it holds first; one killed
#: outright loses it: less than this many seconds of work. ``TUMBLE_CHECKPOINT_AFTER`` (seconds, 0: every chunk as
#: it finishes) overrides it.
CHECKPOINT_AFTER = 2.0


def checkpoint_after():
    """:data:`CHECKPOINT_AFTER`, or ``TUMBLE_CHECKPOINT_AFTER`` where that holds a number of seconds >= 0."""
    text = os.environ.get("TUMBLE_CHECKPOINT_AFTER")
    if text is None:
        return CHECKPOINT_AFTER
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:  # NaN too
        warnings.warn(f"TUMBLE_CHECKPOINT_AFTER={text!r} is not a number of seconds >= 0; checkpointing after "
                      f"{CHECKPOINT_AFTER:g} s", RuntimeWarning, stacklevel=2)
        return CHECKPOINT_AFTER
    return value


def default_chunk_scenes(scenes):
    """Scenes per chunk when not given: about 32 chunks per study (enough to balance two to eight workers,
    few enough that writing the chunk files costs little), at least one scene."""
    return max(1, math.ceil(scenes / 32))


#: Samples per chunk of one scene when not given (``--chunk-samples``): a scene of more samples is cut into
#: ranges of this many, run and checkpointed apart (1e6 samples: 8 ranges). A multiple of
#: :data:`tumble.engine.sampling.CHUNK`, like every range boundary.
DEFAULT_CHUNK_SAMPLES = 32 * CHUNK


def _count(value, name, default):
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def chunk_samples_size(chunk_samples=None):
    """Samples per range of a split scene: ``chunk_samples`` checked (a positive multiple of
    :data:`tumble.engine.sampling.CHUNK`), or :data:`DEFAULT_CHUNK_SAMPLES`."""
    size = _count(chunk_samples, "chunk_samples", DEFAULT_CHUNK_SAMPLES)
    if size % CHUNK:
        raise ValueError(f"chunk_samples must be a multiple of {CHUNK} (the sampler's block of samples), "
                         f"got {chunk_samples!r}")
    return size


def sample_ranges(samples, size, *, first=0, done=()):
    """The ``[start, stop)`` ranges that cover the samples of one scene not covered by ``done``.

    Boundaries are the multiples of ``size`` (a multiple of :data:`tumble.engine.sampling.CHUNK`), so every sample ``i``
    is drawn and run exactly as in the whole scene; the range holding sample 0 reaches at least ``first``. The
    ``done`` ranges (from a checkpoint, perhaps cut with another size) are kept as they are.
    """
    cuts = {0, samples, *(k for k in range(size, samples, size) if k >= first)}
    for start, stop in done:
        cuts.update((start, stop))
    cuts = sorted(cuts)
    return [(lo, hi) for lo, hi in zip(cuts[:-1], cuts[1:])
            if not any(start <= lo and hi <= stop for start, stop in done)]


def _usable_parts(parts, samples, first):
    """The finished ranges of one scene a run can build on: inside the scene, not overlapping, aligned to
    :data:`tumble.engine.sampling.CHUNK`, none but the first starting before ``first`` (the norm curve's samples)."""
    kept, end = {}, 0
    for (start, stop), part in sorted(parts.items()):
        if start >= end and stop <= samples and start % CHUNK == 0 and (start == 0 or start >= first):
            kept[(start, stop)] = part
            end = stop
    return kept


def plan_tasks(job, done, *, chunk_scenes=None, chunk_samples=None):
    """The :class:`Task` list of what ``done`` (a :class:`tumble.pipeline.checkpoint.Finished`) lacks.

    Scenes of at most ``chunk_samples`` samples run whole, ``chunk_scenes`` to a task; a larger scene (or one
    with finished ranges) runs as sample ranges (:func:`sample_ranges`), one to a task. Unusable finished ranges
    are dropped from ``done``.
    """
    n, samples = job.layout["scenes"], job.samples
    per_task = _count(chunk_scenes, "chunk_scenes", default_chunk_scenes(n))
    size = chunk_samples_size(chunk_samples)
    first = job.scenes.first_samples(job)
    whole, ranges = [], []
    for i in range(n):
        parts = done.parts.pop(i, {})
        if i in done.scenes:
            continue
        if samples <= size and not parts:
            whole.append(i)
            continue
        done.parts[i] = _usable_parts(parts, samples, first)
        ranges += [Task((i,), lo, hi) for lo, hi in sample_ranges(samples, size, first=first, done=done.parts[i])]
    return [Task(tuple(whole[k:k + per_task])) for k in range(0, len(whole), per_task)] + ranges


def run_scenes(job, *, store=None, client=None, chunk_scenes=None, chunk_samples=None, progress=None, log=None):
    """Run every scene of a :func:`scene_job` not already in the checkpoint; return all of them, in order.

    Parameters
    ----------
    job : dict
        From :func:`scene_job`.
    store : tumble.pipeline.checkpoint.Checkpoint, optional
        Finished chunks are read from it and every newly finished chunk is written to it (atomically); those that
        finish in the first :func:`checkpoint_after` seconds are held, and written with the first that finishes
        later (or as the run stops on an error or Ctrl-C).
    client : distributed.Client, optional
        Run the chunks on this dask cluster (:mod:`tumble.pipeline.distributed`); default: in this process.
    chunk_scenes : int, optional
        Scenes per chunk (default :func:`default_chunk_scenes`). The results do not depend on it.
    chunk_samples : int, optional
        Samples per chunk of a scene with more samples than this (a multiple of 4096; default
        :data:`DEFAULT_CHUNK_SAMPLES`). The results do not depend on it.
    progress : bool, optional
        Progress bar over the scenes (default: on a terminal only).
    log : callable, optional
        Called with one line of text about a resume.

    Returns
    -------
    list of dict
        The scene records (:func:`tumble.measure.reduction.scene_records`).
    """
    n = job.layout["scenes"]
    digest = store.digest if store is not None else ""
    done = store.load() if store is not None else checkpoint.Finished({}, {})
    tasks = plan_tasks(job, done, chunk_scenes=chunk_scenes, chunk_samples=chunk_samples)
    if log and store is not None and store.stale:
        log(f"ignored and removed {store.stale} checkpoint file(s) of another study or tumble version")
    ranges_done = sum(len(parts) for parts in done.parts.values())
    if log and (done.scenes or ranges_done):
        started = sum(1 for parts in done.parts.values() if parts)
        ranges = f" and {ranges_done} sample range(s) of {started} more" if ranges_done else ""
        log(f"resuming: {len(done.scenes)} of {n} scenes{ranges} already finished in {store.folder}")
    scenes, left = done.scenes, {i: 0 for i in done.parts}  # sample ranges still to run, by split scene
    for task in tasks:
        if task.start is not None:
            left[task.scenes[0]] += 1

    def reduce_finished_scenes():
        for i in [i for i, count in left.items() if count == 0]:
            scenes[i] = _scene_record(job, _scene_plan(job, i), list(done.parts.pop(i).values()))
            del left[i]

    unwritten = _Unwritten(store)

    def finish(task, finished, data=None):
        unwritten.add(task, finished, data)
        scenes.update(finished.scenes)
        for i, parts in finished.parts.items():
            done.parts[i].update(parts)
            left[i] -= 1
        reduce_finished_scenes()

    reduce_finished_scenes()  # resumed with every range of a scene finished
    try:
        if client is not None:
            from . import distributed

            try:
                for task, data in distributed.run_chunks(client, compute_task, job, tasks, digest):
                    finish(task, checkpoint.unpack(data, digest, n), data)
            except distributed.SchedulerLost as err:
                unwritten.save_before_stopping()
                # one line (issue 44): what was lost and where (err), what is kept, how to resume
                kept = (f"{sum(1 for _ in store.folder.glob('*' + checkpoint.CHUNK_SUFFIX))} finished chunk(s) are "
                        f"kept in {store.folder}: start a scheduler again (or run without one) and rerun to resume "
                        f"from them" if store is not None and store.folder.is_dir()
                        else "no finished chunk is kept: rerun to start again")
                raise distributed.SchedulerLost(f"{err}; {kept}") from None
        else:
            show = sys.stderr.isatty() if progress is None else progress
            with tqdm(total=n, initial=len(scenes), unit="scenes", disable=not (show and n > 1), desc="scan") as bar:
                for task in tasks:
                    before = len(scenes)
                    finish(task, _compute(job, task, progress=progress if n == 1 else False))
                    bar.update(len(scenes) - before)
    except BaseException:  # Ctrl-C, a failed scene: what finished is kept for the rerun
        unwritten.save_before_stopping()
        raise
    return [scenes[i] for i in range(n)]


#: Figures that draw a trace besides the scenes' records (:func:`_extras`).
TRACE_FIGURES = frozenset({"invariant_drift", "work_precision", "flat_spin", *config.ATTITUDE_FIGURES})


def needs_traces(resolved):
    """Whether the study's figures draw a trace besides its scenes' records: its result is then built where the
    scenes ran (the traces are xarray Datasets), not from the records alone (:func:`write_records`)."""
    return not TRACE_FIGURES.isdisjoint(resolved["outputs"]["figures"])


def _extras(resolved, job, progress):
    """The datasets some figures draw besides the scenes' (invariant drift, work-precision, flat spin, attitude),
    computed from the study's first scene; none when its figures need none."""
    if not needs_traces(resolved):
        return []
    p = job.plan
    values, options = p.values, p.options
    figures = resolved["outputs"]["figures"]
    first_body = np.atleast_2d(p.moments)[0]
    scene = (first_body, _first(values["axis"]), _first(values["spin"]), _first(values["amplitude"]))
    extras = []
    if "invariant_drift" in figures:
        methods = [m for m in np.atleast_1d(values["method"]) if m in STEPPING] or list(STEPPING)
        extras.append(traces.invariant_drift(*scene, methods, samples=min(_DRIFT_SAMPLES, p.samples), seed=p.seed,
                                             horizon=options["horizon"]))
    if "work_precision" in figures:
        from ..measure import precision  # scipy's solve_ivp runs: imported only when asked for

        extras.append(precision.work_precision(*scene, samples=p.samples, t_end=options["horizon"] or 20.0,
                                               seed=p.seed, progress=progress))
    if "flat_spin" in figures:  # a damper's turn-over to the flat spin, from the first scene
        kind = registry.FIGURE_MODELS["flat_spin"].kind  # the study's own: ModelScenes.plan refuses another
        parameters = {key: _first(values[key]) for key in registry.model_kind(kind).parameters}
        model = model_scenes.model_of(kind, first_body, _first(values["axis"]), parameters)
        method = _first(values["method"])
        extras.append(model_scenes.flat_spin_trace(model, *scene[1:], seed=p.seed, method=registry.ACCURATE_STEPPING
                                                   if method == registry.AUTO else method))
    if any(name in config.ATTITUDE_FIGURES for name in figures):
        body = resolved["body"] if "body" not in resolved["scan"] else {}
        method = _first(values["method"])
        extras.append(traces.attitude_trace(*scene, method if method in STEPPING else "auto", seed=p.seed,
                                            torque=options["torque"], horizon=options["horizon"],
                                            shape=body.get("shape", ""), shape_parameters=body.get("dimensions")))
    return extras


def _compile_the_attitude_with_the_scenes(resolved, job):
    """On a cold numba cache, a study that draws its first scene's attitude by the closed form (the attitude figures
    of a torque-free scene, ``method = "auto"`` or ``"exact"``) compiles the attitude's kernels side by side with
    its scenes' (:func:`tumble.physics.exact.compile_kernels_side_by_side`) instead of alone after them: the first
    ``tumble run dzhanibekov_flip`` after an install 12.9 -> 11.2 s on 2 cores. A wrong guess costs a worker's
    compilation, never a result."""
    p = job.plan
    method = _first(p.values["method"])
    if (not any(name in config.ATTITUDE_FIGURES for name in resolved["outputs"]["figures"])  # never a model's
            or method not in ("auto", "exact")):
        return
    _, params, fn, _ = torque_spec(p.options["torque"])
    if params is None and fn is None:
        body, axis, spin = np.atleast_2d(p.moments)[0], _first(p.values["axis"]), _first(p.values["spin"])
        exact.compile_kernels_side_by_side(theory.linear(body, axis, spin)[0], attitude=True)


def _result_shape(job):
    """What places a study's records in its dataset (:func:`tumble.pipeline.results.result_dataset`'s keywords),
    as plain data."""
    return {"layout": job.layout, "scanned": job.scanned, "body_coords": job.body_coords,
            **job.scenes.result_shape(job)}


def _result_dataset(records, job, resolved, extras=()):
    return results.result_dataset(records, **_result_shape(job), resolved=resolved, extras=extras)


def open_checkpoint(resolved, job, directory, stem):
    """The :class:`~tumble.pipeline.checkpoint.Checkpoint` of a study writing ``<directory>/<stem>.nc``."""
    return checkpoint.Checkpoint(directory, stem, checkpoint.study_hash(resolved), job.layout["scenes"])


def _write_staged(directory, stem, stage, figure_process=None):
    """Write a study's files through a staging folder: ``stage(staging)`` writes ``<stem>.nc`` and the figures into
    it and returns ``(what to return, figure paths)``; then they are renamed into ``directory``. Returns ``(that,
    paths written)``.

    The result set appears whole or not at all: the file and the figures are written into a hidden staging folder
    beside the results, then renamed into place, figures first and the .nc last (renames within a folder do not
    fail half-way); on any error or Ctrl-C before that, the staging folder goes and earlier results are left as
    they were. A staging folder left by kill -9 is removed by the next run.

    Raises
    ------
    tumble.pipeline.checkpoint.OutputError
        A file cannot be written (unwritable folder, disk full): an earlier ``<stem>.nc`` is left as it was.
    """
    directory = Path(directory)
    path = directory / f"{stem}.nc"
    staging = checkpoint.staging_folder(directory, stem)
    try:
        shutil.rmtree(staging, ignore_errors=True)
        staging.mkdir(parents=True)
        value, staged = stage(staging)
        figures = [directory / figure.name for figure in staged]
        for figure in staged:
            os.replace(figure, directory / figure.name)
        os.replace(staging / path.name, path)
    except checkpoint.OutputError:
        raise
    except OSError as err:
        what = _disk.disk_problem(err, directory) or err.strerror or err
        raise checkpoint.OutputError(err.errno, f"cannot write the results to {directory}: {what}") from err
    finally:
        if figure_process is not None:
            figure_process.close()  # before the staging folder goes: it may still be writing into it
        shutil.rmtree(staging, ignore_errors=True)
    return value, [path, *figures]


def write_outputs(ds, resolved, directory, stem, *, action=None, figure_process=None):
    """Write ``<directory>/<stem>.nc`` and the study's figures; return ``(stored dataset, paths)``.

    ``figure_process`` (a :class:`~tumble.pipeline.figure_process.FigureProcess`, as ``tumble run`` starts one) draws
    the figures while the netCDF file is written; without it, or if it cannot, they are drawn here.

    Raises
    ------
    tumble.pipeline.checkpoint.OutputError
        A file cannot be written (unwritable folder, disk full): an earlier ``<stem>.nc`` is left as it was.
    """
    def start_drawing(stored, names, staging, stem, formats):
        figure_process.submit(stored, names, staging, stem, formats)
        return figure_process.result

    def stage(staging):
        return results.stage_result(ds, resolved, staging, stem, action=action,
                                    start_drawing=start_drawing if figure_process is not None else None)

    return _write_staged(directory, stem, stage, figure_process)


def write_records(records, job, resolved, directory, stem, *, action=None, figure_process):
    # size: the records, the job that places them, and write_outputs' arguments
    """What :func:`write_outputs` writes, from the scene records of a study without extra traces (:func:`_extras`):
    ``figure_process`` builds the dataset, writes the files and returns the summary
    (:meth:`~tumble.pipeline.figure_process.FigureProcess.submit_result`), so that this process never imports
    xarray; if it cannot, the dataset is built and written here. Returns ``(summary text, paths)``."""
    def stage(staging):
        figure_process.submit_result(records, _result_shape(job), resolved, staging, stem, action)
        answer = figure_process.result()
        if answer is not None:
            return answer
        stored, figures = results.stage_result(_result_dataset(records, job, resolved), resolved, staging, stem,
                                               action=action)
        return results.summary_table(stored), figures

    return _write_staged(directory, stem, stage, figure_process)


class PreparedStudy(NamedTuple):
    """A study checked and planned, before anything runs (:func:`prepare_study`)."""

    resolved: dict  # the study merged over the defaults, every field checked
    file: str  # where it came from (for messages and provenance)
    stem: str  # file stem of its outputs
    directory: Path | None  # where it writes (None: nothing is written)
    job: Job  # the scenes and what each computes
    store: checkpoint.Checkpoint | None  # finished chunks of scenes (None when nothing is written)


def prepare_study(source, *, overrides=None, out=None, formats=None, default_directory=False):
    """Load, check and plan a study; nothing runs and nothing is written.

    ``out`` (else the study's ``outputs.directory``, else ``data/runs/<stem>/`` when ``default_directory``, as
    ``tumble run`` does, else nowhere) is where :func:`execute_study` writes; ``formats`` replaces
    ``outputs.format``. Raises :class:`~tumble.pipeline.config.StudyError` as :func:`run_study`.
    """
    resolved = config.load_study(source, overrides=overrides)
    if formats:
        resolved["outputs"]["format"] = list(dict.fromkeys(formats))
    file = "<mapping>" if isinstance(source, Mapping) else str(source)
    job = scene_job(resolved, file)
    stem = output_stem(source, resolved)
    directory = out if out is not None else resolved["outputs"]["directory"] or None
    if directory is None and default_directory:
        directory = Path("data", "runs", stem)
    directory = None if directory is None else Path(directory)
    store = open_checkpoint(resolved, job, directory, stem) if directory is not None else None
    return PreparedStudy(resolved, file, stem, directory, job, store)


class Outputs(NamedTuple):
    """What :func:`execute_study` gives back."""

    dataset: object  # the result (as stored, when written); None where the figure process built and wrote it
    paths: list  # the files written: <stem>.nc, then the figures
    summary: str | None  # results.summary_table's text, where the figure process built the result (else None)


def execute_study(prepared, *, progress=None, client=None, chunk_scenes=None, chunk_samples=None, log=None,
                  action=None, fresh=False, figure_process=None):
    # size: the prepared study and the run's options (progress, cluster, chunking, log, history, fresh, figures)
    """Run a prepared study's scenes (here, or on the dask ``client``), resuming from its checkpoint, and write
    its outputs; return :class:`Outputs`: the dataset (the stored one when written) and the paths written.
    ``log`` receives one line per resumed or finished chunk; ``action`` is the provenance's command; ``fresh``
    discards the checkpoint first instead of resuming from it.

    ``figure_process`` (``tumble run``'s :class:`~tumble.pipeline.figure_process.FigureProcess`) draws the figures
    (:func:`write_outputs`); for a study whose figures need no extra trace it also builds and writes the result
    from the scene records (:func:`write_records`), and :class:`Outputs` holds its summary instead of a dataset.

    A run that writes holds its folder's lock for the study's stem (:meth:`tumble.pipeline.checkpoint.Checkpoint.locked`)
    from before it reads the checkpoint until its files are in place: a second run of the same stem into the same
    folder is refused at once (:class:`tumble.pipeline.checkpoint.FolderBusy`) instead of sharing its chunks and
    staging folder.
    """
    job, resolved, store = prepared.job, prepared.resolved, prepared.store
    with store.locked() if store is not None else contextlib.nullcontext():
        if fresh and store is not None:
            store.remove()
        _compile_the_attitude_with_the_scenes(resolved, job)
        records = run_scenes(job, store=store, client=client, chunk_scenes=chunk_scenes, chunk_samples=chunk_samples,
                             progress=progress, log=log)
        extras = _extras(resolved, job, progress)
        if prepared.directory is None:
            return Outputs(_result_dataset(records, job, resolved, extras), [], None)
        if figure_process is not None and not needs_traces(resolved):
            summary, paths = write_records(records, job, resolved, prepared.directory, prepared.stem, action=action,
                                           figure_process=figure_process)
            outputs = Outputs(None, paths, summary)
        else:
            ds = _result_dataset(records, job, resolved, extras)
            outputs = Outputs(*write_outputs(ds, resolved, prepared.directory, prepared.stem, action=action,
                                             figure_process=figure_process), None)
        store.remove()
        store.clean_partial_results()
    return outputs


def run_study(source, *, overrides=None, out=None, progress=None, scheduler=None, chunk_scenes=None,
              chunk_samples=None, device=None):
    """Run a study and return its result dataset.

    Parameters
    ----------
    source : str, os.PathLike or Mapping
        A study file, a bundled study's name (``tumble studies``) or a mapping of the same shape
        (see ``studies/defaults.toml``).
    overrides : Mapping[str, object], optional
        Values by dotted field path, e.g. ``{"perturbation.samples": 64}``.
    out : str or os.PathLike, optional
        Folder to write ``<stem>.nc`` and the figures to. Without it, files are written only when the study
        sets ``outputs.directory``; otherwise nothing is written (the command line's ``tumble run`` writes
        to ``data/runs/<stem>/`` by default). When writing, finished chunks of scenes are checkpointed in
        ``<out>/.<stem>.chunks/`` and a rerun resumes from them (:mod:`tumble.pipeline.checkpoint`).
    progress : bool, optional
        Progress bars (default: on a terminal only).
    scheduler : str or distributed.Client, optional
        Run the scenes on a dask cluster: ``"local"`` (a LocalCluster on 127.0.0.1), a scheduler address
        ``"tcp://HOST:PORT"``, or a connected ``distributed.Client`` (see :mod:`tumble.pipeline.distributed`).
        Default: in this process. The results are the same bits either way.
    device : {"cpu", "cuda"}, optional
        Overrides the study's ``integration.device``. ``"cuda"`` runs the scenes on the device (stepping, closed
        form and a ``[model]``'s); a device that cannot run is refused before anything runs (``device 'cuda': ...``);
        an invalid value is a ``StudyError`` naming the field. The figures' traces of a few samples (invariant drift,
        attitude, flat spin, work-precision) run on the CPU.
    chunk_scenes : int, optional
        Scenes per chunk (checkpoint and dask task); the results do not depend on it.
    chunk_samples : int, optional
        A scene of more samples than this is cut into ranges of this many samples, each its own chunk (a
        multiple of 4096; default :data:`DEFAULT_CHUNK_SAMPLES`); the results do not depend on it.

    Returns
    -------
    xarray.Dataset
        Per scene ``rate``, ``rate_theory``, ``rel_error``, ``kind`` (scan parameters as coordinates), the
        arrays and curves the outputs ask for, and, when written, exactly what the file holds (provenance and
        the resolved study in ``attrs["study"]``).

    Raises
    ------
    tumble.pipeline.config.StudyError
        Invalid study (the message names the file, the field path and what is wrong); nothing is written.
    tumble.pipeline.checkpoint.OutputError
        The output folder cannot be written; earlier results there are left as they were.

    See Also
    --------
    tumble.scan : The scans a study runs, from Python.
    tumble.io.read_dataset : A written result read back.

    Examples
    --------
    A study as a mapping, with no figures and no ``out``: nothing is written:

    >>> import tumble
    >>> study = {"body": {"moments": [1.0, 2.0, 3.0]}, "spin": {"axis": 2}, "perturbation": {"samples": 64},
    ...          "outputs": {"figures": []}}
    >>> ds = tumble.run_study(study)
    >>> str(ds["kind"].values), bool(ds["rel_error"] < 5e-3)
    ('exponential', True)
    """
    if device is not None:
        overrides = {**(overrides or {}), "integration.device": device}
    prepared = prepare_study(source, overrides=overrides, out=out)
    with _scheduler(scheduler) as client:
        return execute_study(prepared, progress=progress, client=client, chunk_scenes=chunk_scenes,
                             chunk_samples=chunk_samples).dataset


@contextlib.contextmanager
def _scheduler(scheduler):
    """A dask client for ``scheduler`` (None: none; a Client is used as it is, not closed)."""
    if scheduler is None or not isinstance(scheduler, str):
        yield scheduler
        return
    from . import distributed

    with distributed.connect(scheduler) as client:
        yield client
