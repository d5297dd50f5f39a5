"""Scenes of the models beyond the free body (issue 18): a gyrostat's or a heavy top's steady spin, perturbed, measured.

A model scene is a free-body scene (:mod:`tumble.measure.scene`) for a model of :mod:`tumble.physics.models`: an
ensemble of states near the model's steady spin (:func:`tumble.engine.sampling.perturbed_states`), stepped by the
model kernels (:func:`tumble.engine.model_ensemble.run_planned_model`: the scene's method, device and cost checked
when it was planned, not again per engine call), measured with the free body's
estimators, and reduced by the free body's :func:`tumble.measure.reduction.scene_records`, so that its record holds
the same variables (``kind``, ``rate``, ``rate_theory``, ``rel_error``, the interval, ``sample_rate``, ...) plus the
model's coordinates (``model``; ``rotor``, the rotor's angular momentum along the spin axis, N m s; ``mgl``, N m).

Planning (:func:`scene_plan`):

* kind and ``rate_theory`` from the model's linearisation, :func:`tumble.physics.theory.linear` (the largest real
  part of the Jacobian's eigenvalues, else the largest imaginary part);
* the step resolves the fastest eigenvalue (:data:`tumble.measure.planning.STEPS_PER_RADIAN`), and a heavy top's spin
  too (its up vector turns at ``w3`` in the body frame). A gyrostat's spin is no time scale of its body-frame
  motion: the transverse Jacobian ``[[0, a], [b, 0]]`` has ``J² = ab = -ν²`` (or ``λ²``), so a Runge-Kutta step,
  a polynomial in ``J dt``, is as accurate as ``ν dt`` (``λ dt``) allows, however small ``ν`` is against the spin
  near a threshold (the map's slow precessions: 16 periods at 40 steps per radian of the spin took 300 000 steps);
* exponential: the model's transverse norm (:meth:`~tumble.physics.models.Model.transverse`) is probed at
  :data:`~tumble.measure.planning.PROBES` + 1 equally spaced times up to ``2`` e-foldings past the end of the linear
  regime (the norm reaching ``SATURATION`` (1 %) of the norm of a perturbation one radian large, or
  ``SATURATION_TILTS`` times the tilt), and the growth rate is :func:`~tumble.measure.estimators.growth_rates`'
  linear-prediction fit up to that end. Near a gyrostat's threshold (``rate_theory`` small against the spin) the
  linear regime ends sooner: one factor ``(I_a - I_b) W + h`` of ``lambda²`` is small, and the second-order change of
  the spin, O(amplitude²), shifts it by a fraction O((amplitude W / lambda)²); the saturation is therefore scaled by
  ``rate_theory / |spin|`` (below 1), which brought the worst scene of a 20 x 20 x 3 map (h = 0.1 N m s) from 0.75 %
  to 4e-5. A gyrostat's weighted norm squared is a sum of a growing and a decaying
  exponential (the circular weights), as the free body's, so the fit starts at t = 0;
* periodic: states stored :data:`~tumble.measure.planning.SAVES_PER_PERIOD` times per period of ``rate_theory`` over
  :data:`PERIODS` periods; the frequency is :func:`~tumble.measure.estimators.oscillation_frequencies` of the
  transverse phase pair (a gyrostat's ``(w_b, w_c)`` with their circular weights). That estimator is
  model-agnostic (a phase's least-squares slope) — nothing of the free body in it.

A heavy top is measured in its **modal coordinate** (:class:`Mode`, :func:`mode`). Its transverse motion
``x = (w1, w2, g1, g2)`` has four modes, ``x(t) = sum_j c_j v_j exp(lambda_j t)``: two precessions ``±i nu±`` above the
threshold, a quartet ``±alpha ± i beta`` (or two real pairs) below it. No weighted norm of ``x`` makes every top's
motion a single circle or a single exponential: for an asymmetric top (``I1 != I2``) each mode is elliptical in
any fixed weights, so the squared norm of the waking mode is ``e^{2 alpha t} (A + B cos(2 beta t + phi))`` (the
growth fit, which assumes a sum of two exponentials, was 3 % off for moments (1, 2, 3)), and above the threshold the
tilt's phase follows whichever mode has the larger tilt, with two modes of comparable tilt its phase is not linear
in time at all (every sample failed the phase fit for moments (1, 2, 3) at w3 = 1.5 - 3 rad/s). The left
eigenvector ``u`` of the measured eigenvalue ``lambda`` (the largest real part, else the largest imaginary part:
``rate_theory``) of the transverse Jacobian annihilates every other mode (``u . v_j = 0``, ``j != m``), so
``z(t) = u . x(t) = c_m exp(lambda t)`` exactly in linear theory, whatever the ensemble's mix of modes and the
body's asymmetry: ``|z|^2`` is one exponential, whose rate linear prediction recovers exactly from t = 0, and the
phase of ``z`` turns uniformly at ``Im lambda``. ``u`` is scaled so that ``|z|`` is the amplitude of a mode of unit
transverse norm (rad/s). The states are stored at the probe times (exponential) or
:data:`~tumble.measure.planning.SAVES_PER_PERIOD` times a period (periodic) and projected as soon as the engine returns
(:func:`tumble.measure.estimators.modal_amplitudes`: a compiled gather, then ``matmul``). The ensemble is
that of before (the up direction tilted by ``amplitude``, the spin by ``amplitude`` x
:data:`HEAVY_TOP_SPIN_TILT`), so the sleeping top's scenes run the same samples; only their measurement changed.
Near a threshold (two eigenvalues colliding) ``u`` is ill-conditioned: the projection there amplifies the
nonlinear part of the motion, and the errors grow as the threshold is approached.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from .. import registry
from ..engine.device import LAUNCH_SAMPLES
from ..engine.model_ensemble import check_model_method, run_model_ensemble, run_planned_model
from ..engine.sampling import CHUNK, perturbed_states, seed_entropy
from ..physics import models, theory
from ..physics.models import Model
from ..registry import STATUS_OK
from . import estimators as analysis
from . import planning, reduction

__all__ = ["HEAVY_TOP_SPIN_TILT", "METHODS", "MODAL", "Mode", "ModelScene", "PERIODS", "mode", "model_of", "scan_layout",
           "flat_spin_trace", "measured_eigenvalue", "periodic_plan", "scene_batch", "scene_plan", "scene_records", "scene_samples"]

#: The model kernels' methods; ``"auto"`` is the first.
METHODS = registry.MODEL_STEPPING

#: Periods of ``rate_theory`` a periodic model scene observes. The phase the fit follows turns uniformly in linear
#: theory (a gyrostat's circular weights, a heavy top's modal coordinate), so its slope needs no long average: the
#: error is the nonlinear correction, O(amplitude²), whatever the horizon.
PERIODS = 4

#: A heavy top's spin tilt, as a fraction of its up direction's tilt (``perturbation.amplitude``): the model's own
#: :attr:`~tumble.physics.models.Model.spin_tilt`.
HEAVY_TOP_SPIN_TILT = models.HeavyTop.spin_tilt

#: Most samples per engine call (bounds the memory of stored states).
SLICE = 2 * CHUNK


@dataclass(frozen=True, eq=False)
class ModelScene:
    """One model scene, validated and planned (:func:`scene_plan`): plain data that pickles (dask, checkpoints).

    Its fields are those of :class:`tumble.measure.planning.Scene` that :func:`tumble.measure.reduction.scene_records`
    reads (no torque, no flips, no curves), plus the model and the measured mode."""

    model: Model
    moments: np.ndarray  # (3,) kg m²
    axis: int
    spin: float  # rad/s
    amplitude: float  # rad
    samples: int
    method: str  # as asked
    chosen: str  # rk4 or rk8
    kind: str  # "periodic" or "exponential"
    value: float  # rate_theory: frequency (rad/s) or growth rate (1/s)
    plan: planning.StepPlan
    entropy: int
    distribution: str
    flips: int = 0
    spin_up: None = None
    torque: None = None
    curves: tuple = field(default=())
    mode: Mode | None = None  # a modal model's measured mode (:func:`mode`), planned once for the fits
    device: str = "cpu"  # where the samples step (resolved: "cpu" or "cuda")


class Mode(NamedTuple):
    """The mode a modal scene measures (module docstring): ``z = left . (y[..., columns] - centre)``."""

    columns: np.ndarray  # (k,) int, the transverse columns of the state
    left: np.ndarray  # (k,) complex: the left eigenvector, scaled so that |z| is in rad/s (a unit-norm mode)
    eigenvalue: complex  # 1/s: its real part the growth rate, its imaginary part the frequency
    centre: np.ndarray | float = 0.0  # (k,): the equilibrium's values of the columns


#: Models measured in the modal coordinate of their measured eigenvalue (:func:`mode`): those whose class says so
#: (:attr:`tumble.physics.models.Model.modal`).
MODAL = tuple(kind for kind, cls in models.CLASSES.items() if cls.modal)


def mode(model, axis, spin, kind, *, jacobian=None):
    """The linearisation's mode that a scene of ``kind`` measures: the eigenvalue of the transverse Jacobian with the
    largest real part (``"exponential"``; of a complex pair, the one with ``Im >= 0``), else the least damped
    oscillation, the fastest of those (``"periodic"``, as :func:`tumble.physics.theory.linear` reports it; without
    damping the largest imaginary part), and its left eigenvector (:class:`Mode`).

    The transverse columns (:meth:`~tumble.physics.models.Model.mode_space`: a heavy top's ``(w1, w2, g1, g2)``; a
    gravity gradient's ``w`` and attitude error; a damper's body and sphere across the axis) must be invariant under the linearised motion (a heavy top's
    ``(w1, w2, g1, g2)``: ``w3`` and ``g3`` are constant to first order). ``jacobian``: the model's tangent Jacobian at
    this equilibrium when the caller has it (:func:`tumble.physics.theory.linearisation`)."""
    columns, rows, factor, weights = model.mode_space(axis, spin)
    equilibrium = model.equilibrium(axis, spin)
    jac = model.tangent_jacobian(equilibrium) if jacobian is None else jacobian
    lam, vectors = np.linalg.eig(jac[np.ix_(rows, rows)])
    m = measured_eigenvalue(lam, kind)
    in_columns = vectors[:, m] / factor  # the mode in the state's columns
    scale = math.sqrt(float(np.sum(weights * np.abs(in_columns) ** 2)))
    left = np.linalg.inv(vectors)[m] * factor * scale
    return Mode(columns, left, complex(lam[m]), np.asarray(equilibrium[columns], dtype=float))


def measured_eigenvalue(lam, kind):
    """The index in ``lam`` of the eigenvalue a scene of ``kind`` measures (:func:`mode`)."""
    tol = theory.EIGEN_RTOL * np.abs(lam).max()
    if kind == "exponential":
        top = lam.real.max()
        return int(np.argmax(np.where(lam.real >= top - 1e-9 * np.abs(lam).max(), lam.imag, -np.inf)))
    oscillating = lam.imag > tol
    lead = np.where(oscillating, lam.real, -np.inf).max()
    return int(np.argmax(np.where(oscillating & (lam.real >= lead - tol), lam.imag, -np.inf)))


def _scene_mode(scene):
    """The :class:`Mode` a modal scene measures: planned with it (:func:`scene_plan`), else found now."""
    return scene.mode if scene.mode is not None else mode(scene.model, scene.axis, scene.spin, scene.kind)


def _modal(scene_mode, states):
    """``z`` of states of shape (..., n) (complex, shape (...)): the measured mode's amplitude, rad/s."""
    return (states[..., scene_mode.columns] - scene_mode.centre) @ scene_mode.left


