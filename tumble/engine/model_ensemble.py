"""Ensembles of the models beyond the free body (issue 18): arguments and cost checked, samples in chunks, the model
kernels.

:func:`run_model_ensemble` is :func:`tumble.engine.ensemble.run_ensemble` for a model of
:mod:`tumble.physics.models` (a free body, a gyrostat, a heavy top, a gravity-gradient satellite, a body with a
damper): the same chunks of samples and observers
(final state, decimated trajectory, the transverse norm at probe times, the invariants' drift, a status per
sample), stepped by the models' SIMD kernels (:func:`tumble.kernels.run_model`: rk4 or rk8, and the Lie–Poisson
splittings symplectic_euler, splitting2, splitting4 for a free body, gyrostat or heavy top; one compiled driver
per model and method). The transverse norm is the model's own (:meth:`~tumble.physics.models.Model.transverse`, about
:meth:`~tumble.physics.models.Model.equilibrium`; the gravity gradient's ``Transverse.centre``, ``w2 = −n``, is that
equilibrium's). Initial states near a steady spin come from
:func:`tumble.engine.sampling.perturbed_states`.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from ..kernels import MODEL_BLOCK, MODEL_CODES, device_models, model_methods, parallel_block, run_model
from ..physics.models import Model
from . import cost
from .device import resolve_device
from .ensemble import DEFAULT_DRIFT_LIMIT, _count, _number, observation_times
from .sampling import CHUNK

__all__ = ["ModelEnsembleResult", "check_model_method", "run_model_ensemble", "run_planned_model"]


class ModelEnsembleResult(NamedTuple):
    """Arrays per sample (first axis) and what ran; an output that was not asked for is None."""

    final: np.ndarray | None  # (N, n_state): rad/s, then the model's own units
    times: np.ndarray | None  # (T,), s, of the trajectory
    trajectory: np.ndarray | None  # (N, T, n_state); (T, n_state, N) when asked ``time_major``
    probe_times: np.ndarray | None  # (P,), s
    probes: np.ndarray | None  # (N, P), transverse norm, rad/s (NaN after a sample stopped)
    drift: np.ndarray | None  # (N, n_invariants): running max drift of each invariant (registry's order)
    status: np.ndarray  # (N,) int8, registry.STATUS_NAMES
    steps_taken: np.ndarray  # (N,) int64
    info: dict


def _flag(value, name):
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _states(model, y0):
    """``y0`` as float64 of shape (N, n_state), N >= 1 (non-finite values allowed: those samples are flagged)."""
    try:
        y0 = np.array(y0, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"y0 must be an array of numbers of shape (N, {model.state_size}), got {y0!r}") from None
    if y0.ndim != 2 or y0.shape[1] != model.state_size or len(y0) == 0:
        raise ValueError(f"y0 must have shape (N, {model.state_size}) with N >= 1 ({', '.join(model.spec.state)} of "
                         f"a {model.kind} model), got shape {y0.shape}")
    return y0


def check_model_method(model, method):
    """Refuse a model the kernels do not step or a method they do not step it with (the splittings only for a
    Lie–Poisson model): a ValueError naming ``model`` or ``method``. :func:`run_model_ensemble` checks it, and a model
    scene's planner (:func:`tumble.measure.model_scenes.scene_plan`), whose samples then run unchecked
    (:func:`run_planned_model`)."""
    if not isinstance(model, Model) or model.kind not in MODEL_CODES:
        raise ValueError(f"model must be a tumble.physics.models model ({', '.join(MODEL_CODES)}), got {model!r}")
    if not isinstance(method, str) or method not in model_methods(model.kind):
        why = f" (the Lie–Poisson splittings do not apply: {model.not_lie_poisson})" if model.not_lie_poisson else ""
        raise ValueError(f"method must be one of {', '.join(model_methods(model.kind))} for a {model.kind} model, got "
                         f"{method!r}{why}")


def _checked(model, y0, t_end, dt, method, axis, spin, save_every, probe_times, drift_limit, chunk):
    # size: one check for each argument of run_model_ensemble's public call, all before any kernel runs
    """The arguments of :func:`run_model_ensemble`, checked before anything runs; ValueError naming the argument."""
    check_model_method(model, method)
    y0 = _states(model, y0)
    t_end = _number(t_end, "t_end", low=0.0)
    dt = _number(dt, "dt", positive=True)
    if t_end / dt > np.iinfo(np.int64).max:
        raise ValueError(f"t_end / dt = {t_end / dt:.3g} steps: more than a run can count")
    if isinstance(axis, (bool, np.bool_)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (a principal axis, 1-based), got {axis!r}")
    if spin is None:  # the ensemble's own spin: the median of the axis component of its finite states
        column = y0[:, axis - 1]
        column = column[np.isfinite(column)]
        spin = float(np.median(column)) if len(column) else 1.0
    spin = _number(spin, "spin")
    if save_every is not None:
        save_every = _count(save_every, "save_every", 0)
    if probe_times is not None:
        try:
            probe_times = np.array(probe_times, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"probe_times must be times in s, got {probe_times!r}") from None
        if probe_times.ndim != 1 or not len(probe_times) or not np.isfinite(probe_times).all() or (
                probe_times < 0).any():
            raise ValueError(f"probe_times must have shape (P,), P >= 1, finite times >= 0 s, got {probe_times!r}")
    drift_limit = _number(drift_limit, "drift_limit", low=0.0)
    chunk = _count(chunk, "chunk", 1)
    return y0, t_end, dt, spin, save_every, probe_times, drift_limit, chunk


def run_model_ensemble(model, y0, t_end, dt, *, method="rk4", axis, spin=None, save_every=None, probe_times=None,
                       drift=False, drift_limit=DEFAULT_DRIFT_LIMIT, final=True, chunk=CHUNK, time_major=False,
                       device="cpu"):
    # size: the engine's public call for the models: each keyword is one observer or option a caller may name
    """Run an ensemble of a model with a fixed-step kernel and observe it on the fly.

    Parameters
    ----------
    model : tumble.physics.models.Model
        ``FreeBody``, ``Gyrostat``, ``HeavyTop``, ``GravityGradient`` or ``Damper`` (the kernels step every model
        with a kernel code, ``tumble.kernels.MODEL_CODES``; studies only the ``implemented`` ones of the registry).
    y0 : array_like, shape (N, n_state)
        Initial states (``n_state = model.state_size``): ``w`` (rad/s), then the model's own components (the heavy
        top's unit up vector ``g``, the gravity gradient's unit quaternion ``q`` relative to the orbit frame, put
        back on the unit sphere after every step, the damper sphere's ``s``, rad/s). A sample with a non-finite
        component is not run: its status is non-finite.
    t_end, dt : float
        Horizon and step, s; ``round(t_end / dt)`` steps are taken.
    method : {"rk4", "rk8", "symplectic_euler", "splitting2", "splitting4"}
        The splittings (exact sub-flows; ``|I w + h|``, a heavy top's ``|g|`` and ``L·g`` kept to round-off) for a
        free body, gyrostat or heavy top only: a ValueError naming ``method`` for a gravity gradient or damper.
    axis : {1, 2, 3}
        The steady spin's axis, 1-based: the transverse norm (the probes) measures the perturbation of the spin
        about it (:meth:`~tumble.physics.models.Model.transverse`). A heavy top: 3; a gravity gradient: any (its
        equilibrium follows the orbit, ``w = (0, −n, 0)``, ``q = 1``, whatever the axis).
    spin : float, optional
        The steady spin, rad/s (a gyrostat's norm weights depend on it); default: the median of ``y0[:, axis - 1]``.
    save_every : int, optional
        Store the initial state, every ``save_every``-th step and the final state (0 or None: no trajectory).
    probe_times : array_like, shape (P,), optional
        Times (s) at which to record the transverse norm (rad/s); rounded to whole steps.
    drift : bool
        Record the running maximum drift of each of the model's invariants (``model.spec.invariants``), relative to
        its scale (:mod:`tumble.kernels.loops.model_loop`: the invariant itself, or the largest magnitude an invariant that
        may vanish can take).
    drift_limit : float
        A drift beyond it flags a sample ``invariant drift`` and stops it (0: no flagging).
    final : bool
        Return the final states.
    chunk : int
        Samples per kernel call.
    time_major : bool
        Return the trajectory as the kernels store it, shape (T, n_state, N), a component row of all samples at
        each stored time (no transposing copy: a caller that reduces over the components, such as a modal
        projection, reads it row by row).
    device : str
        ``"cpu"`` or ``"cuda"`` (:func:`tumble.engine.device.resolve_device`): on ``"cuda"`` every model, method and
        observer above runs on the device, one thread per sample (:mod:`tumble.kernels.cuda.models`, the CPU's
        per-sample steps); recorded in ``info["device"]``.

    Returns
    -------
    ModelEnsembleResult
        ``info`` holds the model, method, step, steps, samples, spin and the run time (s).

    Raises
    ------
    ValueError
        An argument of the wrong type, shape or range (named in the message); an axis the model has no steady
        spin about (a heavy top: not 3; a gyrostat with probes: its rotor across the axis).
    tumble.engine.cost.TooLarge
        A run past the cost bound (:func:`tumble.engine.cost.refuse`: its steps, memory or time), before anything is
        allocated; the message starts ``y0 (N states) over t_end / dt = ... steps``.
    """
    device = resolve_device(device)
    y0, t_end, dt, spin, save_every, probe_times, drift_limit, chunk = _checked(
        model, y0, t_end, dt, method, axis, spin, save_every, probe_times, drift_limit, chunk)
    drift, final, time_major = _flag(drift, "drift"), _flag(final, "final"), _flag(time_major, "time_major")
    n, n_state = y0.shape
    steps = float(np.rint(t_end / dt)) if t_end > 0 else 0.0
    cost.refuse(cost.run_cost(n, steps, _stored_per_sample(model, steps, save_every, probe_times, drift, final)),
                f"y0 ({n:,} states) over t_end / dt = {steps:.3g} steps", device)
    return run_planned_model(model, y0, t_end, dt, method=method, axis=axis, spin=spin, save_every=save_every,
                             probe_times=probe_times, drift=drift, drift_limit=drift_limit, final=final, chunk=chunk,
                             time_major=time_major, device=device)


def _stored_per_sample(model, steps, save_every, probe_times, drift, final):
    """Float64 values a run keeps per sample besides its state: the final state, the trajectory's saved states, the
    probes and the invariants' drifts."""
    saved = steps // save_every + 2 if save_every else 0
    return (model.state_size * ((1 if final else 0) + saved) + (0 if probe_times is None else len(probe_times))
            + (len(model.spec.invariants) if drift else 0))


def run_planned_model(model, y0, t_end, dt, *, method, axis, spin, save_every=None, probe_times=None, drift=False,
                      drift_limit=DEFAULT_DRIFT_LIMIT, final=True, chunk=CHUNK, time_major=False, device="cpu"):
    # size: run_model_ensemble's observers and options, passed on as its callers name them (one keyword each)
    """:func:`run_model_ensemble` of arguments already checked, trusted as they come: what the public call runs after
    its checks, and what a planned model scene runs (:func:`tumble.measure.model_scenes.scene_samples`: its method,
    device and cost were checked when it was planned, :func:`tumble.measure.model_scenes.scene_plan`).

    ``y0`` a float array (N, n_state); ``t_end``, ``dt``, ``spin`` and ``drift_limit`` floats; ``method`` one of the
    model's kernel methods; ``save_every`` an int or None; ``probe_times`` a float array (P,) or None; ``device``
    resolved (``"cpu"`` or ``"cuda"``); the flags bools. Nothing here raises for an argument.
    """
    step = run_model if device == "cpu" else device_models().run_model
    transverse = model.transverse(axis, spin)
    y_eq = model.equilibrium(axis, spin) if probe_times is not None else None
    if y_eq is not None and transverse.centre is not None:  # the kernels subtract y_eq: it must be the norm's centre
        assert np.array_equal(y_eq[transverse.columns], transverse.centre), (y_eq, transverse)
    n, n_state = y0.shape
    n_steps = int(round(t_end / dt)) if t_end > 0 else 0
    save = int(save_every or 0)
    times, probe_steps, probe_times = observation_times(t_end, dt, save, probe_times)
    parameters = model.parameters  # the kernels' keywords are the study keys (registry.MODEL_PARAMETERS)
    n_invariants = len(model.spec.invariants)
    out_final = np.empty((n, n_state)) if final else None
    trajectory = None  # the trajectory is one kernel call's own array when one call runs every sample
    if save and (n == 0 or n > chunk or not time_major):
        trajectory = np.empty((len(times), n_state, n) if time_major else (n, len(times), n_state))
    probes = np.empty((n, len(probe_steps))) if probe_steps is not None else None
    drifts = np.empty((n, n_invariants)) if drift else None
    status = np.empty(n, dtype=np.int8)
    steps_taken = np.empty(n, dtype=np.int64)
    started = time.perf_counter()
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        state = np.array(y0[lo:hi].T, order="C")
        observed = step(model.kind, method, state, model.moments, dt, n_steps, save_every=save,
                        columns=transverse.columns, weights=transverse.weights, y_eq=y_eq,
                        probe_steps=probe_steps, drift=drift, drift_limit=drift_limit,
                        block=parallel_block(hi - lo, MODEL_BLOCK), **parameters)
        if final:
            out_final[lo:hi] = state.T
        if save and time_major and lo == 0 and hi == n:  # one kernel call: its array is the trajectory
            trajectory = observed.saved
        elif save and time_major:
            trajectory[..., lo:hi] = observed.saved
        elif save:
            trajectory[lo:hi] = observed.saved.transpose(2, 0, 1)
        if probes is not None:
            probes[lo:hi] = observed.probes.T
        if drift:
            drifts[lo:hi] = observed.drift.T
        status[lo:hi] = observed.status
        steps_taken[lo:hi] = observed.steps_taken
    info = {"path": "model kernel", "model": model.kind, "method": method, "dt": dt, "n_steps": n_steps,
            "samples": n, "axis": int(axis), "spin": spin, "drift_limit": drift_limit, "device": device,
            "run_seconds": time.perf_counter() - started}
    return ModelEnsembleResult(out_final, times, trajectory, probe_times, probes, drifts, status, steps_taken, info)
