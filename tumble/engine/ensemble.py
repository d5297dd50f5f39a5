"""The ensemble engine: plan a scene's path, run it chunk by chunk, observe only what was asked.

A scene asks for some of: the final state, a decimated trajectory, the transverse perturbation norm at
given times (for growth fits), the times of the spin-axis sign changes (flips), the running invariant
error. :func:`run_ensemble` picks the cheapest path that still delivers all of them:

* torque-free with ``method="auto"`` (or ``"exact"``): the closed form (:mod:`tumble.physics.exact`), no steps at all;
* otherwise a fixed-step kernel with only the requested observers compiled in, the torque compiled out when
  it is zero, and — when the caller gives stop criteria — each sample stopping once its measurement is
  complete;
* the attitude (orientation quaternion) only when asked (``attitude=True``): the closed form
  (:func:`tumble.physics.exact.attitude`) or the attitude kernels (:mod:`tumble.kernels.steps.attitude`), which are never
  compiled or run otherwise.

Samples run in chunks of :data:`tumble.engine.sampling.CHUNK`; a progress bar (tqdm, only on a terminal) advances
per chunk, and Ctrl-C stops between chunks. What ran and what was skipped is returned in ``info``.
"""

from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
import time
from collections.abc import Mapping
from typing import NamedTuple

import numba
import numpy as np

from .. import registry
from ..kernels import (BLOCK, METHODS, TORQUE_CONSTANT, TORQUE_SIGNATURE, TORQUE_USER, device_attitude,
                       device_kernels, fits, run, run_attitude)
from ..physics import exact
from ..physics.bodies import finite_array, one_body, spin_vectors
from ..physics.models import FreeBody
from ..registry import STATUS_NAMES, STATUS_NONFINITE, STATUS_OK, choose_method
from . import cost
from .device import LAUNCH_SAMPLES, WARP, check_on_device, resolve_device, stepper
from .progress import tqdm
from .sampling import CHUNK
from .adaptive_runs import fixed_steps_only, no_save_every, run_adaptive
from .system_runs import added_tableau, is_system, no_body_parameters, run_system
from .torqued_body import body_system

__all__ = ["EnsembleResult", "DEFAULT_DRIFT_LIMIT", "Interrupted", "STATUS_NAMES", "check_torque_step", "checked_torque",
           "run_ensemble", "run_planned", "run_scene_table", "torque_spec"]

# Torque-free samples whose energy or |L|^2 drift by more than this (relative) are flagged, not trusted.
DEFAULT_DRIFT_LIMIT = 1e-2

_warmed = set()


class EnsembleResult(NamedTuple):
    """Arrays per sample (first axis) and what ran. An output that was not asked for is None."""

    final: np.ndarray | None  # (N, 3), rad/s
    times: np.ndarray | None  # (T,), s, of the trajectory
    trajectory: np.ndarray | None  # (N, T, 3), rad/s
    probe_times: np.ndarray | None  # (P,), s
    probes: np.ndarray | None  # (N, P), transverse norm, rad/s (NaN after a sample stopped)
    flips: np.ndarray | None  # (N, F), s (NaN where fewer flips happened)
    flip_count: np.ndarray | None  # (N,)
    drift: np.ndarray | None  # (N, 2): max |E/E0 - 1|, max ||L|²/|L0|² - 1|
    status: np.ndarray  # (N,) int8, see STATUS_NAMES
    steps_taken: np.ndarray  # (N,) steps each sample took (0 on the closed-form path)
    info: dict
    quaternion: np.ndarray | None = None  # (N, T, 4), body-to-space rotation, scalar first (attitude=True)
    growth: tuple | None = None  # (rate 1/s, points, first and last norm rad/s), (N,) each (growth_window)
    phase: tuple | None = None  # (frequency rad/s, median radius rad/s, code int8), (N,) each (phase_window)


def _torque_vector(vector):
    try:
        params = np.array(vector, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"torque must be 3 numbers (N m, body frame) or a function, got {vector!r}") from err
    if params.shape != (3,):
        raise ValueError(f"torque must have shape (3,) (N m, body frame), got shape {params.shape}")
    if not np.all(np.isfinite(params)):
        raise ValueError(f"torque must be finite, got {params.tolist()}")
    return params


def torque_spec(torque):
    """``(kind, params, fn, description)`` of a torque argument; params and fn None when torque-free.

    ``torque`` is None, three numbers (N m, body frame; all zero means none), a named profile — a mapping
    ``{"profile": "constant" | "ramp" | "sine" | "pulse", "vector": (N1, N2, N3), "duration": s, "period": s}``
    (``duration`` for ramp and pulse, ``period`` for sine; see :mod:`tumble.kernels.steps.steppers`), or a function
    ``f(t, w1, w2, w3) -> (N1, N2, N3)`` (numba-jitted, or jittable in nopython mode). ``params`` is
    ``(N1, N2, N3, tau)``.
    """
    if torque is None:
        return TORQUE_CONSTANT, None, None, "none"
    if callable(torque):
        fn = torque if isinstance(torque, numba.core.registry.CPUDispatcher) else numba.njit(torque)
        name = getattr(torque, "__name__", repr(torque))
        try:  # the one signature the kernels call a torque function with (kernels.TORQUE_SIGNATURE)
            fn.compile(TORQUE_SIGNATURE)
        except Exception as err:  # numba's typing errors: the function cannot serve as a torque
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise ValueError(f"torque function {name} must compile in numba's nopython mode as f(t, w1, w2, w3) "
                             f"-> (N1, N2, N3), all floats: {first}") from None
        return TORQUE_USER, None, fn, f"function {name}(t, w1, w2, w3)"
    profile, tau = registry.torque_profile("constant"), 0.0
    if isinstance(torque, Mapping):
        if torque.get("profile", "constant") == "none":
            return TORQUE_CONSTANT, None, None, "none"
        profile = registry.torque_profile(torque.get("profile", "constant"))
        if profile.time:
            key = profile.time
            tau = float(torque.get(key, 0.0))
            if not (np.isfinite(tau) and tau > 0):
                raise ValueError(f"torque profile {profile.name!r} needs {key} > 0 s, got {torque.get(key)!r}")
        vector = _torque_vector(torque.get("vector", (0.0, 0.0, 0.0)))
    else:
        vector = _torque_vector(torque)
    if not vector.any():
        return TORQUE_CONSTANT, None, None, "none"
    text = profile.text.format(v=vector.tolist(), tau=f"{tau:g}")
    return profile.code, np.append(vector, tau), None, text


