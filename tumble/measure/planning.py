"""A scene validated and planned: what is computed and why, and what it costs, as plain records.

A *scene* is an ensemble of spins about one principal axis of one body, perturbed by a small tilt
(:func:`tumble.measure.scene.measure`). :func:`scene_plan` checks its arguments once and freezes them with the plan
into a :class:`Scene` record (its :class:`StepPlan`: horizon, step, observation times), which pickles (dask,
checkpoints) and is read, never changed, by every later step: :mod:`tumble.measure.running` runs its samples,
:mod:`tumble.measure.reduction` reduces them.

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
  :data:`tumble.engine.sampling.CHUNK` (:func:`tumble.measure.running.scene_samples`: per-sample fits only, in any
  process) and the ranges are reduced once (:func:`tumble.measure.reduction.scene_result`: median, confidence
  interval, fit window and flip medians over all the samples) — the same bits as the whole scene; ``tumble run``
  cuts large scenes this way.

The cost of a scene (:func:`scene_estimate`) is checked against :mod:`tumble.engine.cost`'s bound before any kernel
loads (:func:`refuse_plan`); a torque about the spin axis is planned as a spin-up (:func:`spin_up_rate`), its sine or
pulse resolved by the planned step (:func:`check_torque_step`). A planned scene's method, device, torque and cost are
checked here once: its samples run unchecked (:func:`tumble.engine.ensemble.run_planned`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import registry
from ..engine import cost
from ..engine.ensemble import torque_spec
from ..engine.sampling import CHUNK, drawn_spins, perturbed_spins, seed_entropy
from ..physics import exact, theory
from ..physics.bodies import one_body
from . import estimators as analysis
from .records import KIND_UNITS

__all__ = ["BATCH", "CURVES", "MAX_SAVES", "MIN_FIT_SPAN", "PERIODS", "PROBES", "SATURATION", "SATURATION_TILTS",
           "SAVES_PER_PERIOD", "SLICE", "STEPS_PER_RADIAN", "Scene", "StepPlan", "TorqueStepError", "check_amplitude",
           "check_fit_span", "check_method", "check_torque_step", "planned_scene", "refuse_plan", "scene_estimate",
           "scene_options", "scene_plan", "spin_up_rate", "step_plan", "validate_scene"]


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
#: slices of 257 times (``tests/test_memory.py``; the stepping exponential scene's again on 2026-12-06 with a warm
#: cache, 132 to 152 MB for 131072 samples in two environments). A stepping periodic scene keeps its trajectory and
#: copies of two of its components for the phase fit; a stepping exponential scene keeps only the probe norms.
_BYTES_PER_TIME = {(False, True): 28, (False, False): 22, (True, True): 9, (True, False): 52}

#: Bytes per sample of a scene while its slices are reduced (the per-sample fits, their stack and the record).
_BYTES_PER_REDUCED_SAMPLE = 200


def scene_estimate(stepping, exponential, samples, times, *, steps=0, flips=0, scenes=1, kept_per_sample=0):
    # size: the quantities the planner knows (or a study's estimate of them), each a factor of the cost
    """:class:`tumble.engine.cost.Cost` of ``scenes`` scenes of ``samples`` samples observed at ``times`` times
    over ``steps`` fixed steps (``stepping``; else the closed form) with ``flips`` flips timed, keeping
    ``kept_per_sample`` bytes per sample and scene: the working set of one slice of samples (:data:`SLICE`;
    closed-form scenes run together in batches of :data:`BATCH`) from :data:`_BYTES_PER_TIME`, the scene's
    reduction and what is kept; its time counts each sample's steps or closed-form evaluations at the ``times`` and its
    fit over them. ``exponential`` False: a periodic (or possibly periodic) scene."""
    in_flight = min(samples if stepping else max(samples, min(BATCH, scenes * samples)), SLICE)
    working = (float(in_flight) * (float(times) * _BYTES_PER_TIME[(bool(stepping), bool(exponential))]
                                   + 32.0 * flips) + float(samples) * _BYTES_PER_REDUCED_SAMPLE)
    return cost.scene_cost(samples, steps if stepping else 0, scenes=scenes, kept_per_sample=kept_per_sample,
                           working=working, times=times, fits=True)  # its time: every sample evaluated and fitted


def refuse_plan(samples, plan, stepping, exponential, flips, device="cpu"):
    """Refuse a planned scene past the cost bound (:func:`tumble.engine.cost.refuse`), naming what set its size."""
    times = len(plan.probe_times) if plan.probe_times is not None else plan.n_steps // (plan.save_every or 1) + 2
    estimate = scene_estimate(stepping, exponential, samples, times, steps=plan.n_steps, flips=flips)
    steps = f"{plan.n_steps:,} steps of {plan.dt:.3g} s" if stepping else "the closed form"
    cost.refuse(estimate, f"samples = {samples} over a horizon of {plan.t_end:.3g} s ({steps}, flips = {flips})",
                device)


def check_method(method):
    if not isinstance(method, str) or method not in registry.CHOICES:
        raise ValueError(f"method must be one of {', '.join(registry.CHOICES)}; got {method!r}")
    return method


def _positive_int(value, name):
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


@dataclass(frozen=True, eq=False)
class StepPlan:
    """Horizon, step and observation times of a scene (:func:`step_plan`)."""

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


def step_plan(moments, a, kind, value, spin, amplitude, method, dt, flips, probe_spins, horizon=None, spin_max=None):
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


class TorqueStepError(ValueError):
    """A planned step that cannot resolve the scene's torque profile (:func:`check_torque_step`): its ``profile``,
    time scale ``tau`` (s, the profile's ``key``: ``"period"`` or ``"duration"``) and the planned step ``dt`` (s), so
    that a study can name its own fields (``torque.<key>``, ``integration.dt``)."""

    def __init__(self, profile, tau, dt, dt_name="dt"):
        self.profile, self.tau, self.dt = profile, tau, dt
        self.key = registry.torque_profile(profile).time
        super().__init__(f"torque.{self.key}: {registry.profile_step_problem(profile, tau, dt, dt_name)} (the step "
                         f"planned for this scene)")


def check_torque_step(spin_up, dt):
    """Refuse a scene whose planned step ``dt`` (s) cannot resolve its torque's sine or pulse
    (:func:`tumble.registry.profile_step_problem`; issue 17, cause 8): a :class:`TorqueStepError`. The one check of it
    for a planned scene (:func:`tumble.measure`, :func:`tumble.scan` and a study's scenes), which then runs unchecked
    (:func:`tumble.engine.ensemble.run_planned`). ``spin_up`` as :class:`Scene` holds it (None: torque-free)."""
    if spin_up is not None and registry.profile_step_problem(spin_up["profile"], spin_up["tau"], dt):
        raise TorqueStepError(spin_up["profile"], spin_up["tau"], dt)


def validate_scene(body, axis, spin, amplitude, samples, method, flips, distribution):
    moments = one_body(body)
    if isinstance(axis, (bool, np.bool_)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (a principal axis, 1-based), got {axis!r}")
    check_method(method)
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
    moments, axis, spin, amplitude, samples, flips = validate_scene(body, axis, spin, amplitude, samples,
                                                                     method, flips, distribution)
    options = scene_options(seed, dt=dt, distribution=distribution, torque=torque, horizon=horizon, curves=curves,
                             device=device)  # resolved by measure, the door
    return planned_scene(moments, axis, spin, amplitude, samples, method, flips, options)


def scene_options(seed, *, dt=None, distribution="cone", torque=None, horizon=None, curves=(), device="cpu"):
    """The options a scene shares with the other scenes of a scan, checked once: ``seed`` as its entropy.

    ``device`` is trusted, resolved where the run entered (:func:`tumble.engine.device.resolve_device`:
    :func:`scene_plan`, :func:`tumble.measure.scans.scan` and ``scan_scene``, a study's
    :func:`tumble.pipeline.runner.scene_job`): ``"cpu"`` or ``"cuda"``."""
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


def planned_scene(moments, axis, spin, amplitude, samples, method, flips, options):
    # size: a scene's checked quantities (validate_scene) and its scan's shared options (scene_options)
    """The :class:`Scene` of checked arguments (:func:`validate_scene`, :func:`scene_options`): the theory, the
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
    plan = step_plan(moments, a, kind, value, spin, amplitude, chosen, options["dt"], flips, probe_spins, horizon,
                 spin_max)
    check_fit_span(kind, value, plan.probe_times[-1] if kind == "exponential" else plan.t_end, horizon)
    refuse_plan(samples, plan, chosen != "exact", kind == "exponential", flips, options["device"])
    check_torque_step(spin_up, plan.dt)
    return Scene(moments=moments, axis=axis, spin=spin, amplitude=amplitude, samples=samples, method=method,
                 chosen=chosen, kind=kind, value=value, spin_up=spin_up,
                 torque=torque if spin_up is not None else None, plan=plan, flips=flips, entropy=entropy,
                 distribution=distribution, curves=options["curves"], device=options["device"])


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


def spin_up_rate(spin_up, value, spin, times):
    """Linear theory's rate of a torqued periodic scene: the least-squares slope of its phase over ``times``."""
    first, second = _spin_up_integrals(spin_up, times)
    spin_now = spin + spin_up["gain"] * first
    if np.any(np.sign(spin_now) != np.sign(spin)):
        raise ValueError("the torque reverses the spin within the horizon; linear theory about a steady spin does "
                         "not apply (shorten the horizon or weaken the torque)")
    phase = (value / abs(spin)) * np.sign(spin) * (spin * times + spin_up["gain"] * second)
    return float(np.polyfit(times, phase, 1)[0])
