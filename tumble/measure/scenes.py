"""Scenes and scans: measure growth rates and frequencies against theory, as xarray Datasets.

:func:`measure` runs one *scene* — an ensemble of spins about one principal axis of one body, perturbed by a
small tilt — and measures, per sample and for the scene, how fast the perturbation oscillates or grows,
next to linear theory. :func:`scan` runs the product of scene parameters and stacks the scenes along scan
dimensions; :func:`regress_scan` and :func:`flip_time_law` regress a scan.

Planning a scene (what is computed and why):

* the kind comes from linear theory (:func:`tumble.physics.theory.linear`): ``periodic`` (largest or smallest
  axis), ``exponential`` (intermediate axis) or ``neutral`` (degenerate moments: symmetric top about an
  axis of its equal pair, sphere);
* ``method="auto"``: torque-free scenes take the closed form (:mod:`tumble.physics.exact`) — no steps; a named
  method steps with ``dt`` chosen from its order (:data:`STEPS_PER_RADIAN`) unless given;
* periodic and neutral scenes store the transverse components at :data:`SAVES_PER_PERIOD` times per period
  over :data:`PERIODS` periods and fit the phase (:func:`tumble.measure.estimators.oscillation_frequencies`);
* exponential scenes record only the scaled transverse norm at :data:`PROBES` times (no trajectory), fit its
  log-slope inside the linear regime (:func:`tumble.measure.estimators.growth_rates`), and locate the first
  ``flips`` sign changes of the spin-axis component; on a stepping path each sample stops once its norm has
  saturated and it has flipped ``flips`` times;
* samples run in slices of :data:`SLICE` (memory stays O(samples), whatever the ensemble size);
* a scene is planned once (:func:`scene_plan`), its samples run in any ranges that start at multiples of
  :data:`tumble.engine.sampling.CHUNK` (:func:`scene_samples`: per-sample fits only, in any process) and the ranges
  are reduced once (:func:`scene_result`: median, confidence interval, fit window and flip medians over all the
  samples) — the same bits as the whole scene; ``tumble run`` cuts large scenes this way.

What the scene skipped is on the dataset (``path``, ``sample_steps_computed``, ``sample_steps_skipped``).
"""

from __future__ import annotations

import itertools
import json
import math
import sys
import warnings
from dataclasses import dataclass, field

import numpy as np

from .. import registry
from .._version import __version__
from ..engine.ensemble import flip_times, observation_times, run_ensemble, run_scene_table, torque_spec
from ..engine.device import LAUNCH_SAMPLES, resolve_device
from ..engine.integration import integrate
from ..engine.progress import tqdm
from ..engine.sampling import CHUNK, drawn_spins, perturbed_spins, seed_entropy
from ..physics import exact, theory
from ..physics.bodies import Body, one_body
from ..registry import STATUS_NAMES, STATUS_OK, STEPPING
from ..engine import cost
from . import estimators as analysis
from .records import CONFIDENCE, INTERVAL_TEXT, KIND_UNITS, assemble_scan, scene_dataset

# xarray is imported by the functions that make a dataset: a study's scenes run without it (``tumble run`` builds
# their dataset in its figure process, :mod:`tumble.pipeline.figure_process`).

__all__ = ["CURVES", "SAMPLE_STATUS_NAMES", "ScenePlanner", "assemble_scan", "check_amplitude", "check_fit_span",
           "closed_form_samples", "flip_time_law", "inertia_triangle", "invariant_drift", "measure", "refuse_plan",
           "regress_scan", "scan", "scan_layout", "scan_scene", "scan_scene_parameters", "scene_batch",
           "scene_dataset", "scene_estimate", "scene_plan", "scene_records", "scene_result", "scene_samples",
           "stepping_samples_on_device"]

#: Per-sample status in a measurement: the engine's (ok, non-finite, invariant drift), then the fit's.
SAMPLE_STATUS_NAMES = registry.SAMPLE_STATUS_NAMES
_FIT_OFFSET = len(STATUS_NAMES) - 1

#: Fixed steps per radian of the scene's fastest phase (1/rate, 1/ω or 1/|spin|), by order of the method:
#: enough that the method's own error stays far below the accuracy targets (0.1 % periodic, 0.5 %
#: exponential). Pass ``dt`` to choose otherwise.
STEPS_PER_RADIAN = {1: 5000, 2: 200, 4: 40, 8: 12}

#: Periods observed in a periodic or neutral scene, and stored times per period (phase unwrapping needs
#: well over 2; 32 keeps every phase step below π/16).
PERIODS = 8
SAVES_PER_PERIOD = 32

#: Most stored states per sample of a periodic scene (bounds memory when a long horizon is asked for).
MAX_SAVES = 8192

#: Least growth (e-foldings, ``rate * span``) or phase (rad, ``frequency * span``) a scene's fit may span: over a
#: horizon of 1e-6 s the (1, 2, 3) body's intermediate-axis rate came out 0.3 to 2 % off, over 1e-9 s 265 1/s
#: for 0.577 (round-off, not growth); 1e-5 s (6e-6 e-foldings) still measured it to 0.03 %.
MIN_FIT_SPAN = 1e-5

#: Points of the optional curves: the traced sample's trajectory (flip_components figure).
TRACE_POINTS = 1500

#: Optional per-scene curves :func:`measure` can keep for figures: the median scaled norm against time
#: (exponential scenes) and the body-frame ω of one sample (every scene).
CURVES = ("norm", "trace")

#: Probe times of the transverse norm in an exponential scene (evenly spaced up to saturation).
PROBES = 256

#: End of the linear regime: the plain transverse norm reaches ``SATURATION · |spin|`` — or, for larger
#: tilts, ``SATURATION_TILTS`` times the tilt (the error then grows as the nonlinear correction, O(amplitude²)).
SATURATION = 0.01
SATURATION_TILTS = 10.0

#: Samples per engine call (bounds the memory of stored components and probes).
SLICE = 8 * CHUNK

#: Samples of closed-form scenes run together (:func:`closed_form_samples`): small enough that the batch's
#: arrays stay in the processor's cache between the kernel and the estimators, large enough that a kernel call
#: and an estimator call cost little next to their work. A slice of one scene may be larger (it runs alone).
BATCH = 4096

#: Bytes per sample and observation time held while a slice of samples is measured — the observed components or
#: probe norms and the fits' temporaries — by (stepping, kind is exponential): peaks measured over 32768-sample
#: slices of 257 times (``tests/test_memory.py``). A stepping periodic scene keeps its trajectory and copies of
#: two of its components for the phase fit; a stepping exponential scene keeps only the probe norms.
_BYTES_PER_TIME = {(False, True): 28, (False, False): 22, (True, True): 14, (True, False): 52}

#: Bytes per sample of a scene while its slices are reduced (the per-sample fits, their stack and the record).
_BYTES_PER_REDUCED_SAMPLE = 200


def scene_estimate(stepping, exponential, samples, times, *, steps=0, flips=0, scenes=1, kept_per_sample=0):
    # size: the quantities the planner knows (or a study's estimate of them), each a factor of the cost
    """:class:`tumble.engine.cost.Cost` of ``scenes`` scenes of ``samples`` samples observed at ``times`` times
    over ``steps`` fixed steps (``stepping``; else the closed form) with ``flips`` flips timed, keeping
    ``kept_per_sample`` bytes per sample and scene: the working set of one slice of samples (:data:`SLICE`;
    closed-form scenes run together in batches of :data:`BATCH`) from :data:`_BYTES_PER_TIME`, the scene's
    reduction and what is kept. ``exponential`` False: a periodic (or possibly periodic) scene."""
    in_flight = min(samples if stepping else max(samples, min(BATCH, scenes * samples)), SLICE)
    working = (float(in_flight) * (float(times) * _BYTES_PER_TIME[(bool(stepping), bool(exponential))]
                                   + 32.0 * flips) + float(samples) * _BYTES_PER_REDUCED_SAMPLE)
    return cost.scene_cost(samples, steps if stepping else 0, scenes=scenes, kept_per_sample=kept_per_sample,
                           working=working)


#: Bytes per sample and scene a scan keeps: its per-sample arrays (rate, status, flip times, the index), twice (the
#: records and the stacked dataset).
_SCAN_KEPT = 2 * (8 + 1 + 8 + 8 + 8)


def refuse_plan(samples, plan, stepping, exponential, flips, device="cpu"):
    """Refuse a planned scene past the cost bound (:func:`tumble.engine.cost.refuse`), naming what set its size."""
    times = len(plan.probe_times) if plan.probe_times is not None else plan.n_steps // (plan.save_every or 1) + 2
    estimate = scene_estimate(stepping, exponential, samples, times, steps=plan.n_steps, flips=flips)
    steps = f"{plan.n_steps:,} steps of {plan.dt:.3g} s" if stepping else "the closed form"
    cost.refuse(estimate, f"samples = {samples} over a horizon of {plan.t_end:.3g} s ({steps}, flips = {flips})",
                device)