def _warm(method, torque, observe):
    """Compile (or load from the cache) the kernel variant a run needs; seconds it took (0 if done before).

    One driver per method and torque type (none, a profile, a function) serves every observer."""
    key = (method, torque.params is None, torque.fn)
    if key in _warmed:
        return 0.0
    started = time.perf_counter()
    w = np.array([[0.0], [1.0], [0.0]])
    run(METHODS[method], w, np.array([1.0, 2.0, 3.0]), 0.0, 1e-3, 1, save_every=1 if observe.save > 0 else 0,
        probe_steps=None if observe.probe_steps is None else [1], max_flips=observe.max_flips, drift=observe.drift,
        torque_params=None if torque.params is None else np.zeros(4), torque_fn=torque.fn)
    _warmed.add(key)
    return time.perf_counter() - started


class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run between two chunks; ``done`` samples of ``total`` had finished."""

    def __init__(self, done, total):
        super().__init__(f"stopped by Ctrl-C between chunks after {done} of {total} samples")
        self.done, self.total = done, total


@contextlib.contextmanager
def _stop_between_chunks():
    """Defer Ctrl-C to the end of the current chunk.

    Inside, SIGINT only sets a flag (the yielded callable reads it), so a chunk is never abandoned half-done —
    the closed form's numpy work included; a second Ctrl-C interrupts at once. The previous handler is
    restored on exit. Outside the main thread (where Python cannot install handlers) nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    pressed = []
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum, frame):
        if pressed:
            raise KeyboardInterrupt
        pressed.append(True)

    signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(pressed)
    finally:
        signal.signal(signal.SIGINT, previous)


def flip_times(first, spacing, max_flips, t_end):
    """``(times (n, max_flips), count (n,))`` of flips at ``first + j spacing`` up to ``t_end`` (scalar or per
    sample), NaN past it; ``count`` is every flip up to ``t_end``, beyond ``max_flips`` too."""
    t_end = np.asarray(t_end, dtype=float)
    later = np.arange(1, max_flips)[None, :] * spacing[:, None]  # inf where the spin never flips again
    times = np.concatenate([first[:, None], first[:, None] + later], axis=1)
    with np.errstate(invalid="ignore"):  # inf - inf where the spin never flips at all
        count = np.where(first <= t_end, np.floor((t_end - first) / spacing) + 1, 0)
    end = t_end[:, None] if t_end.ndim else t_end
    return np.where(times <= end, times, np.nan), count.astype(np.int64)


def observation_times(t_end, dt, save_every=None, probe_times=None):
    """``(saved times or None, probe steps or None, probe times or None)`` of a run of ``round(t_end / dt)``
    steps: every ``save_every``-th step and the last one (exactly ``t_end``), and the probe times rounded to
    whole steps — the times the kernels and the closed form observe at."""
    n_steps = int(round(t_end / dt)) if t_end > 0 else 0
    times = None
    if save_every:
        steps = list(range(0, n_steps + 1, int(save_every)))
        if steps[-1] != n_steps:
            steps.append(n_steps)
        times = np.array(steps, dtype=float) * dt
        times[-1] = t_end  # exactly, not n_steps * dt rounded
    probe_steps = None
    if probe_times is not None:
        probe_steps = np.clip(np.rint(np.asarray(probe_times, dtype=float) / dt), 0, n_steps).astype(np.int64)
        probe_times = probe_steps * dt
    return times, probe_steps, probe_times


def _number(value, name, *, low=None, positive=False):
    """``value`` as a finite Python float (``>= low``, or ``> 0`` when ``positive``); ValueError (TypeError for a
    bool) naming ``name``."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {x!r}")
    if positive and x <= 0:
        raise ValueError(f"{name} must be > 0, got {x!r}")
    if low is not None and x < low:
        raise ValueError(f"{name} must be >= {low}, got {x!r}")
    return x


def _count(value, name, low=0):
    """``value`` as an int ``>= low``; ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    return int(value)


