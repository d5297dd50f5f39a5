"""The models' ensemble kernels: one parallel driver for every model and method, observers on the fly (issue 18).

The state of every sample is a column of ``y`` (shape ``(n_state, N)``, ``n_state`` up to 7: the model's components
as ``registry.MODELS`` lists them, ``w1 w2 w3`` first, then the heavy top's ``g1 g2 g3``, the gravity gradient's
``q0 q1 q2 q3`` or the damper's ``s1 s2 s3``). As in the free body's
driver (:mod:`tumble.kernels.drivers`) the samples are cut into blocks that run in parallel (``prange``); each
block is copied into contiguous component rows (structure of arrays) and the generated per-sample step
(:mod:`tumble.kernels.model_steps`, from the Butcher tableaux of :mod:`tumble.kernels.tableaux`) runs in a loop
over the block's samples that the compiler vectorises across samples (SIMD lanes).

**One compiled driver per system and method.** The model and the method are codes that reach the loop as constants of
its caller (:func:`make_propagate_model`'s closure, the device kernel's), and the loop compiles that system's and that
method's step only (:func:`_step`); the observers are runtime switches on arrays that are empty when not asked for; a
model's parameters are one float array (:func:`tumble.kernels.systems.constants`: each system's named record first).
So one compiled (and cached) driver per system and method serves every combination of outputs: rk4 and rk8 for every
system, the Lie–Poisson splittings for the free body, the gyrostat and the heavy top
(:mod:`tumble.kernels.model_splittings`). The free body runs as the gyrostat with ``h = 0`` (the free body keeps its
own, faster driver for everything else: :func:`tumble.kernels.run`). A system's equations are its module of
:mod:`tumble.kernels.systems`; the steps and the dispatch over systems and methods are generated from them
(:mod:`tumble.kernels.model_steps`).

**Observers.** The final state (in place); the state every ``save_every`` steps; the transverse norm
``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` at given steps (the arrays of
:class:`tumble.physics.models.Transverse`); the running maximum of each invariant's drift ``|x − x0| / scale0``
(each system's ``invariants``, :mod:`tumble.kernels.systems`: the scale is the invariant itself where it is
sign-definite, else the largest magnitude it can take, so that an invariant that starts at 0 does not divide by 0;
the gravity gradient's Jacobi integral: the sum of its three terms' magnitudes; the damper tracks ``|L|²`` only, its
energy decays).

**Gravity gradient.** The quaternion is divided by its norm after every step (in the generated block loop): the
right-hand side keeps ``|q|`` exactly but rk4 and rk8 only to their order, and off the unit sphere the attitude rows
``c2``, ``c3`` of the torque and of ``w + n c2`` are no rotation's. A projection after each step keeps the method's
order and puts every observer (probes, trajectory, drifts) on the unit sphere; the ``|q|²`` drift then reports round-off
(and a non-unit initial quaternion, rescaled by the first step). The probes' ``y_eq`` is the orbit-following
equilibrium ``w = (0, −n, 0)``, ``q = (1, 0, 0, 0)``: subtracting it from the norm's columns ``(w1, w2, w3, q1, q2,
q3)`` is the ``Transverse.centre`` of the physics layer.

**Status.** ``STATUS_OK``, ``STATUS_NONFINITE`` (a component NaN or infinite, checked before the first step, every
:data:`CHECK_EVERY` steps, at the end, and every step while drifts are tracked) or ``STATUS_DRIFT`` (a drift beyond
``drift_limit``; each step a branch-free screening pass over the block,
:func:`tumble.kernels.model_steps.drift_suspects` (:mod:`tumble.kernels.drift_screen`), finds whether any sample comes
near either, and only then do the exact per-sample checks run); a sample with a bad status stops and keeps the state
it had when it was caught; its later probes are NaN. Samples never interact: results do not depend on the number of threads or on the block size.
"""

import math
from typing import NamedTuple

import numpy as np
from numba import prange, types
from numba.core.errors import TypingError
from numba.extending import overload

