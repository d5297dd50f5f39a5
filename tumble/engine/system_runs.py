"""Run a system that is not a ``Body``: a built-in model (:mod:`tumble.models`) or a user's :class:`tumble.System`.

:func:`run_system` is what :func:`tumble.integrate` and :func:`tumble.propagate` call for them: the arguments are
checked once here, then

* a built-in model steps with the models' SIMD kernels (:func:`tumble.kernels.run_model`, one compiled and cached
  driver for every model: rk4, rk8 and, for the Lie–Poisson models, the splittings), ``parameters`` overriding the
  model's own; with any other tableau of :data:`tumble.kernels.TABLEAUX` (a method added at run time) it runs as a
  System does, its rate the kernels' own (:func:`tumble.kernels.rate_sample`);
* a :class:`~tumble.physics.system.System` steps on the CPU with the built-ins' vectorised blocks, its rate rewritten
  into their scalar form and its rk4 and rk8 steps generated from it (:mod:`tumble.kernels.steps.system_steps`: made once
  per process, their drivers cached on disk), and otherwise (a rate without a scalar form, said in one warning; any
  other tableau; the device) with the per-sample loop of :mod:`tumble.kernels.loops.sample_loop`, compiled for that system
  and method on its first run in a process and kept with the system. Before anything runs the rate is compiled alone
  and called once at the first initial state with bounds checked, and at up to :data:`PROBED` initial states: a rate
  numba cannot compile, that reads or writes beyond the state, or that leaves a component of ``dydt`` unset or NaN is
  one line naming the system (ValueError), never a numba traceback or a silent NaN.

Both run on ``device="cpu"`` or ``"cuda"`` (one thread per sample, the same per-sample code).
"""

from __future__ import annotations

import functools
import os
import sys
import warnings
import weakref
from typing import NamedTuple

import numpy as np

from .. import registry
from ..kernels import (MODEL_BLOCK, TABLEAUX, device_models, device_sample_loop, model_methods, parallel_block,
                       rate_sample, rate_sample_parameters, run_model, run_system_blocks)
from ..kernels import sample_loop, system_steps
from ..physics.models import Model
from ..physics.system import System, with_parameters
from . import cost

__all__ = ["PROBED", "SystemRun", "added_tableau", "no_body_parameters", "block_code", "changed_reads", "compiled",
           "initial_states", "is_system", "method_order", "model_parameters", "probe", "run_system", "state_units",
           "system_cache", "system_methods", "system_name", "warn_caller"]

#: Initial states at which a user's rate is called once before a run (the first with bounds checked): a NaN or an
#: unset component there is refused with the sample named; later in the run a non-finite state is a sample status.
PROBED = 256


class SystemRun(NamedTuple):
    """What :func:`run_system` returns (arrays per sample first)."""

    final: np.ndarray  # (N, n): the final (or frozen) states
    times: np.ndarray | None  # (T,), s, of the stored states
    trajectory: np.ndarray | None  # (N, T, n) with save_every
    status: np.ndarray  # (N,) int8, registry.STATUS_NAMES
    steps_taken: np.ndarray  # (N,) int64
    method: str
    dt: float
    n_steps: int
    parameters: dict  # name -> value, as run
    name: str  # the system's name (a model's kind)
    components: tuple  # names of the state's components
    units: tuple  # their units ("" where a System does not say)


def is_system(value):
    """Whether ``value`` is a built-in model or a user's :class:`System` (not a ``Body``: the free-body path)."""
    return isinstance(value, (System, Model))


def no_body_parameters(parameters):
    """Refuse ``parameters`` (not None) for a ``Body``: its moments are the body, it has no parameters to replace."""
    if parameters is not None:
        raise ValueError("parameters are a model's or a System's; a free body has none (its moments are the body)")


