"""Error-controlled runs: ``method="dop853"`` for the free body, a built-in model or a user's System.

Each sample takes its own steps to the tolerance ``rtol``, ``atol`` (scalars, or one value per state component) and
its states at the output times are read off the method's dense output of order 7
(:mod:`tumble.kernels.loops.adaptive_loop`). :func:`run_adaptive` checks the arguments once and runs the kernel; a
``Body`` runs as :class:`tumble.models.FreeBody` (the free body's rate in the per-sample loop), a built-in model with
its kernels' own rate (:func:`tumble.kernels.rate_sample`), a System with its rate, probed first as every run probes
it. The CPU runs one share of the samples per thread (blocks of samples vectorised across them where the system has a
block step); the device one thread per sample (:mod:`tumble.kernels.cuda.adaptive`).
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np

from .. import registry
from ..kernels import adaptive_blocks, adaptive_loop, device_adaptive_loop, rate_sample, system_steps
from ..physics.system import System, with_parameters
from . import cost
from .system_runs import block_code, compiled, initial_states, model_parameters, probe, state_units, system_name

__all__ = ["AdaptiveRun", "Surface", "DEFAULT_ATOL", "DEFAULT_RTOL", "FLAG_MEANINGS", "FLAG_VALUES", "MAX_STEPS", "MIN_RTOL",
           "checked_horizon", "checked_scalars", "fixed_steps_only", "no_save_every", "output_times", "run_adaptive", "run_attrs", "run_variables", "tolerance_attrs", "tolerances",
           "warn_stops"]

#: The tolerances of a run that names none: near the double's limit for the smooth motions tumble studies.
DEFAULT_RTOL, DEFAULT_ATOL = 1e-10, 1e-12

#: The smallest ``rtol`` a run takes: below it the error estimate is round-off (Hairer's dop853 asks rtol > 10 uround
#: of its ``atol + rtol |y|``; SciPy raises rtol to 100 eps = 2.2e-14).
MIN_RTOL = 1e-14

#: Steps (accepted and rejected) a sample may take before it stops with "step limit" (Hairer's ``nmax`` is 1e5).
MAX_STEPS = 1_000_000


class AdaptiveRun(NamedTuple):
    """What :func:`run_adaptive` returns (arrays per sample first)."""

    final: np.ndarray  # (N, n): the final states (or the states the samples stopped with)
    times: np.ndarray  # (T,), s: the output times
    states: np.ndarray  # (N, T, n): the states at the output times
    status: np.ndarray  # (N,) int8, codes of registry.ADAPTIVE_STATUSES
    steps: np.ndarray  # (N,) int64: accepted steps
    rejected: np.ndarray  # (N,) int64: rejected steps
    rtol: np.ndarray  # (n,)
    atol: np.ndarray  # (n,)
    parameters: dict  # name -> value, as run
    name: str  # the system's name (a model's kind)
    components: tuple  # names of the state's components
    units: tuple  # their units ("" where a System does not say)
    t_end: float  # s
    stopped: np.ndarray  # (N,), s: the time each sample reached (t_end, unless it stopped)
    crossing_times: np.ndarray  # (N, most), s: a section's crossings (most = 0: no section), NaN past each count
    crossing_states: np.ndarray  # (N, most, n)
    crossings: np.ndarray  # (N,) int64: each sample's count
    path: str = "vectorised blocks"  # how the samples ran: "vectorised blocks", "per-sample loop", "one sample per
    # device thread"


class Surface(NamedTuple):
    """A section's surface, checked (:func:`tumble.engine.sections.section`): ``g = y[component] − value``, or a
    user's ``g(t, y, p)`` (``function``, compiled); the crossings counted in ``direction`` (1 up, −1 down, 0 both),
    at most ``most`` per sample."""

    component: int
    value: float
    function: object  # None, or the user's g
    direction: int
    most: int


def _tolerance(value, default, name, components):
    """``value`` (None, a number, or one per component) as a float64 array (n,), each finite and > 0."""
    n = len(components)
    if value is None:
        return np.full(n, default)
    if type(value) is float and math.isfinite(value) and value > 0.0:  # the common case, without numpy's checks
        return np.full(n, value)
    try:
        given = np.asarray(value)
        if given.dtype.kind not in "iuf":  # a string, a bool or an object is not a tolerance, whatever it converts to
            raise TypeError
        array = np.array(given, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number or one number per state component ({', '.join(components)}), "
                         f"got {value!r}") from None
    if array.ndim == 0:
        array = np.full(n, float(array))
    if array.shape != (n,):
        raise ValueError(f"{name} must be a number or one number per state component ({n}: {', '.join(components)}), "
                         f"got shape {np.shape(value)}")
    if not np.all(np.isfinite(array)) or np.any(array <= 0.0):
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return np.ascontiguousarray(array)


def tolerances(rtol, atol, components):
    """``(rtol, atol)`` checked, as arrays (n,): positive, finite, ``rtol >= MIN_RTOL``."""
    rtol = _tolerance(rtol, DEFAULT_RTOL, "rtol", components)
    atol = _tolerance(atol, DEFAULT_ATOL, "atol", components)
    if min(rtol.tolist()) < MIN_RTOL:  # a few numbers: Python's min, not a numpy reduction (a tenth of the time)
        raise ValueError(f"rtol must be >= {MIN_RTOL:g}: below it a double's rounding is the error estimate (the "
                         f"tolerance cannot be met, and the step underflows), got {float(rtol.min()):g}")
    return rtol, atol


def output_times(times, t_end):
    """The output times (T,), s: ``[t_end]`` for None; else finite, increasing, within ``[0, t_end]``."""
    if times is None:
        return np.array([t_end])
    try:
        array = np.array(times, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"times must be an array of numbers (s), got {times!r}") from None
    if len(array) == 0 or not np.all(np.isfinite(array)):
        raise ValueError(f"times must be one or more finite numbers (s), got {times!r}")
    if np.any(np.diff(array) <= 0.0):
        raise ValueError("times must be increasing")
    if array[0] < 0.0 or array[-1] > t_end:
        raise ValueError(f"times must lie within [0, t_end] = [0, {t_end!r}] s, got {float(array[0])!r} ... "
                         f"{float(array[-1])!r}")  # repr: 0.30000000000000004 is not 0.3
    return np.ascontiguousarray(array)


def checked_horizon(t_end):
    """``t_end`` (s) as a float, finite and >= 0."""
    try:
        horizon = float(t_end)
    except (TypeError, ValueError):
        raise ValueError(f"t_end must be a number (s), got {t_end!r}") from None
    if not (math.isfinite(horizon) and horizon >= 0.0):
        raise ValueError(f"t_end must be finite and >= 0, got {t_end!r}")
    return horizon


def fixed_steps_only(method, dt, rtol, atol, times, max_steps):
    """A fixed-step ``method`` takes ``dt`` (and ``save_every``), never a tolerance's arguments."""
    given = [name for name, value in (("rtol", rtol), ("atol", atol), ("times", times), ("max_steps", max_steps))
             if value is not None]
    if given:
        raise ValueError(f"{', '.join(given)}: for an error-controlled run (method='dop853'); method {method!r} takes a "
                         f"fixed step dt and save_every")
    if dt is None:
        raise ValueError(f"dt (s) is required for the fixed-step method {method!r}; an error-controlled run names "
                         f"method='dop853' and a tolerance (rtol, atol) instead")


