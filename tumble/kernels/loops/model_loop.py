"""The models' ensemble kernels: the CPU driver of every model and method through the one time loop, and the
kernels' door for the models (:func:`run_model`, :func:`model_rhs`, :func:`model_tangent`).

The state of every sample is a column of ``y`` (shape ``(n_state, N)``, ``n_state`` up to 7: the model's components
as ``registry.MODELS`` lists them, ``w1 w2 w3`` first, then the heavy top's ``g1 g2 g3``, the gravity gradient's
``q0 q1 q2 q3`` or the damper's ``s1 s2 s3``). The samples are cut into blocks that run in parallel (a share of whole blocks per thread)
through the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`, the free body's too), where the generated
per-sample step (:mod:`tumble.kernels.steps.model_steps`, from each system's module of :mod:`tumble.kernels.systems` and the
Butcher tableaux of :mod:`tumble.kernels.tableaux`) runs over a block's samples vectorised across them (SIMD lanes).

**One compiled driver per system and method.** The model and the method are codes that reach the loop as constants of
its caller (:func:`make_propagate_model`'s closure, the device kernel's), and the loop compiles that system's and that
method's step only; the observers are runtime switches on arrays that are empty when not asked for; a model's
parameters are one float array (:func:`tumble.kernels.systems.constants`: each system's named record first). So one
compiled (and cached) driver per system and method serves every combination of outputs: rk4 and rk8 for every system,
the Lie–Poisson splittings for the free body, the gyrostat and the heavy top (:mod:`tumble.kernels.steps.model_splittings`).
The ``free`` model is the gyrostat with ``h = 0`` (the free body's own fused steps run by :func:`tumble.kernels.run`).

**Observers.** The final state (in place); the state every ``save_every`` steps; the transverse norm
``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` at given steps (the arrays of
:class:`tumble.physics.models.Transverse`); the running maximum of each invariant's drift ``|x − x0| / scale0``
(each system's ``invariants``, :mod:`tumble.kernels.systems`; the gravity gradient's Jacobi integral is scaled by the
sum of its three terms' magnitudes; the damper tracks ``|L|²`` only, its energy decays). Status and early stop: the
loop's (:mod:`tumble.kernels.loops.block_loop`).

**Gravity gradient.** The quaternion is divided by its norm after every step (in the generated block loop): the
right-hand side keeps ``|q|`` exactly but rk4 and rk8 only to their order, and off the unit sphere the attitude rows
``c2``, ``c3`` of the torque and of ``w + n c2`` are no rotation's. A projection after each step keeps the method's
order and puts every observer (probes, trajectory, drifts) on the unit sphere; the ``|q|²`` drift then reports round-off
(and a non-unit initial quaternion, rescaled by the first step). The probes' ``y_eq`` is the orbit-following
equilibrium ``w = (0, −n, 0)``, ``q = (1, 0, 0, 0)``: subtracting it from the norm's columns ``(w1, w2, w3, q1, q2,
q3)`` is the ``Transverse.centre`` of the physics layer.
"""

import math
from typing import NamedTuple

import numpy as np

from ...registry import LIE_POISSON_MODELS, MODEL_KINDS, MODEL_PARAMETERS, MODEL_STEPPING, STEPPING, model_kind
from ...registry import model_methods  # the names the model kernels run for a kind (re-exported)
from .block_loop import N_INVARIANTS, block_scratch, run_block_inlined
from ..jit import jit
from ..threads import in_parallel
from ..steps.model_splittings import SPLITTINGS
from .sample_loop import saved_count
from ..steps.model_steps import rate_columns, rate_sample, tangent_columns, tangent_sample
from ..steps.system_steps import cacheable
from ..systems import constants
from ..trig import _min

__all__ = ["MODEL_CODES", "MODEL_METHODS", "ModelObserved", "SPLITTING_KINDS", "make_propagate_model",
           "model_arguments", "model_methods", "model_rhs", "model_tangent", "propagate_model", "rate_sample",
           "rate_sample_parameters", "run_model", "run_system_blocks", "tangent_sample"]

#: Kernel codes of the models: their index in ``registry.MODEL_KINDS``. The kernels step every model of this table,
#: whatever ``registry.MODELS``' ``implemented`` says (that flag is the studies'; the gravity gradient and the damper
#: have kernels before they have studies).
MODEL_CODES = {kind: code for code, kind in enumerate(MODEL_KINDS)}

#: The methods the model kernels run, by name: kernel id (index in ``registry.STEPPING``, as the free body's): rk4 and
#: rk8 for every model, the Lie–Poisson splittings (:mod:`tumble.kernels.steps.model_splittings`) for ``SPLITTING_KINDS``.
MODEL_METHODS = {name: STEPPING.index(name) for name in MODEL_STEPPING}

#: The models the splittings apply to (``registry.LIE_POISSON_MODELS``, which says why).
SPLITTING_KINDS = LIE_POISSON_MODELS


# Samples per SIMD block: the free body's 256 (kernels.loops.methods.BLOCK); results do not depend on it.
BLOCK = 256


