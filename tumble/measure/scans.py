"""Scans: every combination of scene parameters measured, and the layout that cuts a scan into scenes.

:func:`scan` runs the product of scene parameters (bodies, e.g. over :func:`inertia_triangle`, axes, spins,
amplitudes, methods) and stacks the scenes along scan dimensions. The same scan cut into chunks of scenes, as
``tumble run`` does to checkpoint it or run it on a dask cluster: :func:`scan_layout` (the scenes, in order),
:func:`scan_scene` or a :class:`ScenePlanner` (the plan of scene ``i``), :func:`scene_batch` (the records of whole
scenes, closed-form ones in batches), :func:`tumble.measure.records.assemble_scan` (the dataset).
"""

from __future__ import annotations

import itertools
import math
import sys

import numpy as np

from ..engine import cost
from ..engine.device import resolve_device
from ..engine.progress import tqdm
from ..physics.bodies import Body, one_body
from .planning import PROBES, planned_scene, scene_estimate, scene_options, validate_scene
from .records import assemble_scan
from .reduction import scene_records
from .running import closed_form_samples, scene_samples, stepping_samples_on_device

__all__ = ["ScenePlanner", "inertia_triangle", "scan", "scan_layout", "scan_scene", "scan_scene_parameters",
           "scene_batch"]


#: Bytes per sample and scene a scan keeps: its per-sample arrays (rate, status, flip times, the index), twice (the
#: records and the stacked dataset).
_SCAN_KEPT = 2 * (8 + 1 + 8 + 8 + 8)


def inertia_triangle(n=20):
    """Moments on an ``n × n`` grid over the inertia triangle, every point a valid body.

    With ``I3 = 1`` the largest moment, ``I2/I3 = s`` runs over ``(1/2, 1)`` and ``I1/I3`` over
    ``(1 − s, s)`` (the triangle inequality ``I1 + I2 >= I3`` and the ordering ``I1 <= I2``); both are
    sampled at cell midpoints, so no point sits on an edge (a symmetric top or a flat lamina).

    Returns
    -------
    moments : ndarray, shape (n * n, 3)
    coords : dict
        ``"i2_over_i3"`` and ``"i1_fraction"`` (where ``I1/I3`` lies between ``1 − s`` and ``s``), each (n * n,).

    See Also
    --------
    tumble.scan : Measure every body of the grid (``body_coords=coords``).

    Examples
    --------
    >>> import tumble
    >>> moments, coords = tumble.inertia_triangle(4)
    >>> moments.shape, sorted(coords)
    ((16, 3), ['i1_fraction', 'i2_over_i3'])
    >>> bool((moments[:, 0] + moments[:, 1] > moments[:, 2]).all())
    True
    """
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1 (points along each side of the triangle), got {n!r}")
    mid = (np.arange(n) + 0.5) / n
    s, u = np.meshgrid(0.5 + 0.5 * mid, mid, indexing="ij")
    i1 = (1.0 - s) + u * (2.0 * s - 1.0)
    moments = np.stack([i1.ravel(), s.ravel(), np.ones(n * n)], axis=1)
    return moments, {"i2_over_i3": s.ravel(), "i1_fraction": u.ravel()}


def scan_layout(bodies, axis=(1, 2, 3), spin=1.0, amplitude=1e-3, method="auto"):
    """The scenes of a scan, in order: what :func:`scan` runs, cut so that scenes can run anywhere.

    Parameters
    ----------
    bodies, axis, spin, amplitude, method
        As for :func:`scan`.

    Returns
    -------
    dict
        ``moments`` (B, 3) kg m², ``swept`` (name -> list of values, the scan dimensions after ``body``, in
        order), ``fixed`` (name -> scalar) and ``scenes``: the number of scenes, ``B`` times the product of
        the swept lengths. Scene ``i`` is body ``i // per_body`` with the ``i % per_body``-th combination of
        the swept values in C order (:func:`scan_scene_parameters`). Plain data: it pickles and hashes.
    """
    if isinstance(bodies, Body) or (not isinstance(bodies, (list, tuple)) and np.ndim(bodies) == 1) or (
            isinstance(bodies, (list, tuple)) and len(bodies) == 3 and all(np.ndim(b) == 0 for b in bodies)):
        bodies = [bodies]
    moments = np.array([one_body(b) for b in bodies])
    if not len(moments):
        raise ValueError("bodies holds no body (an empty sequence)")
    values = {"axis": axis, "spin": spin, "amplitude": amplitude, "method": method}
    swept = {name: list(v) for name, v in values.items() if isinstance(v, (list, tuple, np.ndarray))}
    for name, v in swept.items():
        if len(v) == 0:
            raise ValueError(f"{name} must not be an empty sequence")
    fixed = {name: v for name, v in values.items() if name not in swept}
    per_body = math.prod(len(v) for v in swept.values())
    return {"moments": moments, "swept": swept, "fixed": fixed, "scenes": len(moments) * per_body}