def model_of(kind, moments, axis, parameters):
    """The model ``kind`` of a scene: ``parameters`` by study key; a ``rotor`` given as a number is that angular
    momentum along ``axis`` (N m s)."""
    parameters = dict(parameters)
    rotor = parameters.get("rotor")
    if rotor is not None and np.ndim(rotor) == 0:
        vector = np.zeros(3)
        vector[axis - 1] = float(rotor)
        parameters["rotor"] = vector
    return models.from_kind(kind, moments, **parameters)


def _initial_states(scene, start, stop):
    """States ``[start, stop)`` of the scene's ensemble (see the module docstring for the heavy top's tilts)."""
    spin_tilt = scene.amplitude * scene.model.spin_tilt
    return perturbed_states(scene.model, scene.axis, scene.spin, spin_tilt, scene.samples,
                            up_amplitude=scene.amplitude, seed=scene.entropy, distribution=scene.distribution,
                            start=start, stop=stop)


def _grid(t_first, t_last, points, dt):
    """``(dt, first step, steps between points)``: ``points`` + 1 equally spaced times from about ``t_first`` to
    ``t_last``, each a whole number of steps of at most ``dt``."""
    every = max(1, math.ceil((t_last - t_first) / points / dt))
    dt = (t_last - t_first) / points / every
    return dt, math.ceil(t_first / dt - 1e-9), every