def added_tableau(method):
    """Whether ``method`` is a Butcher tableau added to :data:`tumble.kernels.TABLEAUX` at run time. The free body's
    fused steps are generated for the built-in methods only, so a ``Body`` runs such a tableau as
    :class:`tumble.models.FreeBody` does: through the per-sample loop with the kernels' own free-body rate."""
    return isinstance(method, str) and method in TABLEAUX and method not in registry.STEPPING


def system_methods(system):
    """The methods ``system`` runs: every tableau of :data:`tumble.kernels.TABLEAUX` (a method added at run time
    included) and, for a built-in model, its kernels' own (:func:`tumble.kernels.model_methods`: the splittings)."""
    if isinstance(system, Model):
        own = model_methods(system.kind)
        return (*own, *(name for name in TABLEAUX if name not in own))
    return tuple(TABLEAUX)


def method_order(method):
    """The order of one of :func:`system_methods`' Runge–Kutta tableaux."""
    return TABLEAUX[method].order


#: Model kind -> the System that runs a built-in model's rate through the per-sample loop, for a tableau its
#: generated SIMD steps do not have; its parameters are :func:`tumble.kernels.rate_sample_parameters`.
_SAMPLE_LOOP_SYSTEMS = {}


#: A built-in model's kernel parameters by its key (kind, moments, parameters): at most :data:`_KEPT_PARAMETERS`.
_MODEL_PARAMETERS = {}
_KEPT_PARAMETERS = 256


def model_parameters(model):
    """:func:`tumble.kernels.rate_sample_parameters` of a built-in ``model``, a fresh array: kept for the model's
    values, since making them (its constants, scaled) took 10-35 us of a small run's 50."""
    key = model._key()
    p = _MODEL_PARAMETERS.get(key)
    if p is None:
        if len(_MODEL_PARAMETERS) >= _KEPT_PARAMETERS:  # a scan over many values: kept afresh
            _MODEL_PARAMETERS.clear()
        p = _MODEL_PARAMETERS[key] = rate_sample_parameters(model.kind, model.moments, model.parameters)
    return p.copy()


def _sample_loop_system(model):
    """``(System, p)``: ``model`` as the per-sample loop runs it (the kernels' rate of its kind, its parameters)."""
    p = model_parameters(model)
    if model.kind not in _SAMPLE_LOOP_SYSTEMS:
        _SAMPLE_LOOP_SYSTEMS[model.kind] = System(rate_sample, state=model.spec.state, name=model.kind,
                                                  parameters={f"p{i}": 0.0 for i in range(len(p))})
    return _SAMPLE_LOOP_SYSTEMS[model.kind], p


def system_name(system):
    """What a message and a Dataset call ``system``: a System's name, a built-in model's kind."""
    return system.name if isinstance(system, System) else system.kind