def scan_scene_parameters(layout, index):
    """``(moments (3,), {"axis", "spin", "amplitude", "method"})`` of scene ``index`` of a :func:`scan_layout`."""
    return _scene_parameters(layout, list(itertools.product(*layout["swept"].values())), index)


def _scene_parameters(layout, combos, index):
    body, combo = divmod(index, len(combos))
    return layout["moments"][body], {**layout["fixed"], **dict(zip(layout["swept"], combos[combo]))}


def scan_scene(layout, index, *, samples=256, seed=0, **options):
    """The :func:`scene_plan` of scene ``index`` of a :func:`scan_layout` (``options`` as for :func:`measure`).

    A scene depends only on its parameters, ``samples``, ``seed`` and ``options``, never on which other
    scenes run, where or in which order (common random numbers from ``seed``), so a scan cut into chunks of
    scenes and run on any number of processes assembles to the same bits (:func:`assemble_scan`).
    """
    options["device"] = resolve_device(options.get("device", "cpu"))
    return ScenePlanner(layout, samples=samples, seed=seed, **options)(index)


class ScenePlanner:
    """:func:`scan_scene` of any scene of a layout, the scan's shared options and each combination of its swept
    values checked once rather than once per scene (half the time of planning a 30 000-scene map went to checking
    the same options again); the same :class:`Scene` records as :func:`scene_plan`, and the same errors, raised when
    the first scene that needs the value is planned.

    Its ``device`` is trusted: resolved (``"cpu"`` or ``"cuda"``, :func:`tumble.engine.device.resolve_device`) where
    the run entered: :func:`scan`, :func:`scan_scene`, a study's :func:`tumble.pipeline.runner.scene_job`."""

    def __init__(self, layout, *, samples=256, seed=0, **options):
        options.pop("progress", None)
        self.layout, self.samples, self.seed = layout, samples, seed
        self._combos = list(itertools.product(*layout["swept"].values()))
        self._flips = options.pop("flips", 3)
        self._options = options
        self._shared = None
        self._checked = {}

    def parameters(self, index):
        """As :func:`scan_scene_parameters`."""
        return _scene_parameters(self.layout, self._combos, index)

    def __call__(self, index):
        moments, params = self.parameters(index)
        values = (params["axis"], params["spin"], params["amplitude"], params["method"])
        key = repr(values)
        if key not in self._checked:
            distribution = self._options.get("distribution", "cone")
            self._checked[key] = validate_scene(moments, *values[:3], self.samples, values[3], self._flips,
                                                 distribution)[1:]
        if self._shared is None:
            self._shared = scene_options(self.seed, **self._options)
        axis, spin, amplitude, samples, flips = self._checked[key]
        return planned_scene(moments, axis, spin, amplitude, samples, params["method"], flips, self._shared)


def scene_batch(scenes, *, progress=False):
    """The records (:func:`scene_records`) of whole scenes: the closed-form scenes in batches
    (:func:`closed_form_samples`), the fixed-step scenes on the device many a launch
    (:func:`stepping_samples_on_device`), the others one by one."""
    parts = [None] * len(scenes)
    together = {}  # closed-form scenes; fixed-step scenes on the device (many a launch), but those with a norm curve
    for i, scene in enumerate(scenes):
        if scene.chosen == "exact" or (scene.device == "cuda" and "norm" not in scene.curves):
            together.setdefault((scene.chosen == "exact", scene.samples), []).append(i)
    for (closed_form, samples), members in together.items():
        run_together = closed_form_samples if closed_form else stepping_samples_on_device
        for i, part in zip(members, run_together([scenes[i] for i in members], 0, samples)):
            parts[i] = [part]
    for i, scene in enumerate(scenes):
        if parts[i] is None:
            parts[i] = [scene_samples(scene, 0, scene.samples, progress=progress)]
    return scene_records(scenes, parts)