def _checked_arguments(w0, t_end, dt, axis, save_every, probe_times, norm_weights, max_flips, stop_norm,
                       stop_flips, drift_limit, chunk):
    # size: one check for each argument of run_ensemble's public call, all before any kernel runs
    """:func:`run_ensemble`'s arguments checked before any kernel runs (issue 17, cause 16): a ValueError naming
    the argument for NaN or infinity, a wrong shape, no spins, a negative count or step. Returns ``(w0 (N, 3),
    t_end, dt, probe_times or None, norm_weights or None)`` as floats."""
    w0 = spin_vectors(w0)
    if w0.ndim != 2:
        raise ValueError(f"w0 must have shape (N, 3) (N spins, rad/s, body frame), got shape {w0.shape}")
    if len(w0) == 0:
        raise ValueError("w0 holds no spins (shape (0, 3))")
    t_end = _number(t_end, "t_end", low=0)
    dt = _number(dt, "dt", positive=True)
    if isinstance(axis, (bool, np.bool_)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (a principal axis, 1-based), got {axis!r}")
    if save_every is not None:
        _count(save_every, "save_every")
    if probe_times is not None:
        probe_times = finite_array(probe_times, "probe_times")
        if probe_times.ndim != 1 or not len(probe_times):
            raise ValueError(f"probe_times must have shape (P,) with P >= 1 (times, s), got shape {probe_times.shape}")
        if (probe_times < 0).any():
            raise ValueError(f"probe_times must be >= 0 s, got {probe_times.min()!r}")
    if norm_weights is not None:
        norm_weights = finite_array(norm_weights, "norm_weights")
        if norm_weights.shape != (3,) or (norm_weights < 0).any() or not norm_weights.any():
            raise ValueError(f"norm_weights must be 3 numbers >= 0, not all 0, got {norm_weights.tolist()}")
    _count(max_flips, "max_flips")
    _number(stop_norm, "stop_norm", low=0)
    _count(stop_flips, "stop_flips")
    _number(drift_limit, "drift_limit", low=0)
    _count(chunk, "chunk", low=1)
    return w0, t_end, dt, probe_times, norm_weights


def _stored_per_sample(steps, save_every, probe_times, max_flips, drift, attitude):
    """Float64 values a run keeps per sample: the final state, the trajectory (and attitude), probes, flips, drift."""
    saved = steps // save_every + 2 if save_every else 0
    return 3 + saved * (7 if attitude else 3) + (0 if probe_times is None else len(probe_times)) + max_flips + 2 * drift


def _error_controlled(body, w0, t_end, dt, final, save_every, torque, asked, parameters, device, tolerance):
    # size: run_ensemble's arguments an error-controlled run reads, checked once
    """:func:`run_ensemble` with ``method="dop853"`` (:func:`tumble.engine.adaptive_runs.run_adaptive`): the final
    states and the states at ``times``, a free body's with its torque (:func:`tumble.engine.torqued_body.torqued_body`
    on the CPU); a rigid body's observers and ``save_every`` refused."""
    if not is_system(body):
        asked = [name for name in asked if name != "torque"]
    if asked:
        raise ValueError(f"method 'dop853' observes the final state and the states at times=[...]; {', '.join(asked)} "
                         f"observe a rigid body's scene with the fixed steps or the closed form (remove them)")
    no_save_every(save_every)
    rtol, atol, times, max_steps = tolerance
    name = "y0"
    if not is_system(body):
        no_body_parameters(parameters)
        body, parameters = body_system(one_body(body), checked_torque(torque), False, device)
        name = "w0"
    run, _ = run_adaptive(body, w0, t_end, times=times, rtol=rtol, atol=atol, first_step=dt, max_steps=max_steps,
                          parameters=parameters, device=device, y0_name=name)
    info = {"path": "error-controlled", "method": registry.ERROR_CONTROLLED[0], "rtol": run.rtol, "atol": run.atol,
            "rejected_steps": run.rejected, "system": run.name, "parameters": run.parameters, "samples": len(run.final),
            "device": device}
    trajectory = times is not None
    return EnsembleResult(run.final if final else None, run.times if trajectory else None,
                          run.states if trajectory else None, None, None, None, None, None, run.status, run.steps,
                          info)


def run_ensemble(body, w0, t_end, dt, *, method="auto", torque=None, axis=1, final=True, save_every=None,
                 probe_times=None, norm_weights=None, max_flips=0, drift=False, stop_norm=0.0, stop_flips=0,
                 drift_limit=DEFAULT_DRIFT_LIMIT, chunk=CHUNK, progress=None, attitude=False, device="cpu",
                 growth_window=None, keep_probes=True, phase_window=None, keep_trajectory=True, parameters=None,
                 rtol=None, atol=None, times=None, max_steps=None):
    # size: 24 keywords, the engine's public call (tumble.run_ensemble); each is one observer or stop request a caller
    # may name, checked at once by _checked_arguments and passed on to run_planned (which packs them into _Observe).
    """Run an ensemble of spins and observe it on the fly.

    A built-in model or a :class:`tumble.System` in place of the body runs that system (as :func:`tumble.integrate`
    does: :func:`tumble.engine.system_runs.run_system`) and observes its final state and, with ``save_every``, its
    trajectory (``final`` and ``trajectory`` hold its states, shape (N, n) and (N, T, n)); the other observers are a
    rigid body's scene's and are refused for it.

    Parameters
    ----------
    body : Body, array_like (3,), model or System
    w0 : ndarray, shape (N, 3)
        Initial body-frame angular velocities, rad/s (validated by the caller); a system's states, (N, n).
    t_end, dt : float
        Horizon and step, s; ``dt`` must divide ``t_end`` into whole steps (the caller rounds).
    method : str
        ``"auto"`` (closed form when torque-free, else a kernel), ``"exact"`` or a kernel method name.
    torque : None, array_like (3,) or callable
        See :func:`torque_spec`.
    axis : int
        1-based spin axis of the scene: the transverse norm and the flips refer to it.
    final : bool
        Return the final state.
    save_every : int, optional
        Store the initial state, every ``save_every``-th step and the final state.
    probe_times : array_like, optional
        Times (s) at which to record the transverse norm; rounded to the nearest step.
    norm_weights : array_like (3,), optional
        Weights ``g`` of the transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` about ``axis`` (default: all 1, the
        Euclidean norm; also the norm ``stop_norm`` refers to).
    max_flips : int
        Record the first ``max_flips`` sign changes of the ``axis`` component.
    drift : bool
        Record the running maximum relative error of the energy and ``|L|**2``.
    stop_norm, stop_flips : float, int
        Early stop once a sample's transverse norm reached ``stop_norm`` (rad/s) and it flipped ``stop_flips``
        times; only honoured when neither the final state nor a trajectory is asked for.
    drift_limit : float
        Torque-free invariant drift that flags a sample as ``invariant drift`` (0: no flagging).
    chunk : int
        Samples per kernel call (progress and Ctrl-C granularity); on the device at least
        :data:`tumble.engine.device.LAUNCH_SAMPLES`.
    progress : bool, optional
        Show a progress bar; default: only when standard error is a terminal.
    attitude : bool
        Also integrate the orientation, stored with the trajectory (needs ``save_every``; no other observer).
        The body frame is the space frame at ``t = 0``.
    growth_window : tuple (saturation, min_points), optional
        Fit each sample's exponential growth rate from its norms at ``probe_times`` (equally spaced, at least 3)
        inside its linear regime, up to the first norm above ``saturation`` (rad/s), with at least ``min_points``
        points (:func:`tumble.kernels.fits.growth_fit`): ``growth`` holds ``(rate, points, first, last)``. On the
        device the fit runs in the kernel as the norms come, on the CPU on the probes after the run.
    keep_probes : bool
        With ``growth_window``: also return the probe norms (False: on the device they never leave it).
    phase_window : tuple (plane, weights, floor, max_step), optional
        Fit each sample's oscillation frequency from the phase of its stored transverse components (needs
        ``save_every``; the window is the whole stored trajectory): ``plane`` the two columns ``(b, c)`` (0-based),
        ``weights`` ``(g_b, g_c)``, ``floor`` the radius (rad/s) at or below which a sample has no signal,
        ``max_step`` the largest phase step that unwraps safely (rad), as :func:`tumble.kernels.fits.phase_fit`
        takes them: ``phase`` holds ``(frequency, radius, code)``. On the device the fit runs there, on the
        trajectory where the kernel stored it (the CPU's per-sample fit, :mod:`tumble.kernels.cuda.phase_fit`); on the CPU
        after the run.
    keep_trajectory : bool
        With ``phase_window``: also return the trajectory (False: on the device it never leaves it).
    parameters : mapping, optional
        A model's or System's parameters, by name, in place of its own.
    rtol, atol, times, max_steps
        ``method="dop853"`` only (``dt``: the first step, None: chosen), as :func:`tumble.integrate`: each sample its
        own steps to the tolerance; the final state and, with ``times``, the states there (``times`` and
        ``trajectory``) are what it observes; ``steps_taken`` counts the accepted steps, ``info`` the rejected ones.
    device : str
        ``"cpu"`` or ``"cuda"`` (:func:`tumble.engine.device.resolve_device`). On ``"cuda"`` today: every fixed-step
        method, a constant torque or a named profile, every observer (final state, trajectory, probe norms, flips,
        drift records, early stop), the growth and phase fits and the attitude; the closed form (``"exact"``, and
        ``"auto"`` torque-free) with every observer and the attitude (its flips are analytic in the set-up and timed
        on the host, from the set-up the CPU uses). A Python torque function is refused (``device 'cuda': ...``),
        never run on the CPU.

    Returns
    -------
    EnsembleResult

    Raises
    ------
    ValueError
        An argument that is not finite, of the wrong shape or out of range (named in the message), an unknown
        method, a method that cannot serve the request, a torque profile shorter than its steps.

    See Also
    --------
    tumble.integrate : The states at stored times, as a Dataset.
    tumble.measure : A scene: an ensemble run with the observers its fits need.

    Examples
    --------
    >>> import tumble
    >>> res = tumble.run_ensemble(tumble.Body(1.0, 2.0, 3.0), [[0.01, 1.0, 0.0]], 2.0, 0.01, method="rk4")
    >>> type(res).__name__, res.final.shape
    ('EnsembleResult', (1, 3))
    """
    device = resolve_device(device)  # once, here at the door: the runs below trust it
    asked = [name for name, value in (("probe_times", probe_times is not None), ("max_flips", max_flips),
                                      ("drift", drift), ("stop_norm", stop_norm), ("stop_flips", stop_flips),
                                      ("attitude", attitude), ("growth_window", growth_window is not None),
                                      ("phase_window", phase_window is not None), ("torque", torque is not None))
             if value]
    if method in registry.ERROR_CONTROLLED:
        return _error_controlled(body, w0, t_end, dt, final, save_every, torque, asked, parameters, device,
                                 (rtol, atol, times, max_steps))
    fixed_steps_only(method, dt, rtol, atol, times, max_steps)
    if added_tableau(method) and not is_system(body) and parameters is None:
        body = FreeBody(one_body(body))  # a tableau added at run time: the free body's rate in the per-sample loop
    if is_system(body):
        if asked:
            raise ValueError(f"run_ensemble of a model, a System or a tableau added at run time observes its final "
                             f"state and trajectory; {', '.join(asked)} observe a rigid body's scene with the built-in "
                             f"methods (remove them)")
        t_end, dt = _number(t_end, "t_end", low=0.0), _number(dt, "dt", positive=True)
        n_steps = int(np.rint(t_end / dt)) if t_end > 0.0 else 0
        result, _ = run_system(body, w0, t_end, n_steps, t_end / n_steps if n_steps else dt, method,
                               save_every=save_every, parameters=parameters, device=device)
        info = {"path": "system", "method": result.method, "dt": result.dt, "n_steps": result.n_steps,
                "system": result.name, "parameters": result.parameters, "samples": len(result.final),
                "device": device}
        return EnsembleResult(result.final if final else None, result.times, result.trajectory, None, None, None,
                              None, None, result.status, result.steps_taken, info)
    no_body_parameters(parameters)
    moments = one_body(body)
    w0, t_end, dt, probe_times, norm_weights = _checked_arguments(
        w0, t_end, dt, axis, save_every, probe_times, norm_weights, max_flips, stop_norm, stop_flips, drift_limit,
        chunk)
    n = len(w0)
    steps = float(np.rint(t_end / dt))  # a float (inf at worst): an absurd t_end / dt is refused by the cost bound
    torque = checked_torque(torque, dt)
    axis_is_intermediate = int(axis) - 1 == int(np.argsort(moments, kind="stable")[1])
    chosen, reason = choose_method(method, torque_free=torque.free, axis_is_intermediate=axis_is_intermediate,
                                   flips=max_flips)
    stored = _stored_per_sample(steps, save_every, probe_times, max_flips, drift, attitude)
    times = (steps // save_every + 2 if save_every else 1) + (0 if probe_times is None else len(probe_times))
    cost.refuse(cost.run_cost(n, 0 if chosen == "exact" else steps, stored, times=times, attitude=bool(attitude)),
                f"w0 ({n:,} spins) over t_end / dt = {steps:.3g} steps", device)
    if attitude and (not save_every or probe_times is not None or max_flips or drift or stop_norm or stop_flips):
        raise ValueError("attitude=True is stored with the trajectory: it needs save_every and no other observer")
    if growth_window is not None and (probe_times is None or len(probe_times) < 3):
        raise ValueError("growth_window fits the norms at probe_times: it needs at least 3 probe_times")
    phase_window = _checked_phase_window(phase_window, save_every, attitude)
    if device == "cuda":
        check_on_device(chosen, torque_fn=torque.fn)
    return run_planned(moments, w0, t_end, dt, method=chosen, reason=reason, torque=torque, axis=axis, final=final,
                       save_every=save_every, probe_times=probe_times, norm_weights=norm_weights,
                       max_flips=max_flips, drift=drift, stop_norm=stop_norm, stop_flips=stop_flips,
                       drift_limit=drift_limit, chunk=chunk, progress=progress, attitude=attitude, device=device,
                       growth_window=growth_window, keep_probes=keep_probes, phase_window=phase_window,
                       keep_trajectory=keep_trajectory)


def checked_torque(torque, dt=None):
    """The torque argument of a run (:func:`torque_spec`, which checks it) as the kernels take it, refused also where a
    step of ``dt`` s cannot resolve its sine or pulse (:func:`check_torque_step`; ``dt`` None: checked later, once
    the step is known). The check of every public call that steps a free body (:func:`run_ensemble`,
    :func:`tumble.integrate`, :func:`tumble.propagate`); a planned scene's torque is checked by its planner
    (:func:`tumble.measure.planning.check_torque_step`)."""
    torque = _Torque(*torque_spec(torque))
    if dt is not None:
        check_torque_step(torque, dt)
    return torque


def check_torque_step(torque, dt):
    """Refuse a torque (as :func:`checked_torque` returns it) whose sine or pulse a step of ``dt`` s cannot resolve
    (``registry.profile_step_problem``; issue 17, cause 8): a ``ValueError`` naming the profile's time scale."""
    if torque.params is not None:
        profile = registry.TORQUE_PROFILES[torque.kind]
        problem = registry.profile_step_problem(profile.name, float(torque.params[3]), dt)
        if problem:
            raise ValueError(f"torque {profile.time}: {problem}")


def run_planned(moments, w0, t_end, dt, *, method, torque, axis=1, final=True, save_every=None, probe_times=None,
                norm_weights=None, max_flips=0, drift=False, stop_norm=0.0, stop_flips=0,
                drift_limit=DEFAULT_DRIFT_LIMIT, chunk=CHUNK, progress=None, attitude=False, device="cpu",
                growth_window=None, keep_probes=True, phase_window=None, keep_trajectory=True, reason=""):
    # size: run_ensemble's observers, passed on as its callers name them (one keyword each, as run_ensemble takes)
    """:func:`run_ensemble` of arguments already checked, trusted as they come: what the public call runs after its
    checks, and what a planned scene runs (:func:`tumble.measure.running.scene_samples`: its method, device, torque
    and cost were checked when it was planned, :func:`tumble.measure.planning.scene_plan`).

    ``moments`` (3,) and ``w0`` (N, 3) float arrays; ``method`` the method that runs (``"auto"`` resolved:
    ``"exact"`` or a fixed-step method, with ``reason`` why, for ``info``); ``torque`` as :func:`checked_torque` returns
    it (or the tuple of :func:`torque_spec`); ``device`` resolved; ``phase_window`` as :func:`run_ensemble` checks it;
    the rest as :func:`run_ensemble` takes them. Nothing here raises for an argument.
    """
    torque = torque if isinstance(torque, _Torque) else _Torque(*torque)
    n = len(w0)
    n_steps = int(np.rint(t_end / dt))
    save = int(save_every or 0)
    times, probe_steps, probe_times = observation_times(t_end, dt, save, probe_times)
    if growth_window is not None:
        saturation, min_points = growth_window
        growth_window = (float(saturation), int(min_points),
                         float((probe_times[-1] - probe_times[0]) / (len(probe_times) - 1)))
    early = (stop_norm > 0 or stop_flips > 0) and not final and not save
    observe = _Observe(
        final=final, save=save, times=times, probe_steps=probe_steps, probe_times=probe_times, axis=int(axis) - 1,
        weights=np.ones(3) if norm_weights is None else np.asarray(norm_weights, dtype=float), max_flips=max_flips,
        drift=drift, attitude=attitude, stop_norm=stop_norm if early else 0.0, stop_flips=stop_flips if early else 0,
        drift_limit=drift_limit if torque.free else 0.0, growth=growth_window,
        keep_probes=keep_probes or growth_window is None, phase=phase_window,
        keep_trajectory=keep_trajectory or phase_window is None)
    if device == "cuda":
        chunk = max(chunk, LAUNCH_SAMPLES)
    info = {"path": "closed form" if method == "exact" else "fixed-step kernel", "method": method,
            "reason": reason, "dt": dt, "n_steps": n_steps, "torque": torque.text, "early_stop": early,
            "samples": n, "device": device}
    show = sys.stderr.isatty() if progress is None else progress
    started = time.perf_counter()
    bar = tqdm(total=n, unit="spins", desc=f"{method}") if show else contextlib.nullcontext(_NO_BAR)
    with bar as bar, _stop_between_chunks() as interrupted:

        def chunks():  # sample ranges, the bar advanced and Ctrl-C honoured between them
            for lo in range(0, n, chunk):
                if interrupted():
                    raise Interrupted(lo, n)
                hi = min(lo + chunk, n)
                yield lo, hi
                bar.update(hi - lo)
            if interrupted():  # pressed during the last chunk: the run stops all the same
                raise Interrupted(n, n)

        if method == "exact":
            result = _run_exact(moments, w0, t_end, observe, chunks(), device)
            info.update(sample_steps_computed=0, sample_steps_skipped=n * n_steps, jit_seconds=0.0)
            return _fit_phase(_fit_growth(result._replace(info=info), observe), observe)
        if attitude:
            result = _run_attitude(METHODS[method], moments, w0, dt, n_steps, observe, torque, chunks(), device)
            info.update(run_seconds=time.perf_counter() - started, sample_steps_computed=n * n_steps,
                        sample_steps_skipped=0)
            return result._replace(info=info)
        info["jit_seconds"] = _warm(method, torque, observe) if device == "cpu" else 0.0  # device: in run_seconds
        started = time.perf_counter()
        result = _run_kernel(METHODS[method], moments, w0, dt, n_steps, observe, torque, chunks(), device)
    steps_taken = result.steps_taken
    info.update(run_seconds=time.perf_counter() - started,
                sample_steps_computed=_block_steps(steps_taken, BLOCK if device == "cpu" else WARP),
                sample_steps_skipped=int(n * n_steps - steps_taken.sum()))
    return _fit_phase(_fit_growth(result._replace(info=info), observe), observe)


def _checked_phase_window(phase_window, save_every, attitude):
    """``run_ensemble``'s ``phase_window`` as ``((b, c), (g_b, g_c), floor, max_step)`` of ints and floats, or None;
    ValueError naming what is wrong."""
    if phase_window is None:
        return None
    if not save_every or attitude:
        raise ValueError("phase_window fits the phase of the stored trajectory: it needs save_every (and no attitude)")
    try:
        plane, weights, floor, max_step = phase_window
        plane = tuple(int(k) for k in plane)
        weights = tuple(float(g) for g in weights)
        floor, max_step = float(floor), float(max_step)
    except (TypeError, ValueError):
        raise ValueError(f"phase_window must be (plane (b, c), weights (g_b, g_c), floor, max_step), got "
                         f"{phase_window!r}") from None
    if len(plane) != 2 or plane[0] == plane[1] or not set(plane) <= {0, 1, 2}:
        raise ValueError(f"phase_window's plane must be two different columns of 0, 1, 2, got {plane}")
    if len(weights) != 2 or not all(math.isfinite(g) and g >= 0 for g in weights):
        raise ValueError(f"phase_window's weights must be two finite numbers >= 0, got {weights}")
    if not (math.isfinite(floor) and floor >= 0 and math.isfinite(max_step) and max_step > 0):
        raise ValueError(f"phase_window's floor must be >= 0 and max_step > 0, both finite, got {floor}, {max_step}")
    return plane, weights, floor, max_step


def _fit_phase(result, observe):
    """``result`` with its phase fit (``phase_window``): the kernels' fit of its trajectory where the run did not fit
    it already (the device fits where it stored it); the trajectory dropped unless kept."""
    if observe.phase is None:
        return result
    if result.phase is None:
        plane, weights, floor, max_step = observe.phase
        n = len(result.status)
        phase = np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)
        fits.phase_fit(np.ascontiguousarray(result.times[None, :]), np.zeros(n, dtype=np.int64), result.trajectory,
                       np.tile(np.array(plane, dtype=np.int64), (n, 1)), np.tile(np.array(weights), (n, 1)),
                       np.full(n, floor), max_step, *phase)
        result = result._replace(phase=phase)
    return result._replace(trajectory=result.trajectory if observe.keep_trajectory else None)


def run_scene_table(method, moments, w0, sizes, t_end, dt, *, axis, save_every=None, probe_times=None,
                    norm_weights=None, max_flips=0, stop_norm=None, torque=None, growth_window=None,
                    phase_window=None):
    # size: run_ensemble's observers of a scene, a row per scene: what a scan's planned scenes differ in
    """The samples of many planned scenes in one device launch: :func:`run_ensemble` on ``device="cuda"`` with a row
    per scene (:func:`tumble.kernels.cuda.rigid_body.run_scenes`), for a scan whose scenes are each too small to fill a GPU.

    Each scene is observed as ``run_ensemble(moments[k], w0 of scene k, t_end[k], dt[k], method=method,
    axis=axis[k], final=False, save_every=..., probe_times=..., norm_weights=..., max_flips=max_flips,
    stop_norm=stop_norm[k], stop_flips=max_flips, torque=torque, growth_window=(saturation[k], min_points),
    keep_probes=False, phase_window=..., keep_trajectory=False, device="cuda")`` observes it, with the same bits; the
    arguments come from planned scenes and are not checked again.

    Parameters
    ----------
    method : str
        A fixed-step method (every scene's).
    moments : ndarray, shape (S, 3)
    w0 : ndarray, shape (N, 3)
        The samples of every scene, scene after scene (``sizes`` of them each).
    sizes : array_like of int, shape (S,)
    t_end, dt : ndarray, shape (S,)
        A whole number of steps each.
    axis : ndarray of int, shape (S,)
        1-based.
    save_every : ndarray of int (S,), optional
        Stored states (a trajectory), giving every scene the same number of them.
    probe_times, norm_weights : ndarray (S, P), ndarray (S, 3), optional
        Probe norms (at ``P`` times each); with ``growth_window = (saturation (S,), min_points)`` fitted in the
        kernel, and not kept.
    max_flips : int
        Flips timed per sample (also the early stop's count, as a scene stops).
    stop_norm : ndarray (S,), optional
    torque
        As :func:`run_ensemble` (a constant or a named profile): the same for every scene.
    phase_window : tuple (plane (S, 2), weights (S, 2), floor (S,), max_step), optional
        With ``save_every``: each scene's :func:`run_ensemble` ``phase_window``, fitted on the device; the
        trajectories are then not kept.

    Returns
    -------
    list of EnsembleResult
        One per scene, as :func:`run_ensemble` returns it (``trajectory`` or ``phase``, ``flips``, ``growth``,
        ``status`` and ``steps_taken`` as asked; no probes).
    """
    count = len(sizes)
    torque = _Torque(*torque_spec(torque))
    n_steps = np.rint(np.asarray(t_end) / np.asarray(dt)).astype(np.int64)
    times, probe_rows, probe_step_rows, fit_h = [], [], [], np.zeros(count)
    for k in range(count):
        observed = observation_times(float(t_end[k]), float(dt[k]), None if save_every is None else int(save_every[k]),
                                     None if probe_times is None else probe_times[k])
        times.append(observed[0])
        probe_step_rows.append(np.zeros(0, dtype=np.int64) if observed[1] is None else observed[1])
        probe_rows.append(observed[2])
        if growth_window is not None:
            fit_h[k] = (observed[2][-1] - observed[2][0]) / (len(observed[2]) - 1)
    w = np.array(np.asarray(w0).T, order="C")
    observed = device_kernels().run_scenes(
        METHODS[method], w, sizes, moments, 0.0, dt, n_steps,
        save_every=np.zeros(count, np.int64) if save_every is None else np.asarray(save_every, np.int64),
        axis=np.asarray(axis, np.int64) - 1, norm_weights=norm_weights, probe_steps=np.stack(probe_step_rows),
        max_flips=max_flips, stop_norm=np.zeros(count) if stop_norm is None or save_every is not None else stop_norm,
        stop_flips=max_flips if save_every is None else 0,
        drift_limit=DEFAULT_DRIFT_LIMIT if torque.free else 0.0, torque_kind=torque.kind,
        torque_params=torque.params,
        growth_window=None if growth_window is None else (growth_window[0], int(growth_window[1]), fit_h),
        keep_probes=False, keep_saved=phase_window is None,
        phase_window=None if phase_window is None else (np.stack(times), *phase_window))
    results, lo = [], 0
    for k, size in enumerate(sizes):
        rows = slice(lo, lo + int(size))
        lo += int(size)
        steps_taken = observed.steps_taken[rows]
        info = {"path": "fixed-step kernel", "method": method, "dt": float(dt[k]), "n_steps": int(n_steps[k]),
                "torque": torque.text, "samples": int(size), "device": "cuda",
                "sample_steps_computed": _block_steps(steps_taken, WARP),
                "sample_steps_skipped": int(size * n_steps[k] - steps_taken.sum())}
        results.append(EnsembleResult(
            None, times[k], None if observed.saved is None else observed.saved[:, :, rows].transpose(2, 0, 1),
            probe_rows[k], None, None if observed.flips is None else observed.flips[rows],
            None if observed.flip_count is None else observed.flip_count[rows], None, observed.status[rows],
            steps_taken, info, growth=None if observed.growth is None else tuple(x[rows] for x in observed.growth),
            phase=None if observed.phase is None else tuple(x[rows] for x in observed.phase)))
    return results


def _fit_growth(result, observe):
    """``result`` with its growth fit (``growth_window``): the kernels' fit of its probes where the run did not fit
    them already (the device fits in the kernel); the probes dropped unless kept."""
    if observe.growth is None or result.growth is not None:
        return result
    saturation, min_points, _ = observe.growth
    norms = np.ascontiguousarray(result.probes)
    n, p = norms.shape
    rate, points, code = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int8)
    fits.growth_fit(np.ascontiguousarray(result.probe_times[None, :]), np.zeros(n, dtype=np.int64), norms,
                    np.full(n, saturation), min_points, rate, points, code)
    last = norms[np.arange(n), np.clip(points - 1, 0, p - 1)]
    return result._replace(growth=(rate, points, norms[:, 0].copy(), last),
                           probes=result.probes if observe.keep_probes else None)


