"""``tumble.section``: the Poincaré surface of section of an ensemble, error-controlled.

Two kinds of section, each sample its own:

* a **surface** ``g(t, y) = 0``: a component and a value (``("w2", 0.0)``: ``g = w2 − 0``), or a user's ``g(t, y, p)``
  (plain Python that numba compiles, returning a number). A crossing is a sign change of ``g`` over an accepted step of
  DOP853, in ``direction`` (1: ``g`` rising through 0, −1: falling, 0: both), located on the step's dense output of
  order 7 by a bracketing root finder to a few ulps of ``t`` (:mod:`tumble.kernels.loops.adaptive_loop`); a sample
  stops once it has ``max_crossings``.
* the **stroboscopic** section: the states at ``t = phase + k period``, ``k = 1, 2, ...`` within ``t_end`` (at most
  ``max_crossings``), read off the same dense output.

The result is a Dataset over ``(sample, crossing)``: ``time`` (s), ``state`` (its components) and each sample's
``count``, NaN past it; with the run's ``status``, ``steps`` and ``rejected_steps``.
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from .. import registry
from ..kernels import adaptive_loop, sample_loop, system_steps
from ..physics.bodies import one_body
from ..physics.models import FreeBody
from .adaptive_runs import (DEFAULT_ATOL, DEFAULT_RTOL, Surface, checked_horizon, run_adaptive, run_attrs,
                            run_variables, warn_stops)
from .device import resolve_device
from .system_runs import changed_reads, initial_states, is_system, model_parameters, system_name, warn_caller

__all__ = ["section"]

#: A user's surface -> its compiled ``g``, the kernel's surface over it and what ``g`` read then (made once per process
#: and kept with ``g``; again when what it reads changes).
_SURFACES = weakref.WeakKeyDictionary()

_SURFACE_SIGNATURE = sample_loop.RATE_SIGNATURE[:3]  # g(t, y, p)


def _compiled_surface(g, owner):
    """``(g compiled, the kernel's surface)``: ``g(t, y, p)`` compiled once (one line naming ``owner`` when numba cannot
    compile it, or when it returns no number), and again where a number, array or function it reads from its module or
    closure has changed since (numba compiles those in as constants), which a warning says."""
    reads = system_steps.reads_by_name(g)  # None: what it reads cannot be told
    made = _SURFACES.get(g)
    if made is None or (reads is not None and reads != made[2]):
        compiled = sample_loop.compile_function(g, _SURFACE_SIGNATURE, owner, "surface g(t, y, p)")
        returns = compiled.nopython_signatures[0].return_type
        if not isinstance(returns, (sample_loop.types.Float, sample_loop.types.Integer)):
            raise ValueError(f"{owner}: surface g(t, y, p) must return a number (a float), returns {returns}")
        if made is not None and made[2] is not None:
            warn_caller(f"{owner}: {changed_reads(made[2], reads)}, read by surface g, changed since it was compiled: "
                        f"compiled again (numba compiles a module's names in as constants)")
        _SURFACES[g] = made = (compiled, adaptive_loop.make_user_surface(compiled), reads)
    return made[:2]


def _surface(system, surface, direction, max_crossings):
    """``(Surface, the kernel's surface function or None, a description)``: ``surface`` checked against ``system``."""
    owner = f"system {system_name(system)!r}"
    if callable(surface):
        compiled, kernel = _compiled_surface(surface, owner)
        return (Surface(0, 0.0, compiled, direction, max_crossings), kernel,
                f"g = 0, g: {getattr(surface, '__name__', 'a function')}")
    names = system.spec.state
    if not (isinstance(surface, (tuple, list)) and len(surface) == 2):
        raise ValueError(f"surface must be (component, value), a component of {', '.join(names)} and the value it "
                         f"crosses, or a function g(t, y, p); got {surface!r}")
    component, value = surface
    if isinstance(component, str):
        if component not in names:
            raise ValueError(f"surface: component {component!r} is not one of {', '.join(names)}")
        index = names.index(component)
    elif isinstance(component, (int, np.integer)) and not isinstance(component, bool) and 0 <= component < len(names):
        index = int(component)
    else:
        raise ValueError(f"surface: component must be one of {', '.join(names)} (or its index 0 ... "
                         f"{len(names) - 1}), got {component!r}")
    try:
        level = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"surface: the value must be a number, got {value!r}") from None
    if not math.isfinite(level):
        raise ValueError(f"surface: the value must be finite, got {value!r}")
    return Surface(index, level, None, direction, max_crossings), None, f"{names[index]} = {level:g}"