def scan(bodies, axis=(1, 2, 3), spin=1.0, amplitude=1e-3, method="auto", *, samples=256, seed=0,
         body_coords=None, **options):
    """Measure every combination of scene parameters; scan parameters become coordinates.

    Parameters
    ----------
    bodies : Body, array_like (3,) or sequence of them, or ndarray (B, 3)
        The bodies: a ``body`` dimension with coordinates ``I1``, ``I2``, ``I3`` (kg m²).
    axis, spin, amplitude, method : scalar or sequence
        A sequence becomes a dimension of that name; a scalar stays a scalar coordinate.
    samples, seed
        As for :func:`measure`. Every scene uses the same seed: scenes are coupled sample by sample
        (common random numbers), so differences between them are physics, not sampling noise.
    body_coords : dict, optional
        Extra coordinates along ``body`` (name → array of length B), e.g. from :func:`inertia_triangle`.
    **options
        Passed to :func:`measure` (``dt``, ``flips``, ``distribution``, ``progress``, ``device``).

    Returns
    -------
    xarray.Dataset
        The scene variables of :func:`measure` with dimensions ``(body, axis, spin, amplitude, method)`` (those
        that were sequences), per-sample variables with ``sample`` last.

    See Also
    --------
    tumble.measure : One scene.
    tumble.regress_scan : Measured rates against theory over the scan.
    tumble.inertia_triangle : A grid of bodies to scan.

    Notes
    -----
    Closed-form scenes run in batches (:func:`scene_batch`). The same scan cut into chunks of scenes:
    :func:`scan_layout`, :func:`scan_scene`, :func:`scene_batch`, :func:`assemble_scan` (what ``tumble run``
    does to checkpoint a scan and to run it on a dask cluster).

    Examples
    --------
    The three axes of one body, 16 samples each:

    >>> import tumble
    >>> ds = tumble.scan((1.0, 2.0, 3.0), axis=[1, 2, 3], samples=16)
    >>> dict(ds["rate"].sizes), ds["kind"].values.tolist()
    ({'body': 1, 'axis': 3}, [['periodic', 'exponential', 'periodic']])
    >>> bool((ds["rel_error"] < 5e-3).all())
    True
    """
    layout = scan_layout(bodies, axis, spin, amplitude, method)
    n = layout["scenes"]
    if isinstance(samples, (int, np.integer)) and not isinstance(samples, (bool, np.bool_)) and samples >= 1:
        # before any scene is planned: every scene's per-sample arrays are kept (and stacked once more)
        cost.refuse(scene_estimate(False, False, int(samples), PROBES + 1, scenes=n, kept_per_sample=_SCAN_KEPT),
                    f"{n:,} scenes of samples = {samples}")
    progress = options.pop("progress", None)
    show = sys.stderr.isatty() if progress is None else progress
    options["device"] = resolve_device(options.get("device", "cpu"))  # once: the planner and the scenes trust it
    planner = ScenePlanner(layout, samples=samples, seed=seed, **options)
    plans = [planner(index) for index in range(n)]
    steps = sum(plan.plan.n_steps for plan in plans if plan.chosen != "exact")
    cost.refuse(cost.scene_cost(samples, steps / n, scenes=n, working=0, times=PROBES + 1, fits=True),
                f"{n:,} scenes of samples = {samples} ({steps:,} steps in all)", options["device"])
    records = []
    step = max(1, math.ceil(len(plans) / 32))
    with tqdm(total=len(plans), unit="scenes", disable=not show, desc="scan") as bar:
        for lo in range(0, len(plans), step):
            records += scene_batch(plans[lo:lo + step])
            bar.update(len(plans[lo:lo + step]))
    return assemble_scan(layout, records, body_coords)