from ..registry import (LIE_POISSON_MODELS, MODEL_KINDS, MODEL_PARAMETERS, MODEL_STEPPING, STATUS_DRIFT, STATUS_OK,
                        STEPPING, model_kind)
from ..registry import model_methods  # the names the model kernels run for a kind (re-exported)
from .block_parts import check_finite, freeze, nan_rest, restore_frozen, store, store_initial, store_rest
from .drift_screen import SCREEN_ATOL, SCREEN_RTOL
from .jit import FASTMATH, jit
from .model_splittings import SPLITTINGS
from .model_steps import (drift_suspects, invariants, rate_columns, rate_sample, step, tangent_columns,
                          tangent_sample)
from .systems import N_INVARIANTS, constants

__all__ = ["MODEL_CODES", "MODEL_METHODS", "ModelObserved", "SPLITTING_KINDS", "make_propagate_model",
           "model_arguments", "model_methods", "model_rhs", "model_tangent", "propagate_model", "rate_sample",
           "rate_sample_parameters", "run_block", "run_model", "tangent_sample"]

#: Kernel codes of the models: their index in ``registry.MODEL_KINDS``. The kernels step every model of this table,
#: whatever ``registry.MODELS``' ``implemented`` says (that flag is the studies'; the gravity gradient and the damper
#: have kernels before they have studies).
MODEL_CODES = {kind: code for code, kind in enumerate(MODEL_KINDS)}

#: The methods the model kernels run, by name: kernel id (index in ``registry.STEPPING``, as the free body's): rk4 and
#: rk8 for every model, the Lie–Poisson splittings (:mod:`tumble.kernels.model_splittings`) for ``SPLITTING_KINDS``.
MODEL_METHODS = {name: STEPPING.index(name) for name in MODEL_STEPPING}

#: The models the splittings apply to (``registry.LIE_POISSON_MODELS``, which says why).
SPLITTING_KINDS = LIE_POISSON_MODELS


#: Steps between two checks for non-finite states when no drift is tracked.
CHECK_EVERY = 32

# Samples per SIMD block: the free body's 256 (kernels.methods.BLOCK); results do not depend on it.
BLOCK = 256

_TINY = 2.2250738585072014e-308  # smallest normal float: a zero scale gives a zero drift, not 0/0


# --- the system's and the method's code, chosen when the loop is compiled ---------------------------------------------
# The model's and the method's codes reach the loop as literal types (constants of its caller: the CPU driver's closure,
# :func:`driver`, and the device kernel's, :mod:`tumble.kernels.cuda_models`). The three functions below hand them as
# constants to the generated chains of :mod:`tumble.kernels.model_steps`, which numba inlines and prunes to the one
# branch taken: a driver compiles its own system's step, invariants and drift screen only (the chains compiled every
# system's and method's steps into the one driver there was: 78 s of a first heavy-top ensemble on 2 cores,
# ``benchmarks/first_call.py``). Codes that reach the loop as plain ints (a caller passing them at run time, or
# through a star-call's tuple, which numba-cuda types as plain ints) are a typing error that says so (:func:`_literal`).

# Not inlined at numba's IR level: numba-cuda's pipeline cannot take an overload inlined so (LLVM inlines it).
# ``prefer_literal``: numba tries an overload with the arguments' plain types first and keeps what that gives (when
# the plain-int case had a chain of every branch, it was taken even for literal codes, from 2026-11-29 until
# benchmarks/first_call.py found it: a heavy top's first ensemble compiled every system's steps again).
_OPTIONS = dict(prefer_literal=True, jit_options=dict(fastmath=set(FASTMATH), error_model="numpy"))


def _literal(*codes):
    """Refuse codes that are not literals (a typing error that says so): the generated chain would compile every
    system's (and method's) branch into the loop."""
    for code in codes:
        if not isinstance(code, types.IntegerLiteral):
            raise TypingError(f"the models' loop takes its system and method codes as literals, constants of its "
                              f"caller (the driver's closure, the device kernel's), got {code}")


def _step(model, method, ys, t, h, a, x0):
    """:func:`tumble.kernels.model_steps.step` of the system and method given as literal codes."""