def make_propagate_model(model, method, observing=True):
    """The CPU's driver of the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`) for ``model`` and ``method``
    (codes of :data:`MODEL_CODES` and :data:`MODEL_METHODS`), with its observers or without (``observing``: a plain
    integration asks for none), constants of the closure: the loop compiles that system's and that method's step only,
    and the observers only where a run may ask for them. numba's disk cache tells the closures apart by their
    constants (a user's System's code that keys nothing is not cached:
    :func:`tumble.kernels.steps.system_steps.cacheable`)."""

    @jit(cache=cacheable(model))
    def propagate(y, constants, h, n_steps, block, save_every, saved, columns, weights, y_eq, probe_steps, probes,
                  drift, drift_limit, status, steps_taken, start, stop):
        n_state, n = y.shape
        no_flips, no_count = np.empty((n, 0)), np.empty(0, dtype=np.int64)  # a model's flips are not observed
        no_fit = np.empty((0, 1))
        no_stops = (0.0, np.int64(0))  # (not the literal 0: the free body's drivers pass an int64)
        for lo in range(start, stop, block):
            m = _min(block, stop - lo)
            run_block_inlined(model, method, True, observing, y, lo, block_scratch(n_state, m), constants, 0.0, h,
                              n_steps, save_every, saved, (columns, weights, y_eq), probe_steps, probes,
                              (0, no_flips, no_count), drift, drift_limit, status, steps_taken, no_stops,
                              (0, None, None), (0.0, 0, 0.0, no_fit, no_count))

    return propagate


#: The CPU drivers made so far, by (model code, method code, observing); each compiles (or loads) on its first call.
_DRIVERS = {}


def propagate_model(model, method, y, constants, h, n_steps, block,
                    save_every, saved,
                    columns, weights, y_eq, probe_steps, probes,
                    drift, drift_limit,
                    status, steps_taken):
    """Advance every sample ``n_steps`` steps of size ``h`` of ``method`` on ``model``, observing as asked: the CPU's
    wrapper of the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`), blocks of ``block`` samples in parallel
    (a share of whole blocks per thread, :func:`tumble.kernels.threads.in_parallel`).

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
    observing = len(probe_steps) > 0 or drift.shape[0] > 0 or drift_limit > 0.0
    key = (int(model), int(method), bool(observing))
    driver = _DRIVERS.get(key)
    if driver is None:
        driver = _DRIVERS[key] = make_propagate_model(*key)
    in_parallel(driver, y.shape[1], y, constants, h, n_steps, block, save_every, saved, columns, weights, y_eq,
                probe_steps, probes, drift, drift_limit, status, steps_taken, granule=int(block))


def run_system_blocks(code, method, y, constants, h, n_steps, save_every=0, block=BLOCK):
    """Integrate an ensemble of a user's System on the block path: ``code`` its steps'
    (:func:`tumble.kernels.steps.system_steps.system_code`), ``method`` rk4 or rk8 (:data:`MODEL_METHODS`), ``y`` (n, N)
    the states as columns (overwritten with the final ones), ``constants`` its parameters; stores as
    :func:`run_model`, no other observer. Returns :class:`ModelObserved` (no probes, no drift)."""
    n_state, n = y.shape
    saved = np.empty((saved_count(n_steps, save_every), n_state, n))
    status = np.zeros(n, dtype=np.int8)
    steps_taken = np.zeros(n, dtype=np.int64)
    propagate_model(code, MODEL_METHODS[method], y, np.ascontiguousarray(constants, dtype=float), float(h),
                    int(n_steps), int(block), int(save_every), saved, _NO_COLUMNS, _NO_WEIGHTS, np.zeros(n_state),
                    _NO_STEPS, np.empty((0, n)), np.zeros((0, n)), 0.0, status, steps_taken)
    return ModelObserved(saved if save_every > 0 else None, None, None, status, steps_taken)


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
    does, and the invariants of moments of 1e-170 or 1e200 kg m² stay in range (as :func:`tumble.kernels.loops.methods.run`).
    ``parameters``: the model's keywords of :func:`run_model`."""
    if kind not in MODEL_CODES:
        raise ValueError(f"model kind must be one of {', '.join(MODEL_CODES)} for the kernels, got {kind!r}")
    moments = np.asarray(moments, dtype=float)
    unit = math.ldexp(1.0, -math.frexp(float(moments.max()))[1])
    scaled = {key: np.asarray(value, dtype=float) * unit if key in _SCALED else value
              for key, value in parameters.items()}
    return MODEL_CODES[kind], len(model_kind(kind).state), constants(kind, moments * unit, scaled)


def rate_sample_parameters(kind, moments, parameters):
    """The parameters ``p`` of :func:`tumble.kernels.steps.model_steps.rate_sample` (and ``tangent_sample``) for model
    ``kind``: its code, then its constants (:func:`_kind_constants`), float64 (1 + N_CONSTANTS,).

    With them a built-in system runs as a user's ``System`` does, through the per-sample loop of
    :mod:`tumble.kernels.loops.sample_loop`: on either device, with any tableau of :data:`tumble.kernels.tableaux.TABLEAUX`,
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
    :mod:`tumble.kernels.cuda.models`): ``(model code, n_state, constants, n_saved, columns, weights, y_eq,
    probe_steps)``, the arrays contiguous and empty when not asked for. ``parameters``: the model's keywords.
    Raises ``ValueError`` as :func:`run_model` documents."""
    code, n_state, constants = _kind_constants(kind, moments, parameters)
    if method not in model_methods(kind):
        raise ValueError(f"method must be one of {', '.join(model_methods(kind))} for a {kind} model in the model "
                         f"kernels, got {method!r}" + _NOT_LIE_POISSON * (method in SPLITTINGS))
    if y.ndim != 2 or y.shape[0] != n_state or y.dtype != np.float64 or not y.flags.c_contiguous:
        raise ValueError(f"y must be a C-contiguous float64 array of shape ({n_state}, N), got {y.dtype} {y.shape}")
    n_saved = saved_count(n_steps, save_every)
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