def _check_method(method):
    if not isinstance(method, str) or method not in registry.CHOICES:
        raise ValueError(f"method must be one of {', '.join(registry.CHOICES)}; got {method!r}")
    return method


def _positive_int(value, name):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class StepPlan:
    """Horizon, step and observation times of a scene (:func:`_plan`)."""

    t_end: float  # s, a whole number of steps
    dt: float  # s
    n_steps: int
    probe_times: np.ndarray | None = None  # exponential: the growth fit's equally spaced probes, s
    weights: np.ndarray | None = None  # exponential: the transverse norm's invariant weights (3,)
    saturation: float | None = None  # exponential: end of the linear regime (scaled norm), rad/s
    save_every: int | None = None  # periodic and neutral: steps between stored states
    plane: tuple | None = None  # neutral: the two axes whose phase is measured


@dataclass(frozen=True, eq=False)
class Scene:
    """One scene of :func:`measure`, validated and planned (:func:`scene_plan`): plain data that pickles (dask,
    checkpoints) and is read, never changed, by every later step."""

    moments: np.ndarray  # (3,) kg m²
    axis: int  # 1, 2 or 3
    spin: float  # rad/s
    amplitude: float  # rad
    samples: int
    method: str  # as asked ("auto" included)
    chosen: str  # the method that runs ("exact" for the closed form)
    kind: str  # linear theory's "periodic", "exponential" or "neutral"
    value: float  # linear theory's frequency (rad/s) or rate (1/s)
    spin_up: dict | None  # an axial torque's spin-up (_axial_spin_up), None when torque-free
    torque: object  # the torque as given, None when torque-free
    plan: StepPlan
    flips: int  # flips timed per sample (0 unless exponential)
    entropy: int  # the seed's entropy
    distribution: str
    curves: tuple = field(default=())
    device: str = "cpu"  # where the samples step (resolved: "cpu" or "cuda")


def _neutral_plane(moments, a):
    """The plane whose phase a neutral scene measures: ``(a, d)`` with ``I_d = I_a`` (the degenerate pair,
    which precesses slowly about the distinct axis), or the transverse pair for a sphere."""
    b, c = (a + 1) % 3, (a + 2) % 3
    scale = moments.max()
    equal_b = abs(moments[b] - moments[a]) <= 1e-12 * scale
    equal_c = abs(moments[c] - moments[a]) <= 1e-12 * scale
    if equal_b and equal_c:
        return (b, c), 0.0
    d, e = (b, c) if equal_b else (c, b)
    return (a, d), abs(moments[e] - moments[a]) / moments[a]


def _plan(moments, a, kind, value, spin, amplitude, method, dt, flips, probe_spins, horizon=None, spin_max=None):
    # size: the scene's resolved quantities the horizon and step depend on; called once per scene by scene_plan
    """Horizon, step and observation times of a scene.

    Observations (probes or stored states) are ``spacing`` apart, a whole number of steps: the growth estimator
    needs equally spaced times, and the closed form evaluates exactly there. ``spin_max`` (a torque spins the
    body up) sets the step; ``horizon`` replaces the planned horizon.
    """
    w = abs(spin)
    timescale = 1.0 / value if value > 0 else 1.0 / w
    if dt is None and method != "exact":
        fastest = max(w, spin_max or w)
        dt = min(timescale * w / fastest, 1.0 / fastest) / STEPS_PER_RADIAN[registry.method(method).order]
    tilt = math.sin(min(amplitude, 0.5 * np.pi))
    plan = {}  # the kind's own fields of the StepPlan
    if kind == "exponential":
        weights = analysis.invariant_weights(moments, a + 1)
        b, c = (a + 1) % 3, (a + 2) % 3
        # End of the linear regime: the plain transverse norm at `level`. Once the growing mode dominates, a plain
        # norm p has the scaled norm p / sqrt((1/g_b + 1/g_c) / 2).
        level = max(SATURATION, SATURATION_TILTS * tilt) * w
        saturation = level / math.sqrt(0.5 * (1.0 / weights[b] + 1.0 / weights[c]))
        t_growth = (math.log(max(level / max(tilt * w, 1e-300), math.e)) + 3.0) / value
        if horizon:
            t_growth = min(t_growth, horizon)
        spacing = t_growth / PROBES
        t_end = t_growth
        if flips and horizon:
            t_end = horizon
        elif flips:
            w0_probe = probe_spins()
            first = exact.first_flip_time(moments, w0_probe)
            last = first + (flips - 1) * exact.flip_spacing(moments, w0_probe)
            last = last[np.isfinite(last)]
            if len(last):
                t_end = max(t_end, 1.1 * float(np.quantile(last, 0.9)))
        plan.update(weights=weights, saturation=saturation)
    else:
        if kind == "periodic":
            period = 2 * np.pi / value
        else:
            plane, ratio = _neutral_plane(moments, a)
            precession = w * tilt * ratio
            period = 2 * np.pi / (precession if precession > 0 else w)
            plan.update(plane=plane)
        # A torque that spins the body up shortens the period: sample at the fastest one.
        spacing = period / SAVES_PER_PERIOD * (w / max(w, spin_max or w))
        t_end = horizon or PERIODS * period
        if t_end / spacing > MAX_SAVES:
            raise ValueError(f"horizon {t_end:g} s needs {t_end / spacing:.0f} stored states per sample for the phase "
                             f"fit ({SAVES_PER_PERIOD} per period), more than {MAX_SAVES}; choose a shorter horizon")
    every = 1 if method == "exact" else max(1, math.ceil(spacing / dt))
    dt = spacing / every
    n_steps = max(1, math.ceil(t_end / dt - 1e-9))
    if kind == "exponential":
        plan["probe_times"] = np.arange(PROBES + 1) * spacing
    else:
        plan["save_every"] = every
    return StepPlan(t_end=n_steps * dt, dt=dt, n_steps=n_steps, **plan)


def check_amplitude(amplitude):
    """Refuse a tilt below :data:`tumble.registry.MIN_AMPLITUDE` (no rate can be measured from it): a ValueError
    naming ``amplitude`` and why."""
    problem = float(amplitude) > 0 and registry.amplitude_problem(float(amplitude))
    if problem:
        raise ValueError(f"amplitude {problem}")


def check_fit_span(kind, value, span, horizon):
    """Refuse a scene whose fit spans fewer than :data:`MIN_FIT_SPAN` e-foldings (``kind`` exponential) or radians
    of phase (periodic) at the theory's ``value`` over ``span`` s: what it would report is round-off, not a rate."""
    if kind == "neutral" or value * span >= MIN_FIT_SPAN:
        return
    what = "e-foldings of growth" if kind == "exponential" else "radians of phase"
    raise ValueError(f"horizon = {horizon!r} s: the fit would span {value * span:.2g} {what} (theory: {value:.4g} "
                     f"{KIND_UNITS[kind]}), fewer than the {MIN_FIT_SPAN:g} a rate can be measured over above "
                     f"round-off; give a horizon of at least {MIN_FIT_SPAN / value:.3g} s, or none (the planner's)")