def _checked(direction, max_crossings, method, surface, period, phase):
    if method not in registry.ERROR_CONTROLLED:
        raise ValueError(f"method must be {' or '.join(map(repr, registry.ERROR_CONTROLLED))} (a section reads its "
                         f"crossings off the dense output of an "
                         f"error-controlled run), got {method!r}")
    if (surface is None) == (period is None):
        raise ValueError("give a surface (a component and a value, or g(t, y, p)) or a period (the stroboscopic "
                         "section), one of them" + (", not both" if surface is not None else ""))
    if isinstance(direction, bool) or direction not in (-1, 0, 1):
        raise ValueError(f"direction must be 1 (g rising through 0), -1 (falling) or 0 (both), got {direction!r}")
    if isinstance(max_crossings, bool) or not isinstance(max_crossings, (int, np.integer)) or max_crossings < 1:
        raise ValueError(f"max_crossings must be an integer >= 1, got {max_crossings!r}")
    if surface is not None and phase != 0.0:
        raise ValueError(f"phase is the stroboscopic section's (with a period), not a surface's, got {phase!r}")
    if period is not None and direction != 1:
        raise ValueError(f"direction counts a surface's crossings, not a period's states, got {direction!r}")
    if period is not None:
        for name, value, low in (("period", period, 0.0), ("phase", phase, None)):
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ValueError(f"{name} must be a number (s), got {value!r}") from None
            if not math.isfinite(number) or (low is not None and number <= low) or (low is None and number < 0.0):
                raise ValueError(f"{name} must be finite and {'> 0' if low is not None else '>= 0'}, got {value!r}")