class _NoBar:
    """The progress bar of a run that shows none (a disabled tqdm costs 25 us to make, a tenth of a small run)."""

    @staticmethod
    def update(n):
        pass


_NO_BAR = _NoBar()


class _Torque(NamedTuple):
    """A run's torque as :func:`torque_spec` gives it: the kernels' torque code, ``(N1, N2, N3, tau)`` or None,
    a jitted function or None, and its description."""

    kind: int
    params: np.ndarray | None
    fn: object
    text: str

    @property
    def free(self):
        return self.params is None and self.fn is None


class _Observe(NamedTuple):
    """What a run records and when a sample may stop, resolved once by :func:`run_planned` (stops already
    zeroed where they may not apply)."""

    final: bool
    save: int  # every save-th step stored (0: no trajectory)
    times: np.ndarray | None  # (T,), s, of the trajectory
    probe_steps: np.ndarray | None  # (P,) int
    probe_times: np.ndarray | None  # (P,), s
    axis: int  # 0-based
    weights: np.ndarray  # (3,) of the transverse norm
    max_flips: int
    drift: bool
    attitude: bool
    stop_norm: float
    stop_flips: int
    drift_limit: float
    growth: tuple | None  # (saturation, min_points, probe spacing s): fit the growth rate (growth_window)
    keep_probes: bool
    phase: tuple | None  # ((b, c), (g_b, g_c), floor, max_step): fit the phase of the trajectory (phase_window)
    keep_trajectory: bool