@overload(_step, **_OPTIONS)
def _step_of(model, method, ys, t, h, a, x0):
    _literal(model, method)
    model_code, method_code = model.literal_value, method.literal_value

    def system_step(model, method, ys, t, h, a, x0):
        step(model_code, method_code, ys, t, h, a, x0)

    return system_step


def _invariants(model, ys, i, a):
    """:func:`tumble.kernels.model_steps.invariants` of the system given as a literal code."""


@overload(_invariants, **_OPTIONS)
def _invariants_of(model, ys, i, a):
    _literal(model)
    model_code = model.literal_value

    def system_invariants(model, ys, i, a):
        return invariants(model_code, ys, i, a)

    return system_invariants


def _drift_suspects(model, ys, active, a, x0, scale, screen):
    """:func:`tumble.kernels.model_steps.drift_suspects` of the system given as a literal code."""


@overload(_drift_suspects, **_OPTIONS)
def _drift_suspects_of(model, ys, active, a, x0, scale, screen):
    _literal(model)
    model_code = model.literal_value

    def system_drift_suspects(model, ys, active, a, x0, scale, screen):
        return drift_suspects(model_code, ys, active, a, x0, scale, screen)

    return system_drift_suspects


@jit
def _initial_invariants(model, ys, c, x0, scale):
    """Each sample's invariants ``x0`` (3, m) and their drift scales (3, m) at the start."""
    for i in range(ys.shape[1]):
        x1, x2, x3, s1, s2, s3 = _invariants(model, ys, i, c)
        x0[0, i], x0[1, i], x0[2, i] = x1, x2, x3
        scale[0, i], scale[1, i], scale[2, i] = max(s1, _TINY), max(s2, _TINY), max(s3, _TINY)


@jit
def _observe_drift(model, ys, active, c, x0, scale, drift, lo, drift_limit, k, frozen, status, last):
    """Running maximum of each invariant's drift ``|x − x0| / scale``; samples past ``drift_limit`` stop.

    Returns how many samples it stopped."""
    stopped = 0
    for i in range(ys.shape[1]):
        if not active[i]:
            continue
        x1, x2, x3, _, _, _ = _invariants(model, ys, i, c)
        d1 = abs(x1 - x0[0, i]) / scale[0, i]
        d2 = abs(x2 - x0[1, i]) / scale[1, i]
        d3 = abs(x3 - x0[2, i]) / scale[2, i]
        if drift.shape[0] > 0:
            drift[0, lo + i] = max(drift[0, lo + i], d1)
            drift[1, lo + i] = max(drift[1, lo + i], d2)
            drift[2, lo + i] = max(drift[2, lo + i], d3)
        if drift_limit > 0.0 and not (d1 <= drift_limit and d2 <= drift_limit and d3 <= drift_limit):
            freeze(i, k, STATUS_DRIFT, ys, active, frozen, status, last)
            stopped += 1
    return stopped


@jit
def _observe_norm(ys, active, columns, weights, y_eq, probes, lo, row):
    """The weighted transverse norm of each sample into ``probes[row]`` (NaN for stopped samples)."""
    for i in range(ys.shape[1]):
        total = 0.0
        for j in range(columns.shape[0]):
            d = ys[columns[j], i] - y_eq[columns[j]]
            total += weights[j] * d * d
        probes[row, lo + i] = math.sqrt(total) if active[i] else np.nan