def no_save_every(save_every):
    """An error-controlled run gives its outputs at times, never every so many steps."""
    if save_every is not None:
        raise ValueError("save_every counts fixed steps; method 'dop853' gives its outputs at times=[...] (s), read "
                         "off its dense output")


def checked_scalars(t_end, first_step, max_steps):
    """``(t_end, first step (0: chosen), max_steps)`` of an error-controlled run, checked (one line each)."""
    t_end = checked_horizon(t_end)
    h0 = 0.0
    if first_step is not None:
        try:
            h0 = float(first_step)
        except (TypeError, ValueError):
            raise ValueError(f"dt (the first step of an error-controlled run) must be a number (s), got "
                             f"{first_step!r}") from None
        if not (math.isfinite(h0) and h0 > 0.0):
            raise ValueError(f"dt (the first step of an error-controlled run) must be finite and > 0, or None (chosen), "
                             f"got {first_step!r}")
    limit = MAX_STEPS if max_steps is None else max_steps
    if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
        raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    return t_end, h0, int(limit)


#: Built-in models' error-controlled drivers, by (system module, rate, the user's surface or None): each a driver of its
#: model's own attempt (:func:`tumble.kernels.loops.adaptive_blocks.for_model`, cached on disk with the component
#: surface).
_MODEL_KERNELS = {}