def _run_kernel(method, moments, w0, dt, n_steps, observe, torque, chunks, device="cpu"):
    # size: one more than the limit: the device, whose kernels take the CPU kernels' arguments
    """A fixed-step kernel over the samples, chunk by chunk, the observers' outputs gathered per sample."""
    step = run if device == "cpu" else stepper(device)
    # The device fits the growth in the kernel (the CPU fits its probes after the run, _fit_growth)
    fit = {} if device == "cpu" or observe.growth is None else dict(growth_window=observe.growth,
                                                                     keep_probes=observe.keep_probes)
    # and the phase where it stored the trajectory (the CPU fits the trajectory after the run, _fit_phase)
    if device != "cpu" and observe.phase is not None:
        fit.update(phase_window=(observe.times, *observe.phase), keep_saved=observe.keep_trajectory)
    n = len(w0)
    final_w = np.empty((n, 3)) if observe.final else None
    trajectory = None
    if observe.save and (observe.keep_trajectory or "phase_window" not in fit):
        trajectory = np.empty((n, len(observe.times), 3))
    probes = None
    if observe.probe_steps is not None and (observe.keep_probes or "growth_window" not in fit):
        probes = np.empty((n, len(observe.probe_steps)))
    growth = None
    if "growth_window" in fit:
        growth = (np.empty(n), np.empty(n, dtype=np.int64), np.empty(n), np.empty(n))
    phase = (np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)) if "phase_window" in fit else None
    flips = np.empty((n, observe.max_flips)) if observe.max_flips else None
    flip_count = np.empty(n, dtype=np.int64) if observe.max_flips else None
    drifts = np.empty((n, 2)) if observe.drift else None
    status = np.empty(n, dtype=np.int8)
    steps_taken = np.empty(n, dtype=np.int64)
    for lo, hi in chunks:
        state = np.array(w0[lo:hi].T, order="C")
        observed = step(method, state, moments, 0.0, dt, n_steps, save_every=observe.save, axis=observe.axis,
                        norm_weights=observe.weights, probe_steps=observe.probe_steps, max_flips=observe.max_flips,
                        drift=observe.drift, stop_norm=observe.stop_norm, stop_flips=observe.stop_flips,
                        drift_limit=observe.drift_limit, torque_kind=torque.kind, torque_params=torque.params,
                        torque_fn=torque.fn, **fit)
        for gathered, parts in ((growth, observed.growth), (phase, observed.phase)):
            if gathered is not None:
                for whole, part in zip(gathered, parts):
                    whole[lo:hi] = part
        if final_w is not None:
            final_w[lo:hi] = state.T
        if trajectory is not None:
            trajectory[lo:hi] = observed.saved.transpose(2, 0, 1)
        if probes is not None:
            probes[lo:hi] = observed.probes.T
        if flips is not None:
            flips[lo:hi] = observed.flips
            flip_count[lo:hi] = observed.flip_count
        if drifts is not None:
            drifts[lo:hi] = observed.drift.T
        status[lo:hi] = observed.status
        steps_taken[lo:hi] = observed.steps_taken
    return EnsembleResult(final_w, observe.times, trajectory, observe.probe_times, probes, flips, flip_count, drifts,
                          status, steps_taken, {}, growth=growth, phase=phase)