def section(system, y0, t_end, *, surface=None, period=None, phase=0.0, direction=1, max_crossings=1000,
            method=registry.ERROR_CONTROLLED[0], rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, dt=None, max_steps=None,
            parameters=None, device="cpu"):
    # size: the contract's arguments (DESIGN.md "Tolerance and sections"), each checked once
    """The Poincaré section of an ensemble: where each sample crosses a surface, or its states once per period.

    Parameters
    ----------
    system : Body, array_like (3,), model or System
        The free body (its moments, torque-free), a built-in model (:mod:`tumble.models`) or a user's
        :class:`tumble.System`.
    y0 : array_like, shape (N, n) or (n,)
        Initial states (a free body's spins, rad/s).
    t_end : float
        Horizon, s.
    surface : (component, value) or callable, optional
        ``g = y[component] − value`` (a component's name or index), or ``g(t, y, p) -> float`` (plain Python that
        numba compiles: ``y`` the state; ``p`` a System's parameters' values in its order, a built-in model's
        kernel constants, which a surface should not need). A number it reads from its module is compiled in:
        changed, ``g`` is compiled again (a warning says so).
    period, phase : float, optional
        The stroboscopic section instead: the states at ``phase + k period`` (s), ``k >= 1``, within ``t_end``
        (the run ends at the last of them).
    direction : {1, -1, 0}
        Count the crossings where ``g`` rises through 0 (1), falls (-1), or both (0).
    max_crossings : int
        Crossings kept per sample; a sample stops once it has them.
    method : {"dop853"}
    rtol, atol : float or array_like (n,)
        The run's tolerance (as :func:`tumble.integrate`); the crossings are located on its dense output.
    dt : float, optional
        The first step, s (None: chosen).
    max_steps : int, optional
        The steps (accepted and rejected) a sample may take (None: 1 000 000); one that needs more stops with status
        "step limit", its crossings so far kept. A ``RuntimeWarning`` says how many samples stopped before
        ``t_end`` without their ``max_crossings``, and why.
    parameters : mapping, optional
        A model's or System's parameters, by name, in place of its own.
    device : str
        ``"cpu"``, or ``"cuda"``: one thread per sample, the CPU's per-sample loop compiled for the device.

    Returns
    -------
    xarray.Dataset
        ``time(sample, crossing)`` (s), ``state(sample, crossing, component)``, ``count(sample)`` (NaN past each
        count; the crossing dimension is the largest count), ``status(sample)`` (:data:`tumble.registry.ADAPTIVE_STATUSES`), ``steps``, ``rejected_steps``; the
        surface, direction and tolerance in the attributes.

    Raises
    ------
    ValueError
        Surface and period both or neither; a direction other than -1, 0, 1; ``max_crossings`` < 1; a surface
        numba cannot compile or that returns no number; a tolerance out of range (as :func:`tumble.integrate`).

    See Also
    --------
    tumble.integrate : The whole trajectory, ``method="dop853"`` with its dense output at ``times``.
    tumble.lyapunov : Whether the orbits a section shows are chaotic.

    Examples
    --------
    The free body's spins cross ``w2 = 0`` twice a period (once each way):

    >>> import tumble
    >>> ds = tumble.section((1.0, 2.0, 3.0), [[1.0, 0.1, 0.0]], 40.0, surface=("w2", 0.0), direction=0)
    >>> int(ds["count"][0]) > 4
    True
    """
    device = resolve_device(device)
    _checked(direction, max_crossings, method, surface, period, phase)
    free = not is_system(system)
    model = FreeBody(one_body(system)) if free else system
    name = "w0" if free else "y0"
    t_stop = checked_horizon(t_end)
    if surface is not None:
        spec, kernel, what = _surface(model, surface, int(direction), int(max_crossings))
        if spec.function is not None:  # called once at each initial state: a NaN there is a bug in g, said here
            y, _ = initial_states(model, y0, name)
            p = (model.parameter_values(parameters) if hasattr(model, "parameter_values") else
                 model_parameters(model))
            for i in range(min(len(y), 256)):
                value = spec.function(0.0, y[i], p)
                if not math.isfinite(value):
                    raise ValueError(f"system {system_name(model)!r}: surface g(t, y, p) returned {value} at {name}"
                                     f"[{i}] = {y[i].tolist()}")
        run, _ = run_adaptive(model, y0, t_stop, rtol=rtol, atol=atol, first_step=dt, max_steps=max_steps,
                              parameters=parameters, device=device, y0_name=name, surface=spec,
                              compiled_surface=kernel)
        times, states, count = run.crossing_times, run.crossing_states, run.crossings
        attrs = {"surface": what, "direction": int(direction)}
    else:
        period, phase = float(period), float(phase)
        marks = phase + period * np.arange(1, int(max_crossings) + 1, dtype=float)
        marks = marks[marks <= t_stop]
        # to the last mark: a sample stops stepping once it has its max_crossings states, as at a surface
        run, _ = run_adaptive(model, y0, marks[-1] if len(marks) else t_stop, times=marks if len(marks) else None,
                              rtol=rtol, atol=atol, first_step=dt, max_steps=max_steps, parameters=parameters,
                              device=device, y0_name=name)
        reached = marks[None, :] <= run.stopped[:, None]
        reached &= (run.status == registry.STATUS_OK)[:, None] | (marks[None, :] < run.stopped[:, None])
        states = np.where(reached[:, :, None], run.states[:, :len(marks)], np.nan)
        times = np.where(reached, marks[None, :], np.nan)
        count = reached.sum(axis=1).astype(np.int64)
        attrs = {"period": period, "phase": phase}
    warn_stops(run.status, len(count), run.name, stacklevel=1, kept="their crossings are the ones found before")
    kept = int(count.max(initial=0))  # the crossing dimension as long as the longest sample's
    return _dataset(run, times[:, :kept], states[:, :kept], count, {**attrs, "t_end": t_stop}, device)


def _dataset(run, times, states, count, attrs, device):
    from .integration import indexed_dataset

    variables = {
        "time": (("sample", "crossing"), times, {"units": "s", "long_name": "time of the crossing"}),
        "state": (("sample", "crossing", "component"), states,
                  {"units": run.units[0] if len(set(run.units)) == 1 else "see component_units",
                   "long_name": f"state of {run.name} at the crossing"}),
        "count": ("sample", count, {"long_name": "crossings of the sample (NaN past them)"}),
        **run_variables(run),
        "sample": ("sample", np.arange(len(count)), {"long_name": "ensemble member"}),
        "crossing": ("crossing", np.arange(times.shape[1]), {"long_name": "crossing, in time order"}),
        "component": ("component", np.array(run.components), {"long_name": "state component"}),
        "component_units": ("component", np.array(run.units), {"long_name": "units of each state component"}),
    }
    return indexed_dataset(variables, {"system": run.name, **run_attrs(run), **attrs, "device": device,
                                       **{f"parameter_{key}": value for key, value in run.parameters.items()}})