def _plan(scene_args, kind, value, y0_norms, dt, horizon, eigenvalues=None):
    """The :class:`~tumble.measure.planning.StepPlan` of a model scene (horizon, step, observation times);
    ``eigenvalues``: :func:`tumble.physics.theory.eigenvalues` at the steady spin, when the caller has them."""
    model, axis, spin, amplitude, order = scene_args
    lam = np.abs(theory.eigenvalues(model, axis, spin) if eigenvalues is None else eigenvalues).max()
    if dt is None:
        fastest = max(lam, abs(spin)) if model.resolves_spin else lam  # see the module docstring
        dt = 1.0 / fastest / planning.STEPS_PER_RADIAN[order]
    if kind == "exponential":
        tilt = math.sin(min(amplitude, 0.5 * np.pi))
        start = float(np.median(y0_norms))
        per_radian = start / tilt  # the norm of a perturbation one radian large
        saturation = max(planning.SATURATION, planning.SATURATION_TILTS * tilt) * per_radian
        if model.saturates_near_threshold:  # near a threshold the linear regime ends
            saturation *= min(1.0, value / abs(spin))  # sooner (module docstring); a gravity gradient's spin: n
        t_growth = (math.log(max(saturation / start, math.e)) + 2.0) / value
        if horizon:
            t_growth = min(t_growth, horizon)
        dt, first, every = _grid(0.0, t_growth, planning.PROBES, dt)
        probes = (first + np.arange(planning.PROBES + 1) * every) * dt
        n_steps = first + planning.PROBES * every
        return planning.StepPlan(t_end=n_steps * dt, dt=dt, n_steps=n_steps, probe_times=probes, saturation=saturation,
                               save_every=every if model.modal else None)
    return periodic_plan(value, dt, horizon)