@jit
def run_block(model, method, y, lo, ys, active, frozen, last, x0, scale, c, h, n_steps, save_every, saved, columns,
              weights, y_eq, probe_steps, probes, drift, drift_limit, status, steps_taken):
    # size: the one time loop of every model, method and observer, on either device: flat arrays and scalars
    # (DESIGN.md: arrays and scalars below the kernels' door), the block's scratch owned by the caller, the observers
    # the helpers above
    """Samples ``lo, ..., lo + m - 1`` of ``y`` through the whole run: the models' one time loop, for the CPU and the
    device.

    The CPU's driver (:func:`propagate_model`) calls it for each block of samples in parallel, where the block's
    samples move together in SIMD lanes; the device's kernel (:mod:`tumble.kernels.cuda_models`) for one sample per
    thread (``m = 1``, the scratch in the thread's local memory). The scratch, owned by the caller: ``ys`` and
    ``frozen`` (n_state, m), ``active`` (m,) bool, ``last`` (m,) int64, ``x0`` and ``scale`` (N_INVARIANTS, m). The
    other arguments are :func:`propagate_model`'s; the loop writes the block's columns of ``y``, ``saved``,
    ``probes``, ``drift``, ``status`` and ``steps_taken``.
    """
    n_state, m = ys.shape
    n_probes = probe_steps.shape[0]
    storing = saved.shape[0] > 0
    record_drift = drift.shape[0] > 0
    track_drift = record_drift or drift_limit > 0.0
    screen = drift_limit * (1.0 - SCREEN_RTOL) - SCREEN_ATOL if drift_limit > 0.0 else math.inf
    block_status = status[lo:lo + m]
    for i in range(m):
        for j in range(n_state):
            ys[j, i] = y[j, lo + i]
        active[i] = True
        last[i] = n_steps
        block_status[i] = STATUS_OK
    _initial_invariants(model, ys, c, x0, scale)
    n_frozen = check_finite(ys, active, 0, frozen, block_status, last)
    slot = store_initial(saved, ys, lo)
    probe = 0
    while probe < n_probes and probe_steps[probe] == 0:
        _observe_norm(ys, active, columns, weights, y_eq, probes, lo, probe)
        probe += 1
    ran = 0
    for k in range(n_steps):
        if n_frozen == m:
            break
        _step(model, method, ys, k * h, h, c, x0)
        if n_frozen:
            restore_frozen(ys, active, frozen)
        ran = k + 1
        # with drifts tracked every step, the exact observers run only for a block with a suspect (or whose
        # drifts are recorded): the screen's "nothing to stop" is exact, its suspects are checked exactly
        exact = track_drift and (record_drift or _drift_suspects(model, ys, active, c, x0, scale, screen))
        if exact or (not track_drift and (ran % CHECK_EVERY == 0 or ran == n_steps)):
            n_frozen += check_finite(ys, active, ran, frozen, block_status, last)
        if exact:
            n_frozen += _observe_drift(model, ys, active, c, x0, scale, drift, lo, drift_limit, ran, frozen,
                                       block_status, last)
        if storing and (ran % save_every == 0 or ran == n_steps):
            store(saved, slot, ys, lo)
            slot += 1
        while probe < n_probes and probe_steps[probe] == ran:
            _observe_norm(ys, active, columns, weights, y_eq, probes, lo, probe)
            probe += 1
    # A block whose samples all stopped fills the rest of its outputs: the frozen states, NaN probes.
    store_rest(saved, slot, ys, lo, ran, n_steps, save_every)
    nan_rest(probes, probe, lo, m)
    for i in range(m):
        for j in range(n_state):
            y[j, lo + i] = ys[j, i]
        steps_taken[lo + i] = last[i]