def _kernel(system, surface, parameters):
    """``(drive, p, a, path)``: the CPU driver of ``system``'s error-controlled run (with the user's ``surface``
    function, or the component surface for None), its per-sample rate's parameter array (None: a System's own values),
    the block steps' constants and how its samples run: a built-in model's block driver of its own attempt
    (:func:`tumble.kernels.loops.adaptive_blocks.for_model`, cached on disk but over a user's surface), a System's made once
    per process and kept with its compiled rate, stepping a block's lanes at once where its rate has a scalar form
    (:func:`tumble.engine.system_runs.block_code`), else one sample at a time."""
    if isinstance(system, System):
        made = compiled(system).methods
        key = adaptive_loop.DOP853.name if surface is None else (adaptive_loop.DOP853.name, surface)
        code = block_code(system, registry.AUTO_STEPPING)  # its scalar form (None: it has none, said once)
        if key not in made:
            rate = compiled(system).rate
            keyed = system_steps.functions_key(system.rate) if surface is None else None
            keyed = None if keyed is None else f"sample_{keyed}"
            made[key] = (adaptive_loop.make_dop853_driver(adaptive_loop.make_dop853_sample(rate, surface, keyed), keyed)
                         if code is None else
                         adaptive_blocks.specialised(*system_steps.block_attempt(code), rate, surface,
                                                     f"{code:x}" if surface is None and system_steps.cacheable(code)
                                                     else None))
        a = np.zeros(0) if code is None else system_steps.block_constants(system.parameter_values(parameters))
        return made[key], None, a, "per-sample loop" if code is None else "vectorised blocks"
    p = model_parameters(system)
    model = registry.model_kind(system.kind)
    key = (model.equations_module, model.rate, surface)
    if key not in _MODEL_KERNELS:
        _MODEL_KERNELS[key] = adaptive_blocks.for_model(*key)
    return _MODEL_KERNELS[key], p, p[1:], "vectorised blocks"  # the attempt's constants: the parameters after the code


#: (rate, surface, state size, parameters) -> the device's driver of an error-controlled run (made once per process).
_DEVICE_KERNELS = {}


def _device_kernel(system, surface, n_state):
    """``(drive, p, a)`` as :func:`_kernel`'s, for the device: one thread per sample running the per-sample loop
    (:mod:`tumble.kernels.cuda.adaptive`), the rate a System's or the models' (:func:`tumble.kernels.rate_sample`)."""
    if isinstance(system, System):
        rate, p = compiled(system).rate, None
        n_parameters = len(system.parameters)
    else:
        rate, p = rate_sample, model_parameters(system)
        n_parameters = len(p)
    key = (rate, surface, n_state, n_parameters)
    if key not in _DEVICE_KERNELS:
        cuda = device_adaptive_loop()
        kernel = cuda.make_kernel(adaptive_loop.make_dop853_sample(rate, surface), n_state, n_parameters)
        _DEVICE_KERNELS[key] = lambda *arguments: cuda.run(kernel, *arguments)
    return (lambda y, p, a, *rest: _DEVICE_KERNELS[key](y, p, *rest)), p, np.zeros(0)