def periodic_plan(value, dt, horizon):
    """The plan of a periodic scene of frequency ``value`` (rad/s) with a step of at most ``dt``: :data:`PERIODS`
    periods (or ``horizon`` s), the state stored :data:`~tumble.measure.planning.SAVES_PER_PERIOD` times a period."""
    period = 2 * np.pi / value
    t_end = horizon or PERIODS * period
    spacing = period / planning.SAVES_PER_PERIOD
    if t_end / spacing > planning.MAX_SAVES:
        raise ValueError(f"horizon {t_end:g} s needs {t_end / spacing:.0f} stored states per sample for the phase "
                         f"fit ({planning.SAVES_PER_PERIOD} per period), more than {planning.MAX_SAVES}; choose a "
                         f"shorter horizon")
    every = max(1, math.ceil(spacing / dt))
    dt = spacing / every
    n_steps = max(1, math.ceil(t_end / dt - 1e-9))
    return planning.StepPlan(t_end=n_steps * dt, dt=dt, n_steps=n_steps, save_every=every)


def _checked(model, axis, amplitude, samples, method):
    """The scene's arguments checked; ValueError naming the argument."""
    if not isinstance(model, Model):
        raise ValueError(f"model must be a tumble.models model (FreeBody, Gyrostat, HeavyTop), got {model!r}")
    if isinstance(axis, (bool, np.bool_)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (a principal axis, 1-based), got {axis!r}")
    if method != "auto" and method not in METHODS:
        raise ValueError(f"method must be auto or one of {', '.join(METHODS)} for a model, got {method!r}")
    if isinstance(amplitude, (bool, np.bool_)) or not float(amplitude) > 0:
        raise ValueError(f"amplitude must be > 0 rad, got {amplitude!r}")
    planning.check_amplitude(amplitude)
    if isinstance(samples, (bool, np.bool_)) or not isinstance(samples, (int, np.integer)) or samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    chosen = METHODS[0] if method == "auto" else method
    check_model_method(model, chosen)  # the samples run unchecked (run_planned_model)
    return chosen


def scene_plan(model, axis, spin=1.0, amplitude=1e-3, samples=256, seed=0, method="auto", *, dt=None,
               horizon=None, distribution="cone", device="cpu"):
    # size: a public call: the scene's physics, its ensemble and the study's integration options
    """Plan one model scene (nothing runs but the first samples' initial norms).

    Parameters
    ----------
    model : tumble.physics.models.Model
        ``FreeBody``, ``Gyrostat`` (rotor along ``axis``) or ``HeavyTop`` (``axis`` 3).
    axis : {1, 2, 3}
    spin : float
        Steady spin rate, rad/s, signed (a gyrostat's stability depends on its sign relative to the rotor).
    amplitude : float
        Tilt of the perturbation, rad (a heavy top: its up direction's; see the module docstring).
    samples, seed, distribution
        The ensemble (:func:`tumble.engine.sampling.perturbed_states`).
    method : {"auto", "rk4", "rk8", "symplectic_euler", "splitting2", "splitting4"}
    dt, horizon : float, optional
        Step and horizon, s (default: planned from the linear theory).
    device : {"cpu", "cuda"}
        Where the samples step (:func:`tumble.engine.model_ensemble.run_planned_model`); the fits run on the host.
        Trusted: checked where a study enters (its config, and :func:`tumble.pipeline.runner.scene_job` for a device
        that cannot run), the one caller. The scene's method and cost are checked here, so its samples run unchecked.

    Returns
    -------
    ModelScene

    Raises
    ------
    ValueError
        An invalid argument; an axis the model has no steady spin about; a neutral spin (no rate to measure).
    """
    chosen = _checked(model, axis, amplitude, samples, method)
    spin, amplitude = float(spin), float(amplitude)
    linearised = theory.linearisation(model, int(axis), spin)  # one Jacobian for the kind, the step and the mode
    kind, value = linearised.kind, linearised.value
    if kind == "neutral":
        raise ValueError(f"the steady spin about axis {axis} of this {model.kind} is neutral in linear theory (no "
                         f"growth rate or frequency to measure)")
    entropy = seed_entropy(seed)
    spin = model.steady_spin(spin)  # a gravity gradient's equilibrium turns at the orbit rate, whatever spin.rate says
    probe = ModelScene(model, model.moments, int(axis), spin, amplitude, int(samples), method, chosen, kind, value,
                       None, entropy, distribution)
    y0 = _initial_states(probe, 0, min(int(samples), 256))
    scene_mode = mode(model, int(axis), spin, kind, jacobian=linearised.jacobian) if model.modal else None
    if scene_mode is not None:
        norms = np.abs(_modal(scene_mode, y0))
    else:
        norms = model.transverse_norm(y0, axis, spin)
    order = registry.method(chosen).order
    plan = _plan((model, int(axis), spin, amplitude, order), kind, value, norms, dt, horizon, linearised.eigenvalues)
    planning.check_fit_span(kind, value, plan.t_end, horizon)
    planning.refuse_plan(int(samples), plan, True, kind == "exponential", 0, device)
    return ModelScene(model, model.moments, int(axis), spin, amplitude, int(samples), method, chosen, kind, value,
                      plan, entropy, distribution, mode=scene_mode, device=device)


class _Call(NamedTuple):
    """One engine call of a scene (:func:`_run`): samples ``[lo, hi)``, the engine's result and, for a modal scene,
    what its fit reads of the trajectory (:func:`_modal_signal`; the trajectory itself is then dropped)."""

    lo: int
    hi: int
    result: object  # tumble.engine.model_ensemble.ModelEnsembleResult
    signal: np.ndarray | None  # exponential: |z| (N, T); periodic: (Re z, Im z) (N, T, 2); None: not modal


def _modal_signal(scene, result):
    """What a modal scene's fit reads (:func:`_fit_group`): the measured mode's amplitude ``z`` at the stored times
    (:func:`tumble.measure.estimators.modal_amplitudes` of the time-major trajectory), ``|z|`` for a growth fit,
    its real and imaginary parts for a phase fit. Computed as soon as the engine returns, so that a chunk of scenes
    holds these rather than every scene's trajectory (a 40 x 40 map's chunk of 50 scenes: 180 MB of fresh memory)."""
    scene_mode = _scene_mode(scene)
    z = analysis.modal_amplitudes(result.trajectory, scene_mode.columns, scene_mode.centre, scene_mode.left)
    if scene.kind == "exponential":
        return np.abs(z, out=np.empty(z.shape))  # z is a transposed view: the fits read C-ordered rows of samples
    return np.stack([z.real, z.imag], axis=-1)


def _fit_group(pieces):
    """Per-sample ``(rate, code, extras)`` of engine calls of one kind of measurement, in one estimator call:
    ``pieces`` are ``(scene, call)`` (:class:`_Call`) of the same kind, model family and number of observed times (a
    chunk's scenes, whose bodies differ, are measured together, as :func:`tumble.measure.scans.scene_batch` does)."""
    first = pieces[0][0]
    heavy, counts = first.model.modal, [len(call.result.status) for _, call in pieces]
    row = np.repeat(np.arange(len(pieces), dtype=np.int64), counts)
    if first.kind == "exponential":
        times = np.stack([call.result.times if heavy else call.result.probe_times for _, call in pieces])
        norms = np.concatenate([call.signal if heavy else call.result.probes for _, call in pieces])
        saturation = np.repeat([scene.plan.saturation for scene, _ in pieces], counts)
        fit = analysis.growth_rates(times, norms, saturation, row=row)
        rate, extras = fit.rate, {name: getattr(fit, name) for name in ("t_start", "t_stop", "norm_start", "norm_stop")}
    else:
        times = np.stack([call.result.times for _, call in pieces])
        spin = np.repeat([scene.spin for scene, _ in pieces], counts)
        if heavy:
            signal = np.concatenate([call.signal for _, call in pieces])
            fit = analysis.oscillation_frequencies(times, signal, np.ones(2), spin, row=row)
        else:
            columns, weights = [], []
            for scene, _ in pieces:
                transverse = scene.model.transverse(scene.axis, scene.spin)
                where = [int(np.flatnonzero(transverse.columns == c)[0]) for c in transverse.phase]
                columns.append(transverse.phase.astype(np.int64))
                weights.append(np.asarray(transverse.weights)[..., where])
            trajectories = np.concatenate([call.result.trajectory for _, call in pieces])
            fit = analysis.oscillation_frequencies(times, trajectories,
                                                   np.repeat(weights, counts, axis=0), spin,
                                                   columns=np.repeat(columns, counts, axis=0), row=row)
        rate, extras = fit.frequency, {"radius": fit.radius}
    status = np.concatenate([call.result.status for _, call in pieces])
    offset = len(registry.STATUS_NAMES) - 1
    code = np.where(status != STATUS_OK, status, np.where(fit.code != analysis.FIT_OK, fit.code + offset, 0))
    bounds = np.cumsum([0] + counts)
    return [(rate[lo:hi], code[lo:hi].astype(np.int8), {name: v[lo:hi] for name, v in extras.items()})
            for lo, hi in zip(bounds[:-1], bounds[1:])]


def _fit_all(pieces):
    """:func:`_fit_group` of every group of ``pieces`` (``(scene, call)``), in the order of ``pieces``."""
    groups = {}
    for i, (scene, call) in enumerate(pieces):
        stored = call.signal is not None or call.result.trajectory is not None
        observed = call.result.times if stored else call.result.probe_times
        groups.setdefault((scene.kind, scene.model.modal, len(observed)), []).append(i)
    fits = [None] * len(pieces)
    for members in groups.values():
        for i, fit in zip(members, _fit_group([pieces[i] for i in members])):
            fits[i] = fit
    return fits


def _run(scene, start, stop):
    """The engine calls of samples ``[start, stop)`` of a scene (:class:`_Call`)."""
    plan, growth, modal = scene.plan, scene.kind == "exponential", scene.model.modal
    if not (0 <= start < stop <= scene.samples and start % CHUNK == 0):
        raise ValueError(f"a sample range must lie in [0, {scene.samples}) and start at a multiple of {CHUNK}, "
                         f"got [{start}, {stop})")
    calls = []
    step = SLICE if scene.device == "cpu" else max(SLICE, LAUNCH_SAMPLES)  # a device launch needs many samples
    for lo in range(start, stop, step):
        hi = min(lo + step, stop)
        result = run_planned_model(scene.model, _initial_states(scene, lo, hi), plan.t_end, plan.dt,
                                   method=scene.chosen, axis=scene.axis, spin=scene.spin, final=False,
                                   save_every=plan.save_every, time_major=modal,
                                   probe_times=plan.probe_times if growth and not plan.save_every else None,
                                   device=scene.device)
        if modal:
            calls.append(_Call(lo, hi, result._replace(trajectory=None), _modal_signal(scene, result)))
        else:
            calls.append(_Call(lo, hi, result, None))
    return calls


def _part(scene, start, stop, runs, fits):
    """The part of samples ``[start, stop)`` from their engine calls and fits."""
    names = ("t_start", "t_stop", "norm_start", "norm_stop") if scene.kind == "exponential" else ("radius",)
    out = {"start": np.int64(start), "rate": np.empty(stop - start), "code": np.empty(stop - start, dtype=np.int8),
           **{name: np.empty(stop - start) for name in names}}
    computed = 0
    for (lo, hi, result, _), (rate, code, extras) in zip(runs, fits):
        rows = slice(lo - start, hi - start)
        out["rate"][rows], out["code"][rows] = rate, code
        for name, values in extras.items():
            out[name][rows] = values
        computed += int(result.steps_taken.sum())
    out.update(sample_steps_computed=np.int64(computed),
               sample_steps_skipped=np.int64((stop - start) * scene.plan.n_steps - computed),
               rate_theory=np.float64(scene.value), path=np.array(f"model kernel ({scene.chosen})"),
               torque=np.array(""))
    return out


def scene_samples(scene, start, stop):
    """Run samples ``[start, stop)`` of a :func:`scene_plan`: per-sample fits, no reduction — the part
    :func:`tumble.measure.running.scene_samples` returns (same keys), so that scene records, checkpoints and dask
    tasks take it as they take a free body's."""
    runs = _run(scene, start, stop)
    return _part(scene, start, stop, runs, _fit_all([(scene, call) for call in runs]))


def _model_coordinates(scene):
    """The model's coordinates of a scene record: its kind and parameters (the rotor as h along the spin axis)."""
    model = scene.model
    coords = {"model": np.asarray(model.kind), "@model": model.kind}
    coords.update((key, np.float64(value)) for key, value in model.coordinates(scene.axis).items())
    return coords


def scene_records(model_scenes, parts):
    """The records of model scenes from their :func:`scene_samples` ranges: the free body's
    (:func:`tumble.measure.reduction.scene_records`) and the model's coordinates."""
    records = reduction.scene_records(model_scenes, parts)
    for scene, record in zip(model_scenes, records):
        for name, value in _model_coordinates(scene).items():
            record[name] = np.asarray(value)
        record["@title"] = np.asarray(f"tumble measurement: {scene.model.kind}, {scene.kind} rate about axis "
                                      f"{scene.axis}")
    return records


def scene_batch(model_scenes):
    """The records of whole model scenes: each scene's engine calls (its body is its own: the model kernel takes one
    model's constants a call), then one estimator call for all scenes of a kind (same bits as scene by scene: the
    fits are per sample)."""
    runs = [_run(scene, 0, scene.samples) for scene in model_scenes]
    fits = iter(_fit_all([(scene, call) for scene, calls in zip(model_scenes, runs) for call in calls]))
    parts = [[_part(scene, 0, scene.samples, calls, [next(fits) for _ in calls])]
             for scene, calls in zip(model_scenes, runs)]
    return scene_records(model_scenes, parts)


def scan_layout(moments, values, swept):
    """The scenes of a model study in the form of :func:`tumble.measure.scans.scan_layout` (``moments`` (B, 3) or
    (3,); ``values`` by name: axis, spin, amplitude, method and the model's parameters; ``swept``: the names whose
    value is a list of scene values, in the order of the scan's dimensions)."""
    moments = np.atleast_2d(np.asarray(moments, dtype=float))
    swept = {name: list(values[name]) for name in swept}
    fixed = {name: v for name, v in values.items() if name not in swept}
    per_body = math.prod(len(v) for v in swept.values())
    return {"moments": moments, "swept": swept, "fixed": fixed, "scenes": len(moments) * per_body}


#: Samples of a damper's flat-spin trace (:func:`flat_spin_trace`) and its stored times.
TRACE_SAMPLES = 8
TRACE_POINTS = 1500

#: Steps per radian of the fastest rate of a flat-spin trace (rk8: its energy error per step is then far below
#: round-off, so the energy falls by the dissipation alone).
TRACE_STEPS_PER_RADIAN = 40

#: The damping of the trace's reference run: the kernel takes c > 0 only; at this c the dissipation is below
#: float64's smallest normal number, so that run's energy changes by the integrator alone.
UNDAMPED = 1e-300


def _settle_time(model, axis, spin, amplitude):
    """Seconds from a minor-axis spin tilted by ``amplitude`` to a settled flat spin: the growth to O(1) at the
    linear rate and 8 e-foldings of the nutation's decay about the major axis (first order in ``c``)."""
    kind, growth = theory.linear(model, axis, spin)
    if kind != "exponential":
        raise ValueError(f"a flat-spin trace starts from an unstable spin (a damper's minor axis); axis {axis} is "
                         f"{kind}")
    major = int(np.argmax(model.moments)) + 1
    decay = -theory.damper_nutation_rate(model.moments, model.damper_inertia, model.damping, major)
    return (math.log(1.0 / amplitude) + 2.0) / growth + 8.0 / decay


def flat_spin_trace(model, axis, spin=1.0, amplitude=1e-3, *, seed=0, method=registry.ACCURATE_STEPPING,
                    horizon=None, samples=TRACE_SAMPLES, points=TRACE_POINTS):
    # size: a public call: the scene's physics, its ensemble and the trace's options
    """A damper's minor-axis spin turning over to the flat spin about its major axis (Explorer 1), as the
    ``flat_spin`` figure reads it: ``samples`` samples of the scene's ensemble run for ``horizon`` s (default:
    :func:`_settle_time`) with ``method`` at :data:`TRACE_STEPS_PER_RADIAN` steps a radian of the fastest rate,
    ``points`` + 1 stored times. The same samples are run again with ``c`` = :data:`UNDAMPED`: that run's energy
    change is the integrator's own (to set against the damper's decay).

    Returns
    -------
    xarray.Dataset
        Over ``trace_time`` (s) and ``trace_sample``: ``trace_nutation`` (rad, the angle between the spin axis and
        ``L``), ``trace_energy`` (J), ``trace_momentum`` (``|L|``, N m s), ``trace_energy_undamped`` (J, the
        reference run); scalars ``trace_energy_rise`` (the largest rise of the energy between stored times,
        relative to the initial energy: round-off when it falls monotonically), ``trace_momentum_drift``
        (``max | |L| / |L(0)| - 1 |``), ``trace_undamped_drift`` (the reference run's ``max |E / E(0) - 1|``),
        ``trace_flat_energy`` (``|L|² / (2 (I_max + J))``, J: the flat spin's energy, body and sphere turning
        together) and ``trace_damping`` (N m s).
    """
    import xarray as xr

    if not isinstance(model, models.Damper):
        raise ValueError(f"a flat-spin trace is a damper's (model kind {models.Damper.kind!r}), got {model.kind!r}")
    method = METHODS[0] if method == "auto" else method
    t_end = float(horizon) if horizon else _settle_time(model, axis, spin, amplitude)
    fastest = max(np.abs(theory.eigenvalues(model, axis, spin)).max(), abs(spin), model.damping / model.damper_inertia)
    dt = 1.0 / fastest / TRACE_STEPS_PER_RADIAN
    every = max(1, math.ceil(t_end / points / dt))
    dt = t_end / points / every
    y0 = perturbed_states(model, axis, spin, amplitude, samples, seed=seed)
    runs = {}
    for name, system in (("damped", model), ("undamped", models.Damper(model.moments, model.damper_inertia,
                                                                      UNDAMPED))):
        runs[name] = run_model_ensemble(system, y0, points * every * dt, dt, method=method, axis=axis, spin=spin,
                                        save_every=every, final=False)
    y = runs["damped"].trajectory
    momentum = model.moments * y[..., :3] + model.damper_inertia * y[..., 3:]
    size = np.linalg.norm(momentum, axis=-1)
    nutation = np.arccos(np.clip(np.abs(momentum[..., axis - 1]) / size, 0.0, 1.0))
    energy = model.energy(y)
    undamped = models.Damper(model.moments, model.damper_inertia, UNDAMPED).energy(runs["undamped"].trajectory)
    flat = size[:, 0] ** 2 / (2.0 * (model.moments.max() + model.damper_inertia))
    dims = ("trace_sample", "trace_time")
    return xr.Dataset(
        {"trace_nutation": (dims, nutation, {"units": "rad", "long_name": "angle between the spin axis and L"}),
         "trace_energy": (dims, energy, {"units": "J"}),
         "trace_momentum": (dims, size, {"units": "N m s", "long_name": "|L|"}),
         "trace_energy_undamped": (dims, undamped, {"units": "J", "long_name": f"energy at c = {UNDAMPED:g} "
                                                                               f"(the integrator's drift)"}),
         "trace_flat_energy": (("trace_sample",), flat, {"units": "J", "long_name": "|L|^2 / (2 (I_max + J))"}),
         "trace_energy_rise": ((), float(np.max(np.diff(energy, axis=-1) / energy[:, :1]))),
         "trace_momentum_drift": ((), float(np.max(np.abs(size / size[:, :1] - 1.0)))),
         "trace_undamped_drift": ((), float(np.max(np.abs(undamped / undamped[:, :1] - 1.0)))),
         "trace_damping": ((), model.damping, {"units": "N m s"})},
        coords={"trace_time": ("trace_time", runs["damped"].times, {"units": "s"}),
                "trace_sample": ("trace_sample", np.arange(samples))},
        attrs={"trace_method": method, "trace_dt": dt})