def initial_states(system, y0, name="y0"):
    """``(y (N, n) float64 contiguous, whether y0 was one state)``: ``y0`` checked against ``system``'s state (shape,
    numbers, every value finite); ValueError naming ``name`` and the components otherwise."""
    names = system.spec.state
    try:
        y = np.array(y0, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of numbers of shape (N, {len(names)}) ({', '.join(names)} of "
                         f"{system_name(system)!r}), got {y0!r}") from None
    single = y.ndim == 1
    if single:
        y = y[None, :]
    if y.ndim != 2 or y.shape[1] != len(names) or len(y) == 0:
        raise ValueError(f"{name} must have shape (N, {len(names)}) with N >= 1 ({', '.join(names)} of "
                         f"{system_name(system)!r}), got shape {np.shape(y0)}")
    finite = np.isfinite(y)
    bad = [] if finite.all() else np.flatnonzero(~np.all(finite, axis=1))  # all(axis=1) alone: 30 us for 2000 states
    if len(bad):
        raise ValueError(f"{name} must be finite: sample {int(bad[0])} holds NaN or inf ({', '.join(names)} = "
                         f"{y[bad[0]].tolist()}){f', and {len(bad) - 1} more' if len(bad) > 1 else ''}")
    return np.ascontiguousarray(y), single


class _Kernels(NamedTuple):
    drive: object  # the CPU driver
    run_sample: object  # the per-sample loop (the device kernel's too)
    stages: int


class _Compiled:
    """A System's rate compiled for the engine: with bounds checked at once (the first call's :func:`probe`, and the
    one line naming the system when numba cannot compile it), plain when a run first asks for it (a per-sample loop,
    an error-controlled run; the vectorised blocks compile the rate's source into their own step and never do)."""

    def __init__(self, system):
        self._rate, self._owner = system.rate, f"system {system.name!r}"
        self.checked = self._compile(boundscheck=True)
        self.methods = {}  # method -> the kernels made of it (:func:`_kernels`, the error-controlled runs')

    def _compile(self, boundscheck=False):
        return sample_loop.compile_function(self._rate, sample_loop.RATE_SIGNATURE, self._owner, "rate(t, y, p, dydt)",
                                            boundscheck=boundscheck)

    @functools.cached_property
    def rate(self):
        """The rate compiled, as every engine call runs it."""
        return self._compile()


#: The caches of what this process made for a System (System -> its compiled functions and kernels; they go with the
#: system), dropped together when what its functions read changes (:func:`current`).
SYSTEM_CACHES = []


def system_cache():
    """A new cache System -> what is made for it, one of :data:`SYSTEM_CACHES`."""
    cache = weakref.WeakKeyDictionary()
    SYSTEM_CACHES.append(cache)
    return cache


#: System -> what its rate and Jacobian read from their modules and closures when its kernels were made, by name.
_READS = weakref.WeakKeyDictionary()


def current(system):
    """Drop what this process made for ``system`` where a number, array or function its rate or Jacobian reads from
    its module or closure has changed since (numba compiles those in as constants: the kernels made before would run
    with the old value), and say which changed. What cannot be keyed (an object of another kind) is not told."""
    reads = {}
    for fn in (system.rate, system.jacobian):
        named = system_steps.reads_by_name(fn)
        if named is None:
            return
        reads.update(named)
    before = _READS.get(system, reads)
    _READS[system] = reads
    if reads != before:
        for cache in SYSTEM_CACHES:
            cache.pop(system, None)
        warn_caller(f"system {system.name!r}: {changed_reads(before, reads)}, read by its functions, changed since "
                    f"they were compiled: compiled again (numba compiles a module's names in as constants; a "
                    f"parameter, System(parameters=...), changes without compiling)")


def changed_reads(before, after):
    """The names whose values differ between two :func:`~tumble.kernels.steps.system_steps.reads_by_name`, as text."""
    return ", ".join(sorted(name for name in before.keys() | after.keys() if before.get(name) != after.get(name)))


def warn_caller(message):
    """A ``RuntimeWarning`` of ``message`` attributed to the first caller outside tumble (the user's line)."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 2
    while frame is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, RuntimeWarning, stacklevel=level)


#: System -> its compiled rate and kernels: made once per process (they go with the system).
_COMPILED = system_cache()


def compiled(system):
    """A System's rate compiled once per process (:class:`_Compiled`): one line naming the system when numba cannot
    compile it."""
    if system not in _COMPILED:
        _COMPILED[system] = _Compiled(system)
    return _COMPILED[system]


def _kernels(system, method):
    """The per-sample loop of ``system`` stepped by ``method``'s tableau, made once (kept with the tableau it was made
    of: a tableau replaced at run time under the same name is a new method)."""
    made = compiled(system).methods
    tableau = TABLEAUX[method]
    if method not in made or made[method][0] is not tableau:
        run_sample = sample_loop.make_sample_loop(sample_loop.make_step(compiled(system).rate, tableau))
        made[method] = (tableau, _Kernels(sample_loop.make_cpu_driver(run_sample, len(tableau.b)), run_sample,
                                          len(tableau.b)))
    return made[method][1]


#: System -> the code of its steps on the block path (None: it has no scalar form), made once per process.
_BLOCK_CODES = system_cache()


def block_code(system, method, tangents=False):
    """The code of ``system``'s steps (with ``tangents``, its tangent steps) on the CPU's vectorised block path for
    ``method`` (:func:`tumble.kernels.steps.system_steps.system_code`, :func:`~tumble.kernels.steps.system_steps.tangent_code`), or
    None where it runs one sample at a time: a method without generated steps, or a rate (or Jacobian) that has no
    scalar form, which one warning per System and kind says, with why."""
    if not system_steps.runs(method):
        return None
    made = _BLOCK_CODES.setdefault(system, {})
    if tangents not in made:
        n, k = system.state_size, len(system.parameters)
        try:
            made[tangents] = (system_steps.tangent_code(system.rate, n, k, system.jacobian, system.difference_scales())
                              if tangents else system_steps.system_code(system.rate, n, k))
        except system_steps.NotScalar as why:
            made[tangents] = None
            warnings.warn(f"system {system.name!r} runs one sample at a time, about 20 times slower than on the "
                          f"vectorised blocks: {why} (a rate that reads y[j] and writes dydt[j] at constant indices "
                          f"j, as a Jacobian J[i, j], runs vectorised)", stacklevel=4)
    return made[tangents]


def probe(system, y, p, t0):
    """Call the rate, with bounds checked, at the first :data:`PROBED` finite initial states: ValueError naming the
    system when it reads or writes beyond the state, or leaves a component unset or not finite. Before any of
    ``system``'s kernels are looked up for a run: the kernels made for values its functions no longer read are dropped
    first (:func:`current`)."""
    current(system)
    rate = compiled(system).checked
    n = y.shape[1]
    dydt = np.empty(n)
    for i in range(min(len(y), PROBED)):
        state = np.ascontiguousarray(y[i])
        if not np.all(np.isfinite(state)):
            continue  # a sample that starts non-finite is flagged by the run (its status), not refused
        dydt[:] = np.nan
        try:
            rate(float(t0), state, p, dydt)
        except IndexError:
            raise ValueError(f"system {system.name!r}: its rate indexes beyond the state or the parameters (state has "
                             f"{n} components: {', '.join(system.state)}; parameters {len(p)}: "
                             f"{', '.join(system.parameters) or 'none'})") from None
        bad = np.flatnonzero(~np.isfinite(dydt))
        if len(bad):
            j = int(bad[0])
            raise ValueError(f"system {system.name!r}: its rate left dydt[{j}] ({system.state[j]}) "
                             f"{'unset or NaN' if np.isnan(dydt[j]) else 'infinite'} at sample {i}'s initial state "
                             f"{state.tolist()} (t = {t0:g} s)")


def run_system(system, y0, t_end, n_steps, step, method="rk4", *, save_every=None, parameters=None, device="cpu"):
    # size: the one run of a model or a System for integrate and propagate: checks, cost, plan, either driver
    """Integrate an ensemble of ``system`` (a built-in model or a :class:`System`) with a fixed step.

    Parameters
    ----------
    system : Model or System
    y0 : array_like, shape (N, n) or (n,)
        Initial states (the system's state components, in its order).
    t_end : float
        Horizon, s (>= 0).
    n_steps, step : int, float
        The step plan (the free body's, ``tumble.engine.integration._step_plan``): ``n_steps`` steps of ``step`` s
        end at ``t_end``.
    method : str
        ``"auto"`` (rk4) or one of :func:`system_methods`.
    save_every : int or None
        None: only the final state; ``k``: the initial state, every k-th step and the final one.
    parameters : mapping, optional
        Values in place of the system's own parameters, by name.
    device : str
        "cpu" or "cuda", resolved by the caller (the public call's door: :func:`tumble.engine.device.resolve_device`).

    Returns
    -------
    SystemRun, and whether ``y0`` was a single state.

    Raises
    ------
    ValueError
        A method the system does not run, states of the wrong shape, an unknown parameter, a rate numba cannot
        compile or that misbehaves at the initial states (one line naming the system), a run too large
        (:mod:`tumble.engine.cost`), a device that cannot run.
    """
    system, values = with_parameters(system, parameters)
    name = system_name(system)
    methods = system_methods(system)
    if method == registry.AUTO:
        method = registry.AUTO_STEPPING
    if not isinstance(method, str) or method not in methods:
        why = (" (a System runs the explicit Runge-Kutta methods: the splittings need a Lie-Poisson structure, the "
               "closed form exists for the free body only)" if isinstance(system, System) else "")
        raise ValueError(f"method must be one of {', '.join(methods)} for {name!r}, got {method!r}{why}")
    y, single = initial_states(system, y0)
    n_state = y.shape[1]
    stored = n_state * (n_steps / save_every + 2 if save_every else 2)
    cost.refuse(cost.run_cost(len(y), n_steps, stored), f"y0 ({len(y):,} states) over {n_steps:,} steps", device)
    every = int(save_every or 0)
    code = None
    if isinstance(system, System):
        p = system.parameter_values(parameters)
        probe(system, y, p, 0.0)
        code = block_code(system, method) if device == "cpu" else None
    if code is None and (isinstance(system, System) or method not in model_methods(system.kind)):
        loop_system = system
        if not isinstance(system, System):  # a tableau the model's generated steps do not have
            loop_system, p = _sample_loop_system(system)
        kernels = _kernels(loop_system, method)
        n_saved = sample_loop.saved_count(n_steps, every)
        state = np.ascontiguousarray(y)
        if device == "cpu":
            saved = np.empty((len(y), n_saved, n_state))
            status = np.zeros(len(y), dtype=np.int8)
            steps_taken = np.zeros(len(y), dtype=np.int64)
            kernels.drive(state, p, 0.0, step, n_steps, every, saved, status, steps_taken)
        else:
            cuda = device_sample_loop()
            kernel = _device_kernel(loop_system, method, kernels, n_state)
            saved, status, steps_taken = cuda.run(kernel, state, p, 0.0, step, n_steps, every, n_saved)
        final, trajectory = state, (saved if every else None)
    else:
        state = np.array(y.T, order="C")
        block = parallel_block(len(y), MODEL_BLOCK)
        if code is not None:  # a System on the block path
            observed = run_system_blocks(code, method, state, system_steps.block_constants(p), step, n_steps, every,
                                         block)
        else:
            run = run_model if device == "cpu" else device_models().run_model
            observed = run(system.kind, method, state, system.moments, step, n_steps, **system.parameters,
                           save_every=every, block=block)
        final = state.T
        trajectory = observed.saved.transpose(2, 0, 1) if every else None
        status, steps_taken = observed.status, observed.steps_taken
    times = None
    if every:
        marks = np.arange(0, n_steps + 1, every)
        marks = np.append(marks, n_steps) if marks[-1] != n_steps else marks
        times = marks * step
        times[-1] = t_end
    return SystemRun(final, times, trajectory, status, steps_taken, method, step, n_steps, values, name,
                     system.spec.state, state_units(system)), single


def state_units(system):
    """The units of each state component: a model's from ``registry.STATE_BLOCKS`` (by the component's letter); a
    System's are not known ("")."""
    if isinstance(system, System):
        return ("",) * system.state_size
    by_letter = {letter: units for letter, _, units in registry.STATE_BLOCKS}
    return tuple(by_letter[component[0]] for component in system.spec.state)


#: System -> {per-sample loop: its device kernel} (made once per process, they go with the system).
_DEVICE = system_cache()


def _device_kernel(system, method, kernels, n_state):
    made = _DEVICE.setdefault(system, {})
    if kernels.run_sample not in made:  # the loop of the method's tableau now (_kernels)
        made[kernels.run_sample] = device_sample_loop().make_kernel(kernels.run_sample, n_state, kernels.stages,
                                                                    len(system.parameters))
    return made[kernels.run_sample]