def _block_steps(steps_taken, block=BLOCK):
    """Sample-steps the kernel actually computed: every sample of a block steps until the block's last one
    stops (the SIMD lanes of a CPU block, :data:`tumble.kernels.BLOCK` samples, move together; on the device, the
    :data:`tumble.engine.device.WARP` threads of a warp)."""
    n = len(steps_taken)
    if n == 0:
        return 0
    blocks = np.zeros(-(-n // block) * block, dtype=np.int64)
    blocks[:n] = steps_taken
    sizes = np.minimum(block, n - np.arange(0, n, block))
    return int(np.dot(sizes, blocks.reshape(-1, block).max(axis=1)))


def _run_attitude(method, moments, w0, dt, n_steps, observe, torque, chunks, device="cpu"):
    # size: one more than the limit: the device, whose attitude kernels take the CPU kernels' arguments
    """Angular velocity and attitude by a fixed-step method, chunk by chunk, from the identity attitude, on
    ``device``."""
    step = run_attitude if device == "cpu" else device_attitude().run_attitude
    n = len(w0)
    trajectory = np.empty((n, len(observe.times), 3))
    quaternion = np.empty((n, len(observe.times), 4))
    status = np.empty(n, dtype=np.int8)
    for lo, hi in chunks:
        identity = np.zeros((hi - lo, 4))
        identity[:, 0] = 1.0
        trajectory[lo:hi], quaternion[lo:hi], status[lo:hi] = step(
            method, w0[lo:hi], identity, moments, 0.0, dt, n_steps, save_every=observe.save,
            torque_kind=torque.kind, torque_params=torque.params, torque_fn=torque.fn)
    final_w = trajectory[:, -1].copy() if observe.final else None
    return EnsembleResult(final_w, observe.times, trajectory, None, None, None, None, None, status,
                          np.full(n, n_steps, dtype=np.int64), {}, quaternion)


def _run_exact(moments, w0, t_end, observe, chunks, device="cpu"):
    """The closed form, chunk by chunk: each chunk's per-sample set-up computed once and evaluated at every time
    the observers ask for (final state, trajectory, probe times, attitude) and for the flips. On the device
    (:func:`tumble.physics.exact.omega_on_device`, :func:`~tumble.physics.exact.attitude_on_device`,
    :func:`~tumble.physics.exact.phase_fit_rows_on_device`) each evaluation is set up anew, one thread per sample.
    The flips are analytic in the set-up (the first flip time and the spacing, :func:`tumble.physics.exact.first_flips`,
    :func:`~tumble.physics.exact.flip_spacings`): timed on the host on either device from the same set-up
    (:func:`tumble.physics.exact.solve_rows`), so they are the CPU's bit for bit."""
    n = len(w0)
    b, c = (observe.axis + 1) % 3, (observe.axis + 2) % 3
    times = observe.times
    final_w = np.empty((n, 3)) if observe.final else None
    phase = None
    if device != "cpu" and observe.phase is not None:  # evaluated and fitted on the device, where the states are
        phase = (np.empty(n), np.empty(n), np.empty(n, dtype=np.int8))
    trajectory = None
    if times is not None and (observe.keep_trajectory or phase is None):
        trajectory = np.empty((n, len(times), 3))
    probes = np.empty((n, len(observe.probe_times))) if observe.probe_times is not None else None
    flips = np.empty((n, observe.max_flips)) if observe.max_flips else None
    flip_count = np.empty(n, dtype=np.int64) if observe.max_flips else None
    drifts = np.empty((n, 2)) if observe.drift else None
    quaternion = np.empty((n, len(times), 4)) if observe.attitude else None
    for lo, hi in chunks:
        w = w0[lo:hi]
        if quaternion is not None:
            quaternion[lo:hi] = (exact.attitude(moments, w, times) if device == "cpu" else
                                 exact.attitude_on_device(moments, w, times))
        sol = None
        if device == "cpu" or flips is not None:  # the flips are analytic in the set-up: on the host on either device
            sol = exact.solve_rows(np.broadcast_to(moments, w.shape), w)
        if device == "cpu":
            row = np.zeros(hi - lo, dtype=np.int64)

            def at(grid):  # (n, T, 3) at the times grid (T,)
                return exact.omega_rows(sol, grid[None, :], row)
        else:
            def at(grid):
                return exact.omega_on_device(moments, w, grid)
        if final_w is not None or drifts is not None:
            end = at(np.array([t_end]))[:, 0]
            if final_w is not None:
                final_w[lo:hi] = end
            if drifts is not None:
                e0, l0 = 0.5 * (moments * w**2).sum(1), ((moments * w) ** 2).sum(1)
                e1, l1 = 0.5 * (moments * end**2).sum(1), ((moments * end) ** 2).sum(1)
                drifts[lo:hi] = np.stack([np.abs(e1 / e0 - 1), np.abs(l1 / l0 - 1)], axis=1)
        if trajectory is not None:
            trajectory[lo:hi] = at(times)
        if phase is not None:
            plane, weights, floor, max_step = observe.phase
            k = hi - lo
            fitted = exact.phase_fit_rows_on_device(moments[None, :], w, times[None, :], np.zeros(k, dtype=np.int64),
                                                    np.tile(np.array(plane, dtype=np.int64), (k, 1)),
                                                    np.tile(np.array(weights), (k, 1)), np.full(k, floor), max_step)
            for whole, part in zip(phase, fitted):
                whole[lo:hi] = part
        if probes is not None:
            probed = at(observe.probe_times)
            probes[lo:hi] = np.sqrt(observe.weights[b] * probed[..., b] ** 2 + observe.weights[c] * probed[..., c] ** 2)
        if flips is not None:
            flips[lo:hi], flip_count[lo:hi] = flip_times(exact.first_flips(sol), exact.flip_spacings(sol),
                                                         observe.max_flips, t_end)
    status = np.full(n, STATUS_OK, dtype=np.int8)
    if final_w is not None:
        status[~np.all(np.isfinite(final_w), axis=1)] = STATUS_NONFINITE
    return EnsembleResult(final_w, times, trajectory, observe.probe_times, probes, flips, flip_count, drifts, status,
                          np.zeros(n, dtype=np.int64), {}, quaternion, phase=phase)