def make_propagate_model(model, method):
    """The CPU's driver of the one time loop (:func:`run_block`) for ``model`` and ``method`` (codes of
    :data:`MODEL_CODES` and :data:`MODEL_METHODS`), constants of the closure: the loop compiles that system's and that
    method's step only. numba's disk cache tells the closures apart by their constants."""

    @jit(parallel=True)
    def propagate(y, constants, h, n_steps, block, save_every, saved, columns, weights, y_eq, probe_steps, probes,
                  drift, drift_limit, status, steps_taken):
        n_state, n = y.shape
        for ib in prange((n + block - 1) // block):
            lo = ib * block
            m = min(block, n - lo)
            run_block(model, method, y, lo, np.empty((n_state, m)), np.empty(m, dtype=np.bool_),
                      np.empty((n_state, m)), np.empty(m, dtype=np.int64), np.empty((N_INVARIANTS, m)),
                      np.empty((N_INVARIANTS, m)), constants, h, n_steps, save_every, saved, columns, weights, y_eq,
                      probe_steps, probes, drift, drift_limit, status, steps_taken)

    return propagate


#: The CPU drivers made so far, by (model code, method code); each compiles (or loads) on its first call.
_DRIVERS = {}


def propagate_model(model, method, y, constants, h, n_steps, block,
                    save_every, saved,
                    columns, weights, y_eq, probe_steps, probes,
                    drift, drift_limit,
                    status, steps_taken):
    """Advance every sample ``n_steps`` steps of size ``h`` of ``method`` on ``model``, observing as asked: the CPU's
    wrapper of the one time loop (:func:`run_block`), blocks of ``block`` samples in parallel (``prange``).

    Parameters
    ----------
    model, method : int
        :data:`MODEL_CODES` value; :data:`MODEL_METHODS` value (rk4, rk8; a splitting for a free body, gyrostat
        or heavy top).
    y : ndarray, shape (n_state, N), float64
        The states (rad/s, then the model's own units); overwritten with the final (or frozen) states.
    constants : ndarray, shape (N_CONSTANTS,)
        :func:`tumble.kernels.systems.constants` of the model.
    h : float
        Step, s.
    n_steps, block : int
        Steps to take; samples per block.
    save_every, saved : int, ndarray (n_saved, n_state, N)
        The initial state, every ``save_every``-th and the final state; ``n_saved = 0`` stores nothing.
    columns, weights, y_eq : ndarray (k,) int64, ndarray (k,), ndarray (n_state,)
        The transverse norm ``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)``.
    probe_steps, probes : ndarray (P,) int64 increasing, ndarray (P, N)
        The norm after each listed step (0 = the initial state); NaN once a sample has stopped.
    drift : ndarray (N_INVARIANTS, N) or (0, N)
        Running maximum of each invariant's drift (not recorded when empty).
    drift_limit : float
        A drift beyond it marks a sample ``STATUS_DRIFT`` and stops it (<= 0: off).
    status, steps_taken : ndarray (N,) int8, ndarray (N,) int64
        Outputs: per-sample status and the number of steps each sample took.
    """
    key = (int(model), int(method))
    driver = _DRIVERS.get(key)
    if driver is None:
        driver = _DRIVERS[key] = make_propagate_model(*key)
    driver(y, constants, h, n_steps, block, save_every, saved, columns, weights, y_eq, probe_steps, probes, drift,
           drift_limit, status, steps_taken)


class ModelObserved(NamedTuple):
    """What :func:`run_model` returns; an output that was not asked for is None."""

    saved: np.ndarray | None  # (n_saved, n_state, N)
    probes: np.ndarray | None  # (P, N), transverse norm
    drift: np.ndarray | None  # (n_invariants, N), running max of each invariant's drift (registry's order)
    status: np.ndarray  # (N,) int8
    steps_taken: np.ndarray  # (N,) int64


#: The parameters that carry the moments' units (kg m², N m, N m s: the rotor, mgl, J, c): scaled with them.
_SCALED = frozenset(p.key for p in MODEL_PARAMETERS if "kg" in p.units or "N" in p.units)


def _kind_constants(kind, moments, parameters):
    """``(model code, n_state, constants)``: :func:`tumble.kernels.systems.constants` of the moments (and of the
    parameters in their units, :data:`_SCALED`; not the orbit rate, a direction or an eccentricity) divided by the
    power of two nearest the largest moment: the equations do not change, no bit of the rates or relative drifts
    does, and the invariants of moments of 1e-170 or 1e200 kg m² stay in range (as :func:`tumble.kernels.methods.run`).
    ``parameters``: the model's keywords of :func:`run_model`."""
    if kind not in MODEL_CODES:
        raise ValueError(f"model kind must be one of {', '.join(MODEL_CODES)} for the kernels, got {kind!r}")
    moments = np.asarray(moments, dtype=float)
    unit = math.ldexp(1.0, -math.frexp(float(moments.max()))[1])
    scaled = {key: np.asarray(value, dtype=float) * unit if key in _SCALED else value
              for key, value in parameters.items()}
    return MODEL_CODES[kind], len(model_kind(kind).state), constants(kind, moments * unit, scaled)


def rate_sample_parameters(kind, moments, parameters):
    """The parameters ``p`` of :func:`tumble.kernels.model_steps.rate_sample` (and ``tangent_sample``) for model
    ``kind``: its code, then its constants (:func:`_kind_constants`), float64 (1 + N_CONSTANTS,).

    With them a built-in system runs as a user's ``System`` does, through the per-sample loop of
    :mod:`tumble.kernels.sample_loop`: on either device, with any tableau of :data:`tumble.kernels.tableaux.TABLEAUX`,
    a method added at run time included (the generated steps cover :data:`MODEL_METHODS` only). The gravity
    gradient's quaternion is then not projected after each step: its rate keeps ``|q|``, the method's order holds."""
    code, _, values = _kind_constants(kind, moments, parameters)
    return np.concatenate([[float(code)], values])


def _columns(kind, y, moments, parameters, name="y"):
    code, n_state, values = _kind_constants(kind, moments, parameters)
    y = np.ascontiguousarray(y, dtype=float)
    if y.ndim != 2 or y.shape[0] != n_state:
        raise ValueError(f"{name} must have shape ({n_state}, N) for a {kind} model, got shape {y.shape}")
    return code, y, values


def model_rhs(kind, y, moments, *, t=0.0, **parameters):
    """The kernels' right-hand side ``f(t, y)`` of model ``kind`` at states given as columns (tests, linear theory).

    Parameters
    ----------
    kind : str
        A model kind of ``registry.MODEL_KINDS``.
    y : ndarray, shape (n_state, N)
        States (rad/s, then the model's own units).
    moments : array_like, shape (3,)
        Principal moments, kg m².
    t : float
        Time, s (the gravity gradient's eccentric orbit: from perigee).
    **parameters
        The model's own (:mod:`tumble.kernels.systems`: ``rotor`` N m s, ``mgl`` N m and ``centre``,
        ``orbit_rate`` rad/s and ``eccentricity``, ``damper_inertia`` kg m² and ``damping`` N m s); missing ones
        take the system's defaults, others are ignored.

    Returns
    -------
    ndarray, shape (n_state, N)

    Raises
    ------
    ValueError
        An unknown kind or a state of the wrong number of rows.
    """
    code, y, values = _columns(kind, y, moments, parameters)
    out = np.empty_like(y)
    rate_columns(code, y, values, float(t), out)
    return out


def model_tangent(kind, y, v, moments, *, t=0.0, **parameters):
    """The kernels' tangent flow ``J(t, y) v`` of model ``kind``: states ``y`` and tangent vectors ``v`` as columns
    (n_state, N); otherwise as :func:`model_rhs`."""
    code, y, values = _columns(kind, y, moments, parameters)
    _, v, _ = _columns(kind, v, moments, parameters, "v")
    if v.shape != y.shape:
        raise ValueError(f"v must have the shape of y {y.shape}, got shape {v.shape}")
    out = np.empty_like(y)
    tangent_columns(code, y, v, values, float(t), out)
    return out


_NOT_LIE_POISSON = (" (the Lie–Poisson splittings apply to the free body, the gyrostat and the heavy top only: a damper "
                    "is dissipative, a gravity gradient's state is no Lie–Poisson system in these variables)")

_NO_STEPS = np.zeros(0, dtype=np.int64)
_NO_COLUMNS = np.zeros(0, dtype=np.int64)
_NO_WEIGHTS = np.zeros(0)


def model_arguments(kind, method, y, moments, n_steps, parameters, save_every, columns, weights, y_eq, probe_steps):
    # size: run_model's arguments that its driver takes as arrays, checked and packed in one place for either device
    """:func:`run_model`'s arguments checked and packed for a driver (this module's or the device's,
    :mod:`tumble.kernels.cuda_models`): ``(model code, n_state, constants, n_saved, columns, weights, y_eq,
    probe_steps)``, the arrays contiguous and empty when not asked for. ``parameters``: the model's keywords.
    Raises ``ValueError`` as :func:`run_model` documents."""
    code, n_state, constants = _kind_constants(kind, moments, parameters)
    if method not in model_methods(kind):
        raise ValueError(f"method must be one of {', '.join(model_methods(kind))} for a {kind} model in the model "
                         f"kernels, got {method!r}" + _NOT_LIE_POISSON * (method in SPLITTINGS))
    if y.ndim != 2 or y.shape[0] != n_state or y.dtype != np.float64 or not y.flags.c_contiguous:
        raise ValueError(f"y must be a C-contiguous float64 array of shape ({n_state}, N), got {y.dtype} {y.shape}")
    n_saved = 0
    if save_every > 0:
        n_saved = 1 + n_steps // save_every + (1 if n_steps % save_every else 0)
    return (code, n_state, constants, n_saved,
            _NO_COLUMNS if columns is None else np.ascontiguousarray(columns, dtype=np.int64),
            _NO_WEIGHTS if weights is None else np.ascontiguousarray(weights, dtype=float),
            np.zeros(n_state) if y_eq is None else np.ascontiguousarray(y_eq, dtype=float),
            _NO_STEPS if probe_steps is None else np.ascontiguousarray(probe_steps, dtype=np.int64))


def run_model(kind, method, y, moments, h, n_steps, *, save_every=0, columns=None, weights=None, y_eq=None,
              probe_steps=None, drift=False, drift_limit=0.0, block=BLOCK, **parameters):
    # size: the kernels' door for the models: keywords per observer and the model's parameters, packed here into the
    # driver's flat arrays
    """Integrate an ensemble of a model with rk4, rk8 or a splitting, observing only what is asked
    (:func:`propagate_model`).

    Parameters
    ----------
    kind : str
        A model kind of ``registry.MODEL_KINDS``.
    method : {"rk4", "rk8", "symplectic_euler", "splitting2", "splitting4"}
        The splittings for a free body, gyrostat or heavy top only (:func:`model_methods`).
    y : ndarray, shape (n_state, N), float64, C-contiguous
        Initial states as columns; overwritten with the final states (a gravity gradient's quaternions are put on
        the unit sphere after every step).
    moments : array_like, shape (3,)
        Principal moments, kg m².
    h : float
        Step, s.
    n_steps : int
    save_every : int
        0 stores no trajectory; k > 0 stores the initial state, every k-th step and the final state.
    columns, weights, y_eq : array_like (k,) int, (k,), (n_state,)
        The transverse norm's components, weights and the equilibrium (needed with ``probe_steps``).
    probe_steps : array_like of int, optional
        Steps after which to record the transverse norm (0 = initial state), increasing.
    drift : bool
        Record the running maximum drift of each invariant of the model (``registry.MODELS[...].invariants``).
    drift_limit : float
        Drift that marks a sample ``STATUS_DRIFT`` (0: off).
    block : int
        Samples per SIMD block; results do not depend on it.
    **parameters
        The model's parameters by name (as :func:`model_rhs`).

    Returns
    -------
    ModelObserved

    Raises
    ------
    ValueError
        An unknown kind or method (a splitting for a gravity gradient or damper), or a state of the wrong rows.
    """
    code, n_state, constants, n_saved, columns, weights, y_eq, probe_steps = model_arguments(
        kind, method, y, moments, n_steps, parameters, save_every, columns, weights, y_eq, probe_steps)
    n = y.shape[1]
    saved = np.empty((n_saved, n_state, n))
    probes = np.empty((len(probe_steps), n))
    drifts = np.zeros((N_INVARIANTS if drift else 0, n))
    status = np.zeros(n, dtype=np.int8)
    steps_taken = np.zeros(n, dtype=np.int64)
    propagate_model(code, MODEL_METHODS[method], y, constants, float(h), int(n_steps), int(block), int(save_every),
                    saved, columns, weights, y_eq, probe_steps, probes, drifts, float(drift_limit), status,
                    steps_taken)
    n_invariants = len(model_kind(kind).invariants)
    return ModelObserved(saved if save_every > 0 else None, probes if len(probe_steps) else None,
                         drifts[:n_invariants] if drift else None, status, steps_taken)