def _validate_scene(body, axis, spin, amplitude, samples, method, flips, distribution):
    moments = one_body(body)
    if isinstance(axis, (bool, np.bool_)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (a principal axis, 1-based), got {axis!r}")
    _check_method(method)
    flips = _positive_int(flips, "flips")
    perturbed_spins(moments, axis, spin, amplitude, 1, seed=0, distribution=distribution)  # checks all three
    if float(amplitude) == 0.0:
        raise ValueError("amplitude must be > 0 rad: a growth rate or frequency is measured on perturbed spins, "
                         "and a spin exactly on its axis never moves off it")
    check_amplitude(amplitude)
    if isinstance(samples, (bool, np.bool_)) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    try:
        cost.check(cost.scene_cost(samples, 0))
    except ValueError as err:
        raise ValueError(f"samples = {samples}: {err}") from None
    # the flip times' memory before the plan (whose horizon the flips set): answered before any kernel loads
    cost.refuse(scene_estimate(False, True, int(samples), PROBES + 1, flips=flips),
                f"flips = {flips} for samples = {samples}")
    return moments, int(axis), float(spin), float(amplitude), int(samples), flips


def measure(body, axis, spin=1.0, amplitude=1e-3, samples=1024, seed=0, method="auto", *, dt=None, flips=3,
            distribution="cone", torque=None, horizon=None, curves=(), progress=None, device="cpu"):
    # size: a public call (tumble.measure): each keyword is a documented scene option
    """Measure one scene: how fast perturbations of a steady spin oscillate or grow, against linear theory.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        Principal moments, kg m².
    axis : {1, 2, 3}
        Spin axis, 1-based.
    spin : float
        Unperturbed spin about ``axis``, rad/s (non-zero).
    amplitude : float
        Tilt of the perturbed spins from the axis, rad (see :func:`tumble.engine.sampling.perturbed_spins`).
    samples : int
        Ensemble size.
    seed : int >= 0 or None
        Entropy of the ensemble (``None``: fresh, stored on the dataset).
    method : str
        ``"auto"`` (closed form: the scene is torque-free), ``"exact"`` or a fixed-step method name.
    dt : float, optional
        Step of a fixed-step method, s (default: from the method's order, :data:`STEPS_PER_RADIAN`).
    flips : int
        Exponential scenes: flips of the spin axis to time (first flip and spacing); 0 skips them.
    distribution : str
        Tilt distribution, see :func:`tumble.engine.sampling.perturbed_spins`.
    torque : None, array_like (3,) or mapping, optional
        A torque about the spin axis — three numbers (N m) or a named profile (see
        :func:`tumble.engine.ensemble.torque_spec`) — for periodic scenes: the spin then changes as
        ``w_a(t) = spin + (N_a/I_a) S(t)`` and linear theory's phase advances by ``sqrt(q) ∫|w_a| dt``; the
        theory rate is the least-squares slope of that phase over the observation times, exactly what the
        phase fit measures. (The wobbly space station of the problem sheet.)
    horizon : float, optional
        Span of the scene, s (default: :data:`PERIODS` periods, or growth to saturation and ``flips`` flips).
    curves : iterable of str
        Optional curves to keep for figures, from :data:`CURVES`: ``"norm"`` (median and quartiles of the
        scaled transverse norm at the probe times, exponential scenes) and ``"trace"`` (the body-frame ω of
        the first sample over the horizon).
    progress : bool, optional
        Progress bar (default: on a terminal only).
    device : {"cpu", "cuda"}
        Where the scene's samples step. On ``"cuda"`` a stepping scene (a named fixed-step method, or a torque) runs
        its samples and their observers (probe norms, flips, early stop) on the device and only the per-sample
        arrays the fits need come back; a closed-form scene (``"exact"``, or ``"auto"`` torque-free) sets up and
        evaluates its samples on the device (:func:`tumble.physics.exact.omega_on_device`) and times its flips on the
        host; the fits and the reduction run on the host. A device that is missing raises the ``ValueError``
        ``device 'cuda': ...`` (saying what is), never a silent run on the CPU.

    Returns
    -------
    xarray.Dataset
        Scalars ``rate`` (median over valid samples), ``rate_theory``, ``rel_error``
        (``|rate − rate_theory| / rate_theory``; for a neutral scene, whose theory is 0, relative to
        ``|spin|``), ``kind``; its 95 % confidence interval (order statistics) ``rate_ci_low``/``rate_ci_high`` and ``rate_spread``;
        ``samples_used``/``samples_excluded``; the fit window (exponential); flip statistics (exponential,
        ``flips > 0``); per sample ``sample_rate(sample)`` and ``sample_status(sample)``; the scene's
        parameters as scalar coordinates (``I1``, ``I2``, ``I3``, ``axis``, ``spin``, ``amplitude``,
        ``method``) ready to be stacked by :func:`scan`.

    Raises
    ------
    ValueError
        Invalid body, axis, spin, amplitude, samples, seed, method, flips, torque, horizon or curves.

    Examples
    --------
    >>> ds = measure((1.0, 2.0, 3.0), axis=2, samples=64)
    >>> str(ds.kind.values), bool(ds.rel_error < 5e-3)
    ('exponential', True)
    """
    scene = scene_plan(body, axis, spin, amplitude, samples, seed, method, dt=dt, flips=flips,
                       distribution=distribution, torque=torque, horizon=horizon, curves=curves, device=device)
    return scene_result(scene, [scene_samples(scene, 0, scene.samples, progress=progress)])


def scene_plan(body, axis, spin=1.0, amplitude=1e-3, samples=1024, seed=0, method="auto", *, dt=None, flips=3,
               distribution="cone", torque=None, horizon=None, curves=(), device="cpu"):
    # size: the arguments of measure (a public call), checked and frozen into a Scene record
    """Validate and plan one scene of :func:`measure` (same arguments, no ``progress``): plain data.

    A scene is measured in two steps that can run apart: :func:`scene_samples` runs any range of its samples
    (each sample depends only on the plan and its index), :func:`scene_result` reduces the ranges to the scene
    dataset. ``measure`` is ``scene_result(plan, [scene_samples(plan, 0, samples)])``; a scene cut into ranges
    at multiples of :data:`tumble.engine.sampling.CHUNK` reduces to the same bits.

    Raises
    ------
    ValueError
        As :func:`measure`.
    """
    moments, axis, spin, amplitude, samples, flips = _validate_scene(body, axis, spin, amplitude, samples,
                                                                     method, flips, distribution)
    options = _scene_options(seed, dt=dt, distribution=distribution, torque=torque, horizon=horizon, curves=curves,
                             device=device)
    return _planned_scene(moments, axis, spin, amplitude, samples, method, flips, options)


def _scene_options(seed, *, dt=None, distribution="cone", torque=None, horizon=None, curves=(), device="cpu"):
    """The options a scene shares with the other scenes of a scan, checked once: ``seed`` as its entropy."""
    device = resolve_device(device)
    if dt is not None and (not np.isfinite(dt) or dt <= 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    if horizon is not None and (not np.isfinite(horizon) or horizon <= 0):
        raise ValueError(f"horizon must be a positive number of seconds, got {horizon!r}")
    curves = tuple(curves)
    for name in curves:
        if name not in CURVES:
            raise ValueError(f"curves must be among {', '.join(CURVES)}; got {name!r}")
    return {"entropy": seed_entropy(seed), "dt": dt, "distribution": distribution, "torque": torque,
            "horizon": horizon, "curves": curves, "device": device}


def _planned_scene(moments, axis, spin, amplitude, samples, method, flips, options):
    # size: a scene's checked quantities (_validate_scene) and its scan's shared options (_scene_options)
    """The :class:`Scene` of checked arguments (:func:`_validate_scene`, :func:`_scene_options`): the theory, the
    method and the plan; refused past the cost bound or a fit span too short."""
    entropy, distribution, torque, horizon = (options[k] for k in ("entropy", "distribution", "torque", "horizon"))
    a = axis - 1
    kind, value = theory.linear(moments, axis, spin)
    spin_up = _axial_spin_up(torque, moments, a, kind, spin)
    chosen, _ = registry.choose_method(method, torque_free=spin_up is None)
    if chosen == "exact":  # before the plan, whose horizon already takes the closed form's set-up
        exact.compile_kernels_side_by_side(kind)
    spin_max = None
    if spin_up is not None:
        span = horizon or PERIODS * 2 * np.pi / value
        spin_max = float(np.abs(spin + spin_up["gain"] * _spin_up_integrals(spin_up, np.linspace(0, span, 1001))[0])
                         .max())
    def probe_spins():  # the first samples, whose flips set the horizon (drawn only when flips are timed)
        return drawn_spins(moments, axis, spin, amplitude, entropy, distribution, 0, min(samples, CHUNK))

    flips = flips if kind == "exponential" else 0
    plan = _plan(moments, a, kind, value, spin, amplitude, chosen, options["dt"], flips, probe_spins, horizon,
                 spin_max)
    check_fit_span(kind, value, plan.probe_times[-1] if kind == "exponential" else plan.t_end, horizon)
    refuse_plan(samples, plan, chosen != "exact", kind == "exponential", flips, options["device"])
    return Scene(moments=moments, axis=axis, spin=spin, amplitude=amplitude, samples=samples, method=method,
                 chosen=chosen, kind=kind, value=value, spin_up=spin_up,
                 torque=torque if spin_up is not None else None, plan=plan, flips=flips, entropy=entropy,
                 distribution=distribution, curves=options["curves"], device=options["device"])


#: Per-sample arrays of a :func:`scene_samples` range, by scene kind (and the flip times, when timed).
_GROWTH_FIT = ("t_start", "t_stop", "norm_start", "norm_stop")
_FLIP_ARRAYS = ("flip_first", "flip_spacing", "flip_exact", "flip_asymptote")


def scene_samples(scene, start, stop, *, progress=False):
    """Run samples ``[start, stop)`` of a :func:`scene_plan`: per-sample fits, no reduction.

    ``start`` must be a multiple of :data:`tumble.engine.sampling.CHUNK` (the engine and the sampler work in whole
    chunks, so that the samples of a range are the same bits as in the unsplit scene); the range holding sample
    0 keeps the norm curve (``curves`` with ``"norm"``), which needs the first :data:`SLICE` samples, so it
    must then reach ``min(SLICE, samples)``.

    Returns
    -------
    dict of ndarray
        ``start``; per sample (length ``stop - start``): ``rate``, ``code`` (int8, :data:`SAMPLE_STATUS_NAMES`),
        the fit's
        ``t_start``/``t_stop``/``norm_start``/``norm_stop`` (exponential) or ``radius``, the flip times
        (exponential with ``flips``); scalars ``sample_steps_computed``, ``sample_steps_skipped``,
        ``rate_theory``, ``path`` and ``torque``; from sample 0 the ``norm_*`` curve. Only plain arrays: it
        pickles and stores in a NumPy archive.
    """
    samples, kind, plan = scene.samples, scene.kind, scene.plan
    if not (0 <= start < stop <= samples and start % CHUNK == 0):
        raise ValueError(f"a sample range must lie in [0, {samples}) and start at a multiple of {CHUNK}, "
                         f"got [{start}, {stop})")
    keep_norm = start == 0 and "norm" in scene.curves and kind == "exponential"
    if keep_norm and stop < min(SLICE, samples):
        raise ValueError(f"the sample range holding sample 0 keeps the norm curve: it must reach "
                         f"{min(SLICE, samples)}, got [{start}, {stop})")
    if scene.chosen == "exact":
        return closed_form_samples([scene], start, stop)[0]
    moments, axis, spin = scene.moments, scene.axis, scene.spin
    growth, n_flips = kind == "exponential", scene.flips
    out = _empty_part(scene, start, stop)
    value = scene.value
    computed = skipped = 0
    step = SLICE if scene.device == "cpu" else max(SLICE, LAUNCH_SAMPLES)  # a device launch needs many samples
    for lo in range(start, stop, step):
        hi = min(lo + step, stop)
        w0 = drawn_spins(moments, axis, spin, scene.amplitude, scene.entropy, scene.distribution, lo, hi)
        phase = analysis.phase_window(moments, axis, kind, plan.plane, spin) if scene.device == "cuda" else None
        result = run_ensemble(moments, w0, plan.t_end, plan.dt, method=scene.chosen, axis=axis, final=False,
                              save_every=None if growth else plan.save_every,
                              probe_times=plan.probe_times if growth else None,
                              norm_weights=plan.weights if growth else None, max_flips=n_flips,
                              stop_norm=plan.saturation if growth else 0.0, stop_flips=n_flips,
                              torque=scene.torque, progress=progress, device=scene.device,
                              growth_window=(plan.saturation, analysis.MIN_POINTS) if growth else None,
                              keep_probes=keep_norm and lo == 0, phase_window=phase, keep_trajectory=phase is None)
        value = _observed(scene, result, w0, out, slice(lo - start, hi - start))
        info = result.info
        computed, skipped = computed + info["sample_steps_computed"], skipped + info["sample_steps_skipped"]
    out.update(sample_steps_computed=np.int64(computed), sample_steps_skipped=np.int64(skipped),
               rate_theory=np.float64(value), path=np.array(info["path"]), torque=np.array(info.get("torque", "")))
    return out


def _observed(scene, result, w0, out, rows):
    """Fill ``out[...][rows]`` (a :func:`scene_samples` part) from a run of the scene's samples ``w0`` (an
    :class:`tumble.engine.ensemble.EnsembleResult` with its growth fit, or its trajectory), the norm curve from its
    probes when they were kept; returns the theory's value (a torque's spin-up changes it)."""
    moments, kind, a, value = scene.moments, scene.kind, scene.axis - 1, scene.value
    if kind == "exponential":  # fitted by the engine (on the device in the kernel: no norm comes back but the curve's)
        fit = analysis.growth_window_fit(result.probe_times, *result.growth)
        if result.probes is not None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns after every sample stopped
                quartiles = np.nanquantile(result.probes[:SLICE], [0.25, 0.5, 0.75], axis=0)  # as on the CPU
            out.update(norm_time=result.probe_times, norm_q1=quartiles[0], norm_median=quartiles[1],
                       norm_q3=quartiles[2])
        out["rate"][rows] = fit.rate
        for name in _GROWTH_FIT:
            out[name][rows] = getattr(fit, name)
    else:
        if result.phase is not None:  # fitted on the device, where the trajectory stayed
            fit = analysis.PhaseFit(*result.phase)
        else:
            b, c = scene.plan.plane or ((a + 1) % 3, (a + 2) % 3)
            weights = analysis.invariant_weights(moments, scene.axis)[[b, c]] if kind == "periodic" else np.ones(2)
            fit = analysis.oscillation_frequencies(result.times, result.trajectory[..., [b, c]], weights, scene.spin)
        out["rate"][rows] = fit.frequency
        out["radius"][rows] = fit.radius
        if scene.spin_up is not None:
            value = _spin_up_rate(scene.spin_up, scene.value, scene.spin, result.times)
    out["code"][rows] = np.where(result.status != STATUS_OK, result.status,
                                 np.where(fit.code != analysis.FIT_OK, fit.code + _FIT_OFFSET, 0))
    if scene.flips:
        stats = analysis.flip_statistics(result.flips)
        out["flip_first"][rows], out["flip_spacing"][rows] = stats.first, stats.spacing
        out["flip_exact"][rows] = exact.flip_spacing(moments, w0)
        out["flip_asymptote"][rows] = theory.flip_time_asymptote(moments, w0)
    return value


def stepping_samples_on_device(scenes, start, stop):
    """:func:`scene_samples` of fixed-step scenes on the device, many scenes a launch
    (:func:`tumble.engine.ensemble.run_scene_table`): a scan's scenes, each too small to fill a GPU, run in batches
    of up to :data:`tumble.engine.device.LAUNCH_SAMPLES` samples of scenes that store or probe as many times; the
    parts are the same bits as scene by scene.

    Parameters
    ----------
    scenes : list of Scene
        :func:`scene_plan` results with ``device == "cuda"``, a fixed-step method, the same ``samples`` and method,
        flips and torque, and no norm curve (whose probes a launch does not keep).
    start, stop : int
        The sample range of every scene (as :func:`scene_samples`).
    """
    parts = [_empty_part(scene, start, stop) for scene in scenes]
    groups = {}
    for k, scene in enumerate(scenes):
        plan = scene.plan
        n, every = plan.n_steps, plan.save_every
        stored = len(plan.probe_times) if scene.kind == "exponential" else 1 + n // every + (n % every > 0)
        key = (scene.kind == "exponential", stored, scene.chosen, scene.flips, repr(scene.torque))
        groups.setdefault(key, []).append(k)
    size = stop - start
    per_launch = max(1, LAUNCH_SAMPLES // size)
    for (growth, *_), members in groups.items():
        for lo in range(0, len(members), per_launch):
            _stepping_batch([scenes[k] for k in members[lo:lo + per_launch]],
                            [parts[k] for k in members[lo:lo + per_launch]], growth, start, stop)
    return parts


def _stepping_batch(scenes, parts, growth, start, stop):
    """Run the samples ``[start, stop)`` of ``scenes`` (see :func:`stepping_samples_on_device`) in one launch."""
    first, plans = scenes[0], [scene.plan for scene in scenes]
    w0 = [drawn_spins(s.moments, s.axis, s.spin, s.amplitude, s.entropy, s.distribution, start, stop) for s in scenes]
    phase = None
    if not growth:  # fitted on the device, where the trajectories stay
        windows = [analysis.phase_window(s.moments, s.axis, s.kind, s.plan.plane, s.spin) for s in scenes]
        phase = (np.array([wi[0] for wi in windows]), np.array([wi[1] for wi in windows]),
                 np.array([wi[2] for wi in windows]), windows[0][3])
    results = run_scene_table(
        first.chosen, np.stack([s.moments for s in scenes]), np.concatenate(w0), [stop - start] * len(scenes),
        np.array([p.t_end for p in plans]), np.array([p.dt for p in plans]), axis=np.array([s.axis for s in scenes]),
        save_every=None if growth else np.array([p.save_every for p in plans]),
        probe_times=np.stack([p.probe_times for p in plans]) if growth else None,
        norm_weights=np.stack([p.weights for p in plans]) if growth else None, max_flips=first.flips,
        stop_norm=np.array([p.saturation for p in plans]) if growth else None, torque=first.torque,
        growth_window=(np.array([p.saturation for p in plans]), analysis.MIN_POINTS) if growth else None,
        phase_window=phase)
    for scene, part, result, spins in zip(scenes, parts, results, w0):
        value = _observed(scene, result, spins, part, slice(0, stop - start))
        info = result.info
        part.update(sample_steps_computed=np.int64(info["sample_steps_computed"]),
                    sample_steps_skipped=np.int64(info["sample_steps_skipped"]), rate_theory=np.float64(value),
                    path=np.array(info["path"]), torque=np.array(info["torque"]))


def _empty_part(scene, start, stop):
    n = stop - start
    out = {"start": np.int64(start), "rate": np.empty(n), "code": np.empty(n, dtype=np.int8)}
    out.update((name, np.empty(n)) for name in (_GROWTH_FIT if scene.kind == "exponential" else ("radius",)))
    out.update((name, np.full(n, np.nan)) for name in (_FLIP_ARRAYS if scene.flips else ()))
    return out


def _observation_grid(scene):
    """The times the closed form evaluates a scene at: its probe times (exponential) or stored times."""
    plan = scene.plan
    if scene.kind == "exponential":
        return observation_times(plan.t_end, plan.dt, probe_times=plan.probe_times)[2]
    return observation_times(plan.t_end, plan.dt, save_every=plan.save_every)[0]


def closed_form_samples(scenes, start, stop):
    """:func:`scene_samples` of torque-free scenes run in closed form, many scenes at once.

    The samples of every scene go through one set-up (:func:`tumble.physics.exact.solve_rows`), one kernel call
    (:func:`tumble.physics.exact.omega_rows`, each scene on its own time grid) and one call of each estimator,
    in batches of at most :data:`SLICE` samples of scenes with the same kind and number of times: a scan pays
    no per-scene kernel launch or estimator call. Each sample's arithmetic is the one it gets alone, so the
    parts are the same bits as scene by scene (``scene_samples`` of a closed-form scene is this with one scene).

    Parameters
    ----------
    scenes : list of dict
        :func:`scene_plan` results with ``chosen == "exact"`` and the same ``samples``.
    start, stop : int
        The sample range of every scene (as :func:`scene_samples`).

    Returns
    -------
    list of dict
        One part per scene, as :func:`scene_samples` returns it.
    """
    parts = [_empty_part(scene, start, stop) for scene in scenes]
    grids = [_observation_grid(scene) for scene in scenes]
    groups = {}
    for k, scene in enumerate(scenes):
        key = (scene.kind == "exponential", len(grids[k]), scene.flips, scene.device)
        groups.setdefault(key, []).extend((k, lo, min(lo + SLICE, stop)) for lo in range(start, stop, SLICE))
    for items in groups.values():
        batch, size = [], 0
        for item in items:
            if batch and size + item[2] - item[1] > BATCH:
                _closed_form_batch(scenes, grids, batch, parts, start)
                batch, size = [], 0
            batch.append(item)
            size += item[2] - item[1]
        _closed_form_batch(scenes, grids, batch, parts, start)
    for scene, part in zip(scenes, parts):
        part.update(sample_steps_computed=np.int64(0),
                    sample_steps_skipped=np.int64((stop - start) * scene.plan.n_steps),
                    rate_theory=np.float64(scene.value), path=np.array("closed form"),
                    torque=np.array(torque_spec(None)[3]))
    return parts


def _closed_form_batch(scenes, grids, batch, parts, start):
    """Run the sample slices ``batch`` (``(scene, lo, hi)``) of :func:`closed_form_samples` together."""
    sizes = [hi - lo for _, lo, hi in batch]
    row = np.repeat(np.arange(len(batch)), sizes)
    per_sample = [scenes[k] for k, _, _ in batch]

    def each(values):
        return np.repeat(np.asarray(values), sizes, axis=0)

    moments = each([scene.moments for scene in per_sample])
    w0 = np.concatenate([drawn_spins(scene.moments, scene.axis, scene.spin, scene.amplitude, scene.entropy,
                                     scene.distribution, lo, hi) for scene, (_, lo, hi) in zip(per_sample, batch)])
    times = np.stack([grids[k] for k, _, _ in batch])
    first = per_sample[0]
    on_device = first.device == "cuda"
    # the set-up on the host: the CPU's evaluation, and the flips' times and spacings whatever the device
    sol = exact.solve_rows(moments, w0) if first.flips or not on_device else None
    if on_device and first.kind != "exponential":  # evaluated and phase-fitted on the device (below)
        omega = None
    elif on_device:  # set-up and time grids on the device: one launch, one thread per sample
        omega = exact.omega_rows_on_device(np.stack([scene.moments for scene in per_sample]), w0, times, row)
    else:
        omega = exact.omega_rows(sol, times, row)
    if first.kind == "exponential":
        columns = each([(s.axis % 3, (s.axis + 1) % 3) for s in per_sample])
        weights = each([s.plan.weights for s in per_sample])
        probes = analysis.transverse_norms(omega, columns, np.take_along_axis(weights, columns, axis=1))
        fit = analysis.growth_rates(times, probes, each([s.plan.saturation for s in per_sample]), row=row)
        results = {"rate": fit.rate, **{name: getattr(fit, name) for name in _GROWTH_FIT}}
        if first.flips:
            spacing = exact.flip_spacings(sol)
            flips, _ = flip_times(exact.first_flips(sol), spacing, first.flips,
                                  each([s.plan.t_end for s in per_sample]))
            stats = analysis.flip_statistics(flips)
            results.update(flip_first=stats.first, flip_spacing=stats.spacing, flip_exact=spacing,
                           flip_asymptote=theory.flip_asymptote_from(moments, w0, sol.kc))
    else:
        planes = [s.plan.plane or (s.axis % 3, (s.axis + 1) % 3) for s in per_sample]
        b, c = each(planes).T
        weights = each([analysis.invariant_weights(s.moments, s.axis)[list(plane)] if s.kind == "periodic"
                        else np.ones(2) for s, plane in zip(per_sample, planes)])
        if omega is None:  # on the device: the states stay there, only the fits come back
            fit = analysis.closed_form_frequencies_on_device(np.stack([scene.moments for scene in per_sample]), w0,
                                                             times, weights, each([s.spin for s in per_sample]),
                                                             columns=np.stack([b, c], axis=1), row=row)
        else:
            fit = analysis.oscillation_frequencies(times, omega, weights, each([s.spin for s in per_sample]),
                                                   columns=np.stack([b, c], axis=1), row=row)
        results = {"rate": fit.frequency, "radius": fit.radius}
    code = np.where(fit.code != analysis.FIT_OK, fit.code + _FIT_OFFSET, 0)
    offset = 0
    for (k, lo, hi), size in zip(batch, sizes):
        rows, into = slice(offset, offset + size), slice(lo - start, hi - start)
        part, scene = parts[k], scenes[k]
        for name, values in results.items():
            part[name][into] = values[rows]
        part["code"][into] = code[rows]
        if lo == 0 and "norm" in scene.curves and scene.kind == "exponential":
            quartiles = np.nanquantile(probes[rows], [0.25, 0.5, 0.75], axis=0)
            part.update(norm_time=times[row[offset]], norm_q1=quartiles[0], norm_median=quartiles[1],
                        norm_q3=quartiles[2])
        offset += size


def scene_result(scene, parts):
    """The dataset of :func:`measure` from the :func:`scene_samples` ranges of a scene (in any order, together
    covering every sample once): per-sample arrays concatenated, the scene's values computed from them once."""
    return scene_dataset(scene_records([scene], [parts])[0])


def _joined(scene, parts):
    """The per-sample arrays of a scene's ranges, checked and concatenated, and the ranges' scalars."""
    parts = sorted(parts, key=lambda part: int(part["start"]))
    samples = scene.samples
    covered = 0
    for part in parts:
        if int(part["start"]) != covered:
            raise ValueError(f"the sample ranges of a scene of {samples} samples do not follow each other: one "
                             f"starts at {int(part['start'])}, expected {covered}")
        covered += len(part["rate"])
    if covered != samples:
        raise ValueError(f"the sample ranges of a scene of {samples} samples end at {covered}")
    growth = scene.kind == "exponential"
    names = ("rate", "code", *(_GROWTH_FIT if growth else ("radius",)), *(_FLIP_ARRAYS if scene.flips else ()))
    joined = {name: np.concatenate([part[name] for part in parts]) for name in names}
    joined.update(computed=sum(int(part["sample_steps_computed"]) for part in parts),
                  skipped=sum(int(part["sample_steps_skipped"]) for part in parts),
                  value=float(parts[0]["rate_theory"]), path=str(parts[-1]["path"]), torque=str(parts[-1]["torque"]))
    if "norm_time" in parts[0]:
        joined["norm"] = tuple(parts[0][f"norm_{name}"] for name in ("time", "q1", "median", "q3"))
    return joined


def _medians(values, mask):
    """Median over the samples of each row where ``mask`` (and the value is finite); NaN for none."""
    return analysis.medians(np.where(mask, values, np.nan))


def scene_records(scenes, parts):
    """The scene records of :func:`scene_plan` results from their :func:`scene_samples` ranges.

    A record is a flat dict of NumPy values — every variable, coordinate and attribute (``@name``) of the scene's
    dataset (:func:`scene_dataset`), nothing else — so that it pickles, checkpoints as plain arrays, and a scan is
    assembled from records in one pass (:func:`assemble_scan`). The statistics over samples (median, interval,
    spread, fit window, flips) of all scenes of one kind are computed in one vectorised call each: the same bits
    as one scene at a time.

    Parameters
    ----------
    scenes : list of dict
        :func:`scene_plan` results.
    parts : list of list of dict
        For each scene, its ranges (together covering every sample once).
    """
    joined = [_joined(scene, ranges) for scene, ranges in zip(scenes, parts)]
    groups = {}
    for i, scene in enumerate(scenes):
        groups.setdefault((scene.kind, scene.flips > 0, scene.samples), []).append(i)
    records = [None] * len(scenes)
    for (kind, flipping, _), members in groups.items():
        stacked = {name: np.stack([joined[i][name] for i in members]) for name in joined[members[0]]
                   if isinstance(joined[members[0]][name], np.ndarray)}
        code = stacked["code"]
        valid = code == 0
        rate = np.where(valid, stacked["rate"], np.nan)
        summary = analysis.summarize(rate, confidence=CONFIDENCE)
        extras = _GROWTH_FIT if kind == "exponential" else ("radius",)
        medians = {name: _medians(stacked[name], valid) for name in extras}
        flips = None
        if flipping:
            ok = (code == 0) | (code > _FIT_OFFSET)  # flips need a sound trajectory, not a successful rate fit
            first, spacing = stacked["flip_first"], stacked["flip_spacing"]
            has_spacing = ok & np.isfinite(spacing)
            with np.errstate(invalid="ignore", divide="ignore"):
                spacing_error = np.abs(spacing / stacked["flip_exact"] - 1.0)
            worst = np.where(has_spacing, spacing_error, -np.inf).max(axis=1)
            flips = {"first": _medians(first, ok), "asymptote": _medians(stacked["flip_asymptote"], ok),
                     "spacing": _medians(spacing, ok), "exact": _medians(stacked["flip_exact"], ok),
                     "worst": np.where(has_spacing.any(axis=1), worst, np.nan), "timed": has_spacing.sum(axis=1),
                     "sample_first": np.where(ok, first, np.nan), "sample_spacing": np.where(ok, spacing, np.nan)}
        for j, i in enumerate(members):
            records[i] = _scene_record(scenes[i], joined[i], analysis.Summary(*(field[j] for field in summary)), rate[j],
                                       code[j], {name: m[j] for name, m in medians.items()},
                                       None if flips is None else {name: v[j] for name, v in flips.items()})
    return records


def _scene_record(scene, joined, summary, rate, code, medians, flips):
    """The record (see :func:`scene_records`) of one scene from its joined arrays and statistics."""
    moments, axis, spin, amplitude = scene.moments, scene.axis, scene.spin, scene.amplitude
    kind, plan, value = scene.kind, scene.plan, joined["value"]
    if summary.used == 0:
        counts = np.bincount(code, minlength=len(SAMPLE_STATUS_NAMES))
        warnings.warn(f"no sample of the scene (axis {axis}, amplitude {amplitude}) gave a rate; statuses: "
                      + ", ".join(f"{SAMPLE_STATUS_NAMES[k]} {n}" for k, n in enumerate(counts) if n),
                      RuntimeWarning, stacklevel=4)
    theory_scale = value if value > 0 else abs(spin)
    record = {"rate": summary.median, "rate_theory": value, "rel_error": abs(summary.median - value) / theory_scale,
              "kind": kind, "rate_ci_low": summary.ci_low, "rate_ci_high": summary.ci_high,
              "rate_spread": summary.spread, "samples_used": summary.used, "samples_excluded": summary.excluded,
              "sample_rate": rate, "sample_status": code, "dt": plan.dt, "t_end": plan.t_end,
              "n_steps": np.int64(plan.n_steps), "sample_steps_computed": np.int64(joined["computed"]),
              "sample_steps_skipped": np.int64(joined["skipped"]), "path": joined["path"]}
    if kind == "exponential":
        record.update({f"fit_{name}": medians[name] for name in _GROWTH_FIT}, fit_saturation=plan.saturation)
    else:
        record["signal_radius"] = medians["radius"]
    record["flips_timed"] = np.int64(0)
    if flips is not None:
        record.update(flip_first=flips["first"], flip_first_asymptote=flips["asymptote"], flip_spacing=flips["spacing"],
                      flip_spacing_exact=flips["exact"], flip_spacing_asymptote=2 * flips["asymptote"],
                      flip_spacing_rel_error=flips["worst"], flips_timed=np.int64(flips["timed"]),
                      sample_first_flip=flips["sample_first"], sample_flip_spacing=flips["sample_spacing"])
    kept = {"norm": joined["norm"]} if "norm" in joined else {}
    if "trace" in scene.curves:
        w_trace = drawn_spins(moments, axis, spin, amplitude, scene.entropy, scene.distribution, 0, 1)
        kept["trace"] = _trace(moments, w_trace, plan, scene.chosen, scene.torque, scene.device)
    record.update(_curves(kept, scene.curves))
    record.update(I1=moments[0], I2=moments[1], I3=moments[2], axis=np.int64(axis), spin=spin, amplitude=amplitude,
                  method=scene.method, sample=np.arange(scene.samples, dtype=np.int64))
    if "trace" in scene.curves:
        record["component"] = np.array([1, 2, 3])
    record.update({"@title": f"tumble measurement: {kind} rate about axis {axis}", "@method_run": scene.chosen,
                   "@samples": scene.samples, "@seed_entropy": str(scene.entropy),
                   "@distribution": scene.distribution, "@median_interval": INTERVAL_TEXT,
                   "@source": f"tumble {__version__}"})
    if scene.spin_up is not None:
        record["@torque"] = joined["torque"]
    return {name: np.asarray(v) for name, v in record.items()}


def _axial_spin_up(torque, moments, a, kind, spin):
    """``None`` when torque-free, else the scene's spin-up: profile, time scale and gain ``N_a / I_a``."""
    torque_kind, params, fn, _ = torque_spec(torque)
    if params is None and fn is None:
        return None
    if fn is not None:
        raise ValueError("measure takes a torque as three numbers or a named profile; a torque function belongs "
                         "to tumble.integrate (linear theory cannot be stated for it)")
    if kind != "periodic":
        raise ValueError(f"measure compares a torqued scene with linear theory only about a stable axis (periodic); "
                         f"axis {a + 1} is {kind}")
    others = [i for i in range(3) if i != a]
    if params[others].any():
        raise ValueError(f"measure compares with linear theory for a torque about the spin axis only; torque "
                         f"components {[i + 1 for i in others]} must be 0, got {params[:3].tolist()}")
    profile = registry.TORQUE_PROFILES[torque_kind].name
    return {"profile": profile, "tau": float(params[3]), "gain": float(params[a]) / moments[a]}


def _spin_up_integrals(spin_up, t):
    return theory.profile_integrals(spin_up["profile"], spin_up["tau"], t)


def _spin_up_rate(spin_up, value, spin, times):
    """Linear theory's rate of a torqued periodic scene: the least-squares slope of its phase over ``times``."""
    first, second = _spin_up_integrals(spin_up, times)
    spin_now = spin + spin_up["gain"] * first
    if np.any(np.sign(spin_now) != np.sign(spin)):
        raise ValueError("the torque reverses the spin within the horizon; linear theory about a steady spin does "
                         "not apply (shorten the horizon or weaken the torque)")
    phase = (value / abs(spin)) * np.sign(spin) * (spin * times + spin_up["gain"] * second)
    return float(np.polyfit(times, phase, 1)[0])


def _trace(moments, w0, plan, method, torque, device="cpu"):
    """``(times, omega (T, 3))`` of one sample over the scene's horizon, about :data:`TRACE_POINTS` points."""
    if method == "exact":
        # The set-up and the grid kernel apart, which the scene's samples have loaded already: the fused one-call
        # kernel of exact.omega (the same bits) would be one more to compile, 7 s on the first run after an install.
        times = np.linspace(0.0, plan.t_end, TRACE_POINTS)
        return times, exact.omega_apart(moments, w0, times)[0]
    every = max(1, -(-plan.n_steps // TRACE_POINTS))
    ds = integrate(moments, w0, plan.t_end, plan.dt, method=method, torque=torque, save_every=every, device=device)
    return ds.time.values, ds.omega.values[0]


def _curves(kept, curves):
    """Values of the kept curves (NaN where the scene has none, so that scans stack)."""
    out = {}
    if "norm" in curves:
        nan = np.full(PROBES + 1, np.nan)
        times, q1, median, q3 = kept.get("norm", (nan, nan, nan, nan))
        out.update(growth_time=times, growth_norm=median, growth_norm_q1=q1, growth_norm_q3=q3)
    if "trace" in curves:
        times, omega = kept["trace"]
        n = TRACE_POINTS + 2  # fixed length (NaN padded), so that scenes of a scan stack
        t_pad, w_pad = np.full(n, np.nan), np.full((n, 3), np.nan)
        t_pad[:len(times)], w_pad[:len(times)] = times, omega
        out.update(trace_time=t_pad, trace_omega=w_pad)
    return out


def _var(value, units, long_name, dims=(), **attrs):
    import xarray as xr

    return xr.Variable(dims, value, {"units": units, "long_name": long_name, **attrs})


#: Stored times of an invariant-drift record (:func:`invariant_drift`).
DRIFT_POINTS = 200


def invariant_drift(body, axis, spin=1.0, amplitude=1e-3, methods=tuple(STEPPING), *, samples=16, seed=0,
                    horizon=None, dt=None):
    # size: a public call: the scene's options and the methods to compare
    """How each fixed-step method keeps the invariants ``|L|²`` and kinetic energy over a scene's horizon.

    Every method integrates the same ``samples`` spins (torque-free) with its own step (from its order,
    :data:`STEPS_PER_RADIAN`, unless ``dt`` is given) to the same :data:`DRIFT_POINTS` + 1 times.

    Returns
    -------
    xarray.Dataset
        ``drift_l2(drift_method, drift_time)`` and ``drift_energy(drift_method, drift_time)``: the largest
        relative error ``|X(t)/X(0) − 1|`` over the samples; ``drift_dt(drift_method)``.
    """
    import xarray as xr

    moments, axis, spin, amplitude, samples, _ = _validate_scene(body, axis, spin, amplitude, samples, "auto", 0,
                                                                 "cone")
    methods = [_check_method(m) for m in methods]
    if not methods or any(m in ("auto", "exact") for m in methods):
        raise ValueError(f"methods must be fixed-step methods ({', '.join(STEPPING)}), got {methods!r}")
    kind, value = theory.linear(moments, axis, spin)
    w0 = perturbed_spins(moments, axis, spin, amplitude, samples, seed=seed)
    t_end = horizon or _plan(moments, axis - 1, kind, value, spin, amplitude, "exact", None,
                             2 if kind == "exponential" else 0, lambda: w0).t_end
    l2_0 = np.sum((moments * w0) ** 2, axis=1)[:, None]
    e_0 = np.sum(moments * w0**2, axis=1)[:, None]
    l2, energy, steps = [], [], []
    for m in methods:
        step = dt or min(1.0 / value if value > 0 else 1.0 / abs(spin), 1.0 / abs(spin)) / STEPS_PER_RADIAN[
            registry.method(m).order]
        every = max(1, math.ceil(t_end / step / DRIFT_POINTS))
        ds = integrate(moments, w0, t_end, t_end / (every * DRIFT_POINTS), method=m, save_every=every)
        w = ds.omega.values
        with np.errstate(invalid="ignore", over="ignore"):
            l2.append(np.abs(np.sum((moments * w) ** 2, axis=2) / l2_0 - 1).max(axis=0))
            energy.append(np.abs(np.sum(moments * w**2, axis=2) / e_0 - 1).max(axis=0))
        steps.append(ds.attrs["dt"])
    dims = ("drift_method", "drift_time")
    return xr.Dataset(
        {"drift_l2": _var(np.array(l2), "1", "largest relative |L|^2 error over the samples", dims),
         "drift_energy": _var(np.array(energy), "1", "largest relative kinetic-energy error over the samples",
                              dims),
         "drift_dt": _var(np.array(steps), "s", "time step of each method", ("drift_method",))},
        coords={"drift_method": _var(np.array(methods), "1", "integration method", ("drift_method",)),
                "drift_time": _var(np.linspace(0.0, t_end, DRIFT_POINTS + 1), "s", "time", ("drift_time",))},
        attrs={"drift_samples": samples})


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
    """
    if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1 (points along each side of the triangle), got {n!r}")
    mid = (np.arange(n) + 0.5) / n
    s, u = np.meshgrid(0.5 + 0.5 * mid, mid, indexing="ij")
    i1 = (1.0 - s) + u * (2.0 * s - 1.0)
    moments = np.stack([i1.ravel(), s.ravel(), np.ones(n * n)], axis=1)
    return moments, {"i2_over_i3": s.ravel(), "i1_fraction": u.ravel()}


_SCAN_DIMS = ("axis", "spin", "amplitude", "method")


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
    return ScenePlanner(layout, samples=samples, seed=seed, **options)(index)


class ScenePlanner:
    """:func:`scan_scene` of any scene of a layout, the scan's shared options and each combination of its swept
    values checked once rather than once per scene (half the time of planning a 30 000-scene map went to checking
    the same options again); the same :class:`Scene` records as :func:`scene_plan`, and the same errors, raised when
    the first scene that needs the value is planned."""

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
            self._checked[key] = _validate_scene(moments, *values[:3], self.samples, values[3], self._flips,
                                                 distribution)[1:]
        if self._shared is None:
            self._shared = _scene_options(self.seed, **self._options)
        axis, spin, amplitude, samples, flips = self._checked[key]
        return _planned_scene(moments, axis, spin, amplitude, samples, params["method"], flips, self._shared)


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

    Notes
    -----
    Closed-form scenes run in batches (:func:`scene_batch`). The same scan cut into chunks of scenes:
    :func:`scan_layout`, :func:`scan_scene`, :func:`scene_batch`, :func:`assemble_scan` (what ``tumble run``
    does to checkpoint a scan and to run it on a dask cluster).
    """
    layout = scan_layout(bodies, axis, spin, amplitude, method)
    n = layout["scenes"]
    if isinstance(samples, (int, np.integer)) and not isinstance(samples, (bool, np.bool_)) and samples >= 1:
        # before any scene is planned: every scene's per-sample arrays are kept (and stacked once more)
        cost.refuse(scene_estimate(False, False, int(samples), PROBES + 1, scenes=n, kept_per_sample=_SCAN_KEPT),
                    f"{n:,} scenes of samples = {samples}")
    progress = options.pop("progress", None)
    show = sys.stderr.isatty() if progress is None else progress
    planner = ScenePlanner(layout, samples=samples, seed=seed, **options)
    plans = [planner(index) for index in range(n)]
    steps = sum(plan.plan.n_steps for plan in plans if plan.chosen != "exact")
    cost.refuse(cost.scene_cost(samples, steps / n, scenes=n, working=0),
                f"{n:,} scenes of samples = {samples} ({steps:,} steps in all)", options.get("device", "cpu"))
    records = []
    step = max(1, math.ceil(len(plans) / 32))
    with tqdm(total=len(plans), unit="scenes", disable=not show, desc="scan") as bar:
        for lo in range(0, len(plans), step):
            records += scene_batch(plans[lo:lo + step])
            bar.update(len(plans[lo:lo + step]))
    return assemble_scan(layout, records, body_coords)


def regress_scan(ds):
    """Measured rate against theory over a scan, per kind: slope, intercept, R², worst point.

    Parameters
    ----------
    ds : xarray.Dataset
        From :func:`scan` (or one :func:`measure`).

    Returns
    -------
    xarray.Dataset
        Dimension ``kind`` (the kinds present, neutral excluded: its theory is 0); variables ``slope``,
        ``intercept``, ``r2``, ``median_rel_error``, ``worst_rel_error``, ``points``, and the worst point's
        ``rate``, ``rate_theory`` and scan coordinates.
    """
    import xarray as xr

    rows = []
    for kind in ("periodic", "exponential"):
        mask = ds["kind"] == kind
        if not bool(mask.any()):
            continue
        theory_values = ds["rate_theory"].where(mask).values.ravel()
        measured = ds["rate"].where(mask).values.ravel()
        fit = analysis.regression(theory_values, measured)
        worst = {}
        if fit.worst >= 0:
            point = ds[["rate", "rate_theory"]][dict(zip(ds["rate"].dims, np.unravel_index(fit.worst,
                                                                                          ds["rate"].shape)))]
            for name, variable in [*point.data_vars.items(), *point.coords.items()]:
                if variable.ndim == 0:
                    worst[f"worst_{name}"] = ((), variable.values.item(),
                                              {"units": KIND_UNITS[kind] if name.startswith("rate")
                                               else variable.attrs.get("units", "1"),
                                               "long_name": f"{name} of the scene with the largest error"})
        rel = ds["rel_error"].where(mask).values
        rows.append(xr.Dataset({
            "slope": ((), fit.slope, {"units": "1", "long_name": "slope of measured rate against theory"}),
            "intercept": ((), fit.intercept, {"units": KIND_UNITS[kind], "long_name": "intercept"}),
            "r2": ((), fit.r2, {"units": "1", "long_name": "coefficient of determination"}),
            "median_rel_error": ((), float(np.nanmedian(rel)), {"units": "1",
                                                                "long_name": "median relative error over scenes"}),
            "worst_rel_error": ((), fit.worst_error, {"units": "1", "long_name": "largest relative error"}),
            "points": ((), np.int64(fit.points), {"units": "1", "long_name": "scenes in the fit"}),
            **worst,
        }).expand_dims(kind=[kind]))
    if not rows:
        raise ValueError("the dataset holds no periodic or exponential scene to regress")
    return xr.concat(rows, dim="kind", combine_attrs="override") if len(rows) > 1 else rows[0]


def flip_time_law(ds):
    """The flip-time law over an amplitude scan: first-flip time against ``ln(1/ε)``, slope against ``1/λ``.

    Near the separatrix the first flip comes at ``(1/λ) ln(4/k')`` and ``k' ∝ ε``, so the median first-flip
    time is linear in ``ln(1/ε)`` with slope ``1/λ``.

    Parameters
    ----------
    ds : xarray.Dataset
        A :func:`scan` with an ``amplitude`` dimension (at least two amplitudes) of exponential scenes timed
        with ``flips > 0``.

    Returns
    -------
    xarray.Dataset
        ``slope`` (s), ``slope_theory = 1/rate_theory`` (s), ``rel_error``, ``intercept`` (s), ``r2``, over the
        scan's other dimensions.
    """
    import xarray as xr

    if "amplitude" not in ds.dims or ds.sizes["amplitude"] < 2:
        raise ValueError("the flip-time law needs a scan over at least two amplitudes (an 'amplitude' dimension)")
    if "flip_first" not in ds:
        raise ValueError("the dataset has no flip times: scan exponential scenes with flips > 0")
    x = np.log(1.0 / ds["amplitude"])

    def fit(times, xs):
        r = analysis.regression(xs, times)
        return np.array([r.slope, r.intercept, r.r2])

    out = xr.apply_ufunc(fit, ds["flip_first"], x, input_core_dims=[["amplitude"], ["amplitude"]],
                         output_core_dims=[["fit"]], vectorize=True)
    theory_slope = 1.0 / ds["rate_theory"].isel(amplitude=0, drop=True)
    result = xr.Dataset({
        "slope": out.isel(fit=0, drop=True).assign_attrs(units="s", long_name="d(first flip time)/d ln(1/amplitude)"),
        "intercept": out.isel(fit=1, drop=True).assign_attrs(units="s", long_name="intercept"),
        "r2": out.isel(fit=2, drop=True).assign_attrs(units="1", long_name="coefficient of determination"),
        "slope_theory": theory_slope.assign_attrs(units="s", long_name="1 / linear growth rate"),
    })
    result["rel_error"] = (abs(result["slope"] - result["slope_theory"]) / result["slope_theory"]).assign_attrs(
        units="1", long_name="|slope - 1/lambda| / (1/lambda)")
    return result.drop_vars([c for c in result.coords if c not in result.dims and c != "method"], errors="ignore")


#: Stored times of the attitude trace (the flip animation, strip, polhode and herpolhode figures).
ATTITUDE_POINTS = 1200
#: Steps per turn of the fastest component when a fixed-step method traces the attitude.
_ATTITUDE_STEPS_PER_TURN = 400


def _attitude_horizon(moments, w0, axis):
    """Three flips about the intermediate axis, else three body-frame periods (three turns for a steady spin)."""
    spacing = float(exact.flip_spacing(moments, w0))
    if axis - 1 == int(np.argsort(moments, kind="stable")[1]) and np.isfinite(spacing):
        return float(exact.first_flip_time(moments, w0)) + 2.5 * spacing
    period = float(exact.period(moments, w0))
    return 3.0 * (period if np.isfinite(period) else 2.0 * math.pi / float(np.linalg.norm(w0)))


def attitude_trace(body, axis=2, spin=1.0, amplitude=1e-3, method="auto", *, horizon=None, seed=0, torque=None,
                   shape="", shape_parameters=None, points=ATTITUDE_POINTS):
    # size: a public call: the scene's options and the shape to draw
    """The orientation of one perturbed spin in space, as the attitude figures read it.

    The spin is sample 0 of :func:`tumble.engine.sampling.perturbed_spins` (the same seed gives the same spin as a
    scene's first sample). Torque-free with ``method="auto"`` the closed form runs
    (:func:`tumble.physics.exact.attitude`); otherwise ``method`` (``rk4`` when ``"auto"``) steps the angular
    velocity and the attitude together (:mod:`tumble.kernels.attitude`), about 400 steps per turn.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
    axis, spin, amplitude
        The unperturbed spin (1-based axis, rad/s) and the tilt, rad.
    method : str
        ``"auto"``, ``"exact"`` or a fixed-step method.
    horizon : float, optional
        Time span, s; default three flips about the intermediate axis (the first flip time plus 2.5 flip
        spacings), else three periods of the body-frame motion.
    torque : optional
        As :func:`tumble.integrate`.
    shape, shape_parameters : str, mapping
        The :mod:`tumble.physics.shapes` function the body came from and its arguments, for drawing it.
    points : int
        Stored times (about; the fixed-step path stores every k-th step).

    Returns
    -------
    xarray.Dataset
        ``attitude_quaternion(attitude_time, quaternion_component)`` (body-to-space, scalar first; the
        space frame is the body frame at t = 0), ``attitude_omega(attitude_time, component)`` (rad/s) and
        ``attitude_moments(component)`` (kg m²); ``component`` is the principal axis (1, 2, 3), as in
        ``trace_omega``.
    """
    import xarray as xr

    moments = one_body(body)
    w0 = perturbed_spins(moments, axis, spin, amplitude, 1, seed=seed)
    _, params, fn, _ = torque_spec(torque)
    torque_free = params is None and fn is None
    chosen, _ = registry.choose_method(method, torque_free=torque_free)
    t_end = float(horizon) if horizon is not None else _attitude_horizon(moments, w0[0], axis)
    if chosen == "exact":
        ds = integrate(moments, w0, t_end, t_end / (points - 1), method="exact", save_every=1, attitude=True)
    else:
        dt = 2.0 * math.pi / (_ATTITUDE_STEPS_PER_TURN * float(np.abs(w0).max()))
        n_steps = max(1, math.ceil(t_end / dt))
        ds = integrate(moments, w0, t_end, t_end / n_steps, method=chosen, torque=torque,
                       save_every=max(1, n_steps // (points - 1)), attitude=True)
    if ds.status.values[0] != STATUS_OK:
        raise FloatingPointError(f"the attitude trace with {chosen} became non-finite; use a smaller step")
    attrs = {"units": "1", "long_name": "body-to-space rotation of the traced spin, unit quaternion, scalar first",
             "method": chosen, "spin_axis": int(axis), "body_shape": shape or "",
             "body_shape_json": json.dumps(dict(shape_parameters or {}), sort_keys=True)}
    return xr.Dataset(
        {"attitude_quaternion": (("attitude_time", "quaternion_component"), ds.quaternion.values[0], attrs),
         "attitude_omega": (("attitude_time", "component"), ds.omega.values[0],
                            {"units": "rad/s", "long_name": "body-frame angular velocity of the traced spin"}),
         "attitude_moments": ("component", moments, {"units": "kg m2", "long_name": "principal moments of inertia"})},
        coords={"attitude_time": ("attitude_time", ds.time.values, {"units": "s", "long_name": "time"}),
                "quaternion_component": ("quaternion_component", np.arange(4),
                                         {"long_name": "quaternion component (0: scalar part)"}),
                "component": ("component", np.array([1, 2, 3]), {"long_name": "principal axis (1-based)"})})