def run_adaptive(system, y0, t_end, *, times=None, rtol=None, atol=None, first_step=None, max_steps=None,
                 parameters=None, device="cpu", y0_name="y0", surface=None, compiled_surface=None):
    # size: the run's arguments, each checked once, and the run
    """Integrate an ensemble of ``system`` (a built-in model or a :class:`System`) with DOP853 to a tolerance.

    Parameters
    ----------
    system : Model or System
    y0 : array_like, shape (N, n) or (n,)
        Initial states.
    t_end : float
        Horizon, s (>= 0).
    times : array_like, optional
        Output times, s, increasing within ``[0, t_end]`` (None: ``t_end`` alone).
    rtol, atol : float or array_like (n,), optional
        Relative and absolute tolerance of each step's error estimate (None: :data:`DEFAULT_RTOL`,
        :data:`DEFAULT_ATOL`); ``rtol >= MIN_RTOL``.
    first_step : float, optional
        The first step, s (None: Hairer's choice).
    max_steps : int, optional
        Steps a sample may take (None: :data:`MAX_STEPS`).
    parameters : mapping, optional
        Values in place of the system's own parameters, by name.
    device : str
        Resolved by the caller: ``"cpu"``, or ``"cuda"`` (one thread per sample).
    y0_name : str
        What a message calls ``y0`` (``"w0"``: a free body's spins).
    surface : Surface, optional
        A section's surface, checked (None: no section).
    compiled_surface : function, optional
        The user's ``g`` as the kernel calls it (``surface(t, y, p, component, value)``), when ``surface`` has one.

    Returns
    -------
    AdaptiveRun, and whether ``y0`` was a single state.

    Raises
    ------
    ValueError
        Any argument out of its range (one line naming it), a rate numba cannot compile or that misbehaves at the
        initial states.
    """
    system, values = with_parameters(system, parameters)
    t_end, h0, limit = checked_scalars(t_end, first_step, max_steps)
    components = system.spec.state
    rtol, atol = tolerances(rtol, atol, components)
    marks = output_times(times, t_end)
    y, single = initial_states(system, y0, y0_name)
    cost.refuse(cost.run_cost(len(y), 0, len(marks) * y.shape[1] + 2 * y.shape[1]),
                f"y0 ({len(y):,} states) at {len(marks):,} output times", device)
    most = surface.most if surface is not None else 0
    if most:
        cost.refuse(cost.run_cost(len(y), 0, most * (y.shape[1] + 1)), f"y0 ({len(y):,} states) and max_crossings = "
                    f"{most:,}", device)
    own = system.parameter_values(parameters) if isinstance(system, System) else None
    if own is not None:
        probe(system, y, own, 0.0)  # before its kernels are looked up
    drive, p, a, path = (_kernel(system, compiled_surface, parameters) if device == "cpu" else
                         (*_device_kernel(system, compiled_surface, y.shape[1]), "one sample per device thread"))
    p = own if own is not None else p
    state = y  # initial_states made it: a fresh contiguous copy, which the run overwrites with the final states
    n = y.shape[1]
    out = np.empty((len(y), len(marks), n))
    section = np.array([surface.component, surface.value, surface.direction, most] if most else [0.0, 0.0, 0.0, 0.0])
    crossing_times = np.full((len(y), most), np.nan)
    crossing_states = np.full((len(y), most, n), np.nan)
    status = np.zeros(len(y), dtype=np.int8)
    counts = np.zeros((len(y), 3), dtype=np.int64)
    stopped = np.zeros(len(y))
    drive(state, p, a, 0.0, t_end, h0, rtol, atol, limit, marks, out, section, crossing_times, crossing_states,
          status, counts, stopped)
    return AdaptiveRun(state, marks, out, status, counts[:, 0].copy(), counts[:, 1].copy(), rtol, atol, values,
                       system_name(system), components, state_units(system), t_end, stopped, crossing_times,
                       crossing_states, counts[:, 2].copy(), path), single


#: Each status's name as a flag meaning (``status`` of an error-controlled run's Dataset).
FLAG_VALUES = np.arange(len(registry.ADAPTIVE_STATUSES), dtype=np.int8)
FLAG_MEANINGS = " ".join(s.name.replace(" ", "_") for s in registry.ADAPTIVE_STATUSES)


def warn_stops(status, total, name, stacklevel, kept="their later states are the ones they stopped with"):
    """One warning saying how many samples of ``name`` stopped before ``t_end``, by status (none when every sample
    ran to the end), and what they ``kept``."""
    stopped = status != registry.STATUS_OK
    if stopped.any():
        counts = {registry.ADAPTIVE_STATUSES[code].name: int(np.count_nonzero(status == code))
                  for code in np.unique(status[stopped])}
        warnings.warn(f"{int(stopped.sum())} of {total} samples of {name!r} stopped before t_end "
                      f"({', '.join(f'{n} {what}' for what, n in counts.items())}; status says which, {kept})",
                      RuntimeWarning, stacklevel=stacklevel + 1)


def run_variables(run):
    """The Dataset variables every error-controlled run's result holds: each sample's ``status``, ``steps`` and
    ``rejected_steps`` (:func:`tumble.engine.integration.indexed_dataset`'s form)."""
    return {
        "status": ("sample", run.status, {"long_name": "sample status", "flag_values": FLAG_VALUES.copy(),
                                          "flag_meanings": FLAG_MEANINGS}),
        "steps": ("sample", run.steps, {"long_name": "accepted steps"}),
        "rejected_steps": ("sample", run.rejected, {"long_name": "rejected steps (error above the tolerance)"}),
    }


def run_attrs(run):
    """The attributes every error-controlled run's result holds: the method, its order, ``rtol`` and ``atol`` (a
    number where every component has the same), ``t_end``."""
    return {**tolerance_attrs(run), "t_end": run.t_end}


def tolerance_attrs(run):
    """The method, its order, ``rtol`` and ``atol`` (a number where every component has the same) of a run with
    ``rtol`` and ``atol`` arrays."""
    tolerance = {key: (float(value[0]) if np.all(value == value[0]) else value.copy())
                 for key, value in (("rtol", run.rtol), ("atol", run.atol))}
    return {"method": adaptive_loop.DOP853.name, "order": adaptive_loop.DOP853.order, **tolerance}
