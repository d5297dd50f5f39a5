"""The models' ensemble kernels: one parallel driver for every model and method, observers on the fly (issue 18).

The state of every sample is a column of ``y`` (shape ``(n_state, N)``, ``n_state`` up to 7: the model's components
as ``registry.MODELS`` lists them, ``w1 w2 w3`` first, then the heavy top's ``g1 g2 g3``, the gravity gradient's
``q0 q1 q2 q3`` or the damper's ``s1 s2 s3``). As in the free body's
driver (:mod:`tumble.kernels.drivers`) the samples are cut into blocks that run in parallel (``prange``); each
block is copied into contiguous component rows (structure of arrays) and the generated per-sample step
(:mod:`tumble.kernels.model_steps`, from the Butcher tableaux of :mod:`tumble.kernels.tableaux`) runs in a loop
over the block's samples that the compiler vectorises across samples (SIMD lanes).

**One compiled variant.** The model and the method are runtime codes, tested once per block and step, outside the
loop over the samples; the observers are runtime switches on arrays that are empty when not asked for; a model's
parameters are one float array of a single layout (:func:`tumble.kernels.model_rates.model_constants`). So one
compiled (and cached) driver serves the free body, the gyrostat, the heavy top, the gravity gradient and the damper,
rk4 and rk8 (and the Lie–Poisson splittings for the free body, the gyrostat and the heavy top:
:mod:`tumble.kernels.model_splittings`), and every combination of outputs. The free body runs as the gyrostat with ``h = 0`` (the free body keeps its own, faster
driver for everything else: :func:`tumble.kernels.run`).

**Observers.** The final state (in place); the state every ``save_every`` steps; the transverse norm
``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` at given steps (the arrays of
:class:`tumble.physics.models.Transverse`); the running maximum of each invariant's drift ``|x − x0| / scale0``
(the ``*_invariants`` of :mod:`tumble.kernels.model_rates`: the scale is the invariant itself where it is
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
``drift_limit``; each step a branch-free screening pass over the block, :func:`_drift_suspects`, finds whether any
sample comes near either, and only then do the exact per-sample checks run: run every step, those scalar loops had
cost as much as a gravity gradient's rk4 step, the screen costs a fifth of it); a sample with a bad status stops and keeps the state it had when it was caught; its later probes
are NaN. Samples never interact: results do not depend on the number of threads or on the block size.
"""

import math
from typing import NamedTuple

import numpy as np
from numba import prange

from ..registry import LIE_POISSON_MODELS, MODEL_KINDS, STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK, STEPPING, model_kind
from .jit import jit
from .model_rates import (
    N_CONSTANTS,
    N_INVARIANTS,
    damper_invariants,
    damper_rate,
    gravity_gradient_invariants,
    gravity_gradient_rate,
    gyrostat_invariants,
    gyrostat_rate,
    heavy_top_invariants,
    heavy_top_rate,
    model_constants,
)
from .model_splittings import SPLITTINGS, gyrostat_splitting_block, heavy_top_splitting_block
from .model_steps import (
    damper_rk4_block,
    damper_rk8_block,
    gravity_gradient_rk4_block,
    gravity_gradient_rk8_block,
    gyrostat_rk4_block,
    gyrostat_rk8_block,
    heavy_top_rk4_block,
    heavy_top_rk8_block,
)

__all__ = ["MODEL_CODES", "MODEL_METHODS", "ModelObserved", "SPLITTING_KINDS", "model_arguments", "model_constants",
           "model_methods",
           "model_rhs", "propagate_model", "run_model"]

#: Kernel codes of the models: their index in ``registry.MODEL_KINDS``. The kernels step every model of this table,
#: whatever ``registry.MODELS``' ``implemented`` says (that flag is the studies'; the gravity gradient and the damper
#: have kernels before they have studies).
MODEL_FREE, MODEL_GYROSTAT, MODEL_HEAVY_TOP, MODEL_GRAVITY_GRADIENT, MODEL_DAMPER = (
    MODEL_KINDS.index(k) for k in ("free", "gyrostat", "heavy_top", "gravity_gradient", "damper"))
MODEL_CODES = {"free": MODEL_FREE, "gyrostat": MODEL_GYROSTAT, "heavy_top": MODEL_HEAVY_TOP,
               "gravity_gradient": MODEL_GRAVITY_GRADIENT, "damper": MODEL_DAMPER}

#: The methods the model kernels run, by name: kernel id (index in ``registry.STEPPING``, as the free body's): rk4 and
#: rk8 for every model, the Lie–Poisson splittings (:mod:`tumble.kernels.model_splittings`) for ``SPLITTING_KINDS``.
MODEL_METHODS = {**{name: STEPPING.index(name) for name in ("rk4", "rk8")}, **SPLITTINGS}
_RK4, _RK8 = MODEL_METHODS["rk4"], MODEL_METHODS["rk8"]

#: The models the splittings apply to (``registry.LIE_POISSON_MODELS``, which says why).
SPLITTING_KINDS = LIE_POISSON_MODELS


def model_methods(kind):
    """The names of the methods the model kernels run for model ``kind`` (rk4 and rk8 first)."""
    return tuple(name for name in MODEL_METHODS if name not in SPLITTINGS or kind in SPLITTING_KINDS)

#: Steps between two checks for non-finite states when no drift is tracked.
CHECK_EVERY = 32

# Samples per SIMD block: the free body's 256 (kernels.methods.BLOCK); results do not depend on it.
BLOCK = 256

_TINY = 2.2250738585072014e-308  # smallest normal float: a zero scale gives a zero drift, not 0/0


@jit(inline=True)
def _constants(a):
    """The constants array as a tuple of scalars (kept in registers by the step loops)."""
    return (a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8], a[9], a[10], a[11], a[12], a[13], a[14], a[15],
            a[16], a[17], a[18], a[19], a[20], a[21], a[22], a[23], a[24], a[25])


@jit
def _step(model, method, ys, h, c, x0):
    """Advance every sample of a block (``ys``, shape (n_state, m)) by one step; branches outside the sample loop.
    ``x0``: the samples' initial invariants (a gyrostat's splittings put ``|I w + h|²``, ``x0[1]``, back on it)."""
    if model == MODEL_HEAVY_TOP:
        if method == _RK4:
            heavy_top_rk4_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], h, c)
        elif method == _RK8:
            heavy_top_rk8_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], h, c)
        else:
            heavy_top_splitting_block(method, ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], h, c)
    elif model == MODEL_GRAVITY_GRADIENT:
        if method == _RK4:
            gravity_gradient_rk4_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], ys[6], h, c)
        else:
            gravity_gradient_rk8_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], ys[6], h, c)
    elif model == MODEL_DAMPER:
        if method == _RK4:
            damper_rk4_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], h, c)
        else:
            damper_rk8_block(ys[0], ys[1], ys[2], ys[3], ys[4], ys[5], h, c)
    elif method == _RK4:
        gyrostat_rk4_block(ys[0], ys[1], ys[2], h, c)
    elif method == _RK8:
        gyrostat_rk8_block(ys[0], ys[1], ys[2], h, c)
    else:
        gyrostat_splitting_block(method, ys[0], ys[1], ys[2], h, c, x0[1])


@jit(inline=True)
def _invariants(model, ys, i, c):
    """``(x1, x2, x3, scale1, scale2, scale3)`` of sample ``i`` of a block."""
    if model == MODEL_HEAVY_TOP:
        return heavy_top_invariants(ys[0, i], ys[1, i], ys[2, i], ys[3, i], ys[4, i], ys[5, i], c)
    if model == MODEL_GRAVITY_GRADIENT:
        return gravity_gradient_invariants(ys[0, i], ys[1, i], ys[2, i], ys[3, i], ys[4, i], ys[5, i], ys[6, i], c)
    if model == MODEL_DAMPER:
        return damper_invariants(ys[0, i], ys[1, i], ys[2, i], ys[3, i], ys[4, i], ys[5, i], c)
    return gyrostat_invariants(ys[0, i], ys[1, i], ys[2, i], c)


@jit
def _initial_invariants(model, ys, c, x0, scale):
    """Each sample's invariants ``x0`` (3, m) and their drift scales (3, m) at the start."""
    for i in range(ys.shape[1]):
        x1, x2, x3, s1, s2, s3 = _invariants(model, ys, i, c)
        x0[0, i], x0[1, i], x0[2, i] = x1, x2, x3
        scale[0, i], scale[1, i], scale[2, i] = max(s1, _TINY), max(s2, _TINY), max(s3, _TINY)


@jit
def _freeze(i, k, code, ys, active, frozen, status, last):
    """Stop sample ``i`` of a block after step ``k``: keep its state, record why and when."""
    active[i] = False
    frozen[:, i] = ys[:, i]
    if code != STATUS_OK:
        status[i] = code
    last[i] = k


@jit
def _restore_frozen(ys, active, frozen):
    """The step moved every sample of the block; put the stopped ones back."""
    for i in range(ys.shape[1]):
        if not active[i]:
            ys[:, i] = frozen[:, i]


@jit
def _check_finite(ys, active, k, frozen, status, last):
    """Stop samples with a non-finite component; returns how many."""
    stopped = 0
    for i in range(ys.shape[1]):
        if active[i]:
            finite = True
            for j in range(ys.shape[0]):
                finite = finite and math.isfinite(ys[j, i])
            if not finite:
                _freeze(i, k, STATUS_NONFINITE, ys, active, frozen, status, last)
                stopped += 1
    return stopped


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
            _freeze(i, k, STATUS_DRIFT, ys, active, frozen, status, last)
            stopped += 1
    return stopped


#: The screening pass (:func:`_drift_suspects`) flags drifts beyond ``limit (1 − SCREEN_RTOL) − SCREEN_ATOL``, so
#: that its rounding (vectorised, perhaps fused differently from the exact observer's: a drift is a difference of
#: invariants of the size of their scale, so a few eps of it) can never miss a sample the exact check stops.
SCREEN_RTOL = 1e-6
SCREEN_ATOL = 1e-13


@jit(inline=True)
def _suspect(i, active, x0, scale, screen, x1, x2, x3, total):
    """1 if sample ``i`` of a block is active and drifting beyond ``screen`` or has a non-finite component (``total``,
    the sum of its components, is then not finite; a finite sum that overflows is a false alarm, checked exactly),
    else 0; no branch, no inner loop, so that the loop over samples vectorises."""
    calm = ((abs(x1 - x0[0, i]) <= screen * scale[0, i]) & (abs(x2 - x0[1, i]) <= screen * scale[1, i])
            & (abs(x3 - x0[2, i]) <= screen * scale[2, i]) & math.isfinite(total)) | (not active[i])
    return 0 if calm else 1  # (written so: a branch on active[i] stops LLVM vectorising the loop)


@jit
def _drift_suspects(model, ys, active, c, x0, scale, screen):
    """Whether any active sample of a block is non-finite or has an invariant's drift beyond ``screen``: one pass
    per model without stores, calls or inner loops (it vectorises across samples, unlike the exact observers,
    whose freezing of a sample makes their loops scalar), so that a step with nothing to stop costs a fraction of
    the exact checks. The exact observers (:func:`_check_finite`, :func:`_observe_drift`) run only when it finds a
    suspect."""
    suspects = 0
    m = ys.shape[1]
    if model == MODEL_GRAVITY_GRADIENT:
        for i in range(m):
            w1, w2, w3, q0, q1, q2, q3 = ys[0, i], ys[1, i], ys[2, i], ys[3, i], ys[4, i], ys[5, i], ys[6, i]
            x1, x2, x3, _, _, _ = gravity_gradient_invariants(w1, w2, w3, q0, q1, q2, q3, c)
            total = w1 + w2 + w3 + q0 + q1 + q2 + q3
            suspects += _suspect(i, active, x0, scale, screen, x1, x2, x3, total)
    elif model == MODEL_HEAVY_TOP or model == MODEL_DAMPER:
        for i in range(m):
            a1, a2, a3, b1, b2, b3 = ys[0, i], ys[1, i], ys[2, i], ys[3, i], ys[4, i], ys[5, i]
            if model == MODEL_HEAVY_TOP:
                x1, x2, x3, _, _, _ = heavy_top_invariants(a1, a2, a3, b1, b2, b3, c)
            else:
                x1, x2, x3, _, _, _ = damper_invariants(a1, a2, a3, b1, b2, b3, c)
            suspects += _suspect(i, active, x0, scale, screen, x1, x2, x3, a1 + a2 + a3 + b1 + b2 + b3)
    else:
        for i in range(m):
            w1, w2, w3 = ys[0, i], ys[1, i], ys[2, i]
            x1, x2, x3, _, _, _ = gyrostat_invariants(w1, w2, w3, c)
            suspects += _suspect(i, active, x0, scale, screen, x1, x2, x3, w1 + w2 + w3)
    return suspects > 0


@jit
def _observe_norm(ys, active, columns, weights, y_eq, probes, lo, row):
    """The weighted transverse norm of each sample into ``probes[row]`` (NaN for stopped samples)."""
    for i in range(ys.shape[1]):
        total = 0.0
        for j in range(columns.shape[0]):
            d = ys[columns[j], i] - y_eq[columns[j]]
            total += weights[j] * d * d
        probes[row, lo + i] = math.sqrt(total) if active[i] else np.nan


@jit(parallel=True)
def propagate_model(model, method, y, constants, h, n_steps, block,
                    save_every, saved,
                    columns, weights, y_eq, probe_steps, probes,
                    drift, drift_limit,
                    status, steps_taken):
    # size: the one driver of every model, method and observer: numba takes flat arrays and scalars (run_model packs
    # them), and the step loop with its observer calls stays one prange body so that a block's samples move together
    # in SIMD lanes (the observers are the helpers above)
    """Advance every sample ``n_steps`` steps of size ``h`` of ``method`` on ``model``, observing as asked.

    Parameters
    ----------
    model, method : int
        :data:`MODEL_CODES` value; :data:`MODEL_METHODS` value (rk4, rk8; a splitting for a free body, gyrostat
        or heavy top).
    y : ndarray, shape (n_state, N), float64
        The states (rad/s, then the model's own units); overwritten with the final (or frozen) states.
    constants : ndarray, shape (N_CONSTANTS,)
        :func:`model_constants` of the model.
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
    n_state, n = y.shape
    c = _constants(constants)
    n_blocks = (n + block - 1) // block
    n_probes = probe_steps.shape[0]
    store = saved.shape[0] > 0
    record_drift = drift.shape[0] > 0
    track_drift = record_drift or drift_limit > 0.0
    screen = drift_limit * (1.0 - SCREEN_RTOL) - SCREEN_ATOL if drift_limit > 0.0 else math.inf
    for ib in prange(n_blocks):
        lo = ib * block
        hi = min(lo + block, n)
        m = hi - lo
        ys = np.empty((n_state, m))
        ys[:, :] = y[:, lo:hi]
        active = np.ones(m, dtype=np.bool_)
        frozen = np.empty((n_state, m))
        last = np.full(m, n_steps, dtype=np.int64)
        block_status = status[lo:hi]
        block_status[:] = STATUS_OK
        x0 = np.empty((N_INVARIANTS, m))
        scale = np.empty((N_INVARIANTS, m))
        _initial_invariants(model, ys, c, x0, scale)
        n_frozen = _check_finite(ys, active, 0, frozen, block_status, last)
        slot = 0
        if store:
            saved[0, :, lo:hi] = ys
            slot = 1
        probe = 0
        while probe < n_probes and probe_steps[probe] == 0:
            _observe_norm(ys, active, columns, weights, y_eq, probes, lo, probe)
            probe += 1
        ran = 0
        for k in range(n_steps):
            if n_frozen == m:
                break
            _step(model, method, ys, h, c, x0)
            if n_frozen:
                _restore_frozen(ys, active, frozen)
            ran = k + 1
            # with drifts tracked every step, the exact observers run only for a block with a suspect (or whose
            # drifts are recorded): the screen's "nothing to stop" is exact, its suspects are checked exactly
            exact = track_drift and (record_drift or _drift_suspects(model, ys, active, c, x0, scale, screen))
            if exact or (not track_drift and (ran % CHECK_EVERY == 0 or ran == n_steps)):
                n_frozen += _check_finite(ys, active, ran, frozen, block_status, last)
            if exact:
                n_frozen += _observe_drift(model, ys, active, c, x0, scale, drift, lo, drift_limit, ran, frozen,
                                           block_status, last)
            if store and (ran % save_every == 0 or ran == n_steps):
                saved[slot, :, lo:hi] = ys
                slot += 1
            while probe < n_probes and probe_steps[probe] == ran:
                _observe_norm(ys, active, columns, weights, y_eq, probes, lo, probe)
                probe += 1
        # A block whose samples all stopped fills the rest of its outputs: the frozen states, NaN probes.
        if store:
            for k in range(ran, n_steps):
                if (k + 1) % save_every == 0 or k + 1 == n_steps:
                    saved[slot, :, lo:hi] = ys
                    slot += 1
        while probe < n_probes:
            probes[probe, lo:hi] = np.nan
            probe += 1
        y[:, lo:hi] = ys
        steps_taken[lo:hi] = last


@jit(parallel=True)
def _rhs_columns(model, y, constants, out):
    """``out = f(y)`` for states as columns ``y`` (n_state, N)."""
    c = _constants(constants)
    for i in prange(y.shape[1]):
        if model == MODEL_HEAVY_TOP:
            r = heavy_top_rate(y[0, i], y[1, i], y[2, i], y[3, i], y[4, i], y[5, i], c)
            for j in range(6):
                out[j, i] = r[j]
        elif model == MODEL_GRAVITY_GRADIENT:
            r7 = gravity_gradient_rate(y[0, i], y[1, i], y[2, i], y[3, i], y[4, i], y[5, i], y[6, i], c)
            for j in range(7):
                out[j, i] = r7[j]
        elif model == MODEL_DAMPER:
            r = damper_rate(y[0, i], y[1, i], y[2, i], y[3, i], y[4, i], y[5, i], c)
            for j in range(6):
                out[j, i] = r[j]
        else:
            r3 = gyrostat_rate(y[0, i], y[1, i], y[2, i], c)
            for j in range(3):
                out[j, i] = r3[j]


class ModelObserved(NamedTuple):
    """What :func:`run_model` returns; an output that was not asked for is None."""

    saved: np.ndarray | None  # (n_saved, n_state, N)
    probes: np.ndarray | None  # (P, N), transverse norm
    drift: np.ndarray | None  # (n_invariants, N), running max of each invariant's drift (registry's order)
    status: np.ndarray  # (N,) int8
    steps_taken: np.ndarray  # (N,) int64


def _kind_constants(kind, moments, parameters):
    """``(model code, n_state, constants)``, the moments (and the parameters in their units: the rotor, mgl, J and
    c with them; not the orbit rate) divided by the power of two nearest the largest moment: the equations do not
    change, no bit of the rates or relative drifts does, and the invariants of moments of 1e-170 or 1e200 kg m² stay
    in range (as :func:`tumble.kernels.methods.run`). ``parameters``: the model's keywords of :func:`run_model`."""
    if kind not in MODEL_CODES:
        raise ValueError(f"model kind must be one of {', '.join(MODEL_CODES)} for the kernels, got {kind!r}")
    moments = np.asarray(moments, dtype=float)
    unit = math.ldexp(1.0, -math.frexp(float(moments.max()))[1])
    constants = model_constants(moments * unit, np.asarray(parameters["rotor"], dtype=float) * unit,
                                float(parameters["mgl"]) * unit, float(parameters["orbit_rate"]),
                                float(parameters["damper_inertia"]) * unit, float(parameters["damping"]) * unit)
    assert constants.shape == (N_CONSTANTS,)
    return MODEL_CODES[kind], len(model_kind(kind).state), constants


def model_rhs(kind, y, moments, *, rotor=(0.0, 0.0, 0.0), mgl=0.0, orbit_rate=0.0, damper_inertia=0.0,
              damping=0.0):
    """The kernels' right-hand side ``f(y)`` of model ``kind`` at states given as columns (for tests).

    Parameters
    ----------
    kind : {"free", "gyrostat", "heavy_top", "gravity_gradient", "damper"}
    y : ndarray, shape (n_state, N)
        States (rad/s, then the model's own units).
    moments : array_like, shape (3,)
        Principal moments, kg m².
    rotor, mgl, orbit_rate, damper_inertia, damping
        The gyrostat's ``h`` (N m s), the heavy top's ``M g l`` (N m), the gravity gradient's ``n`` (rad/s), the
        damper's ``J`` (kg m²) and ``c`` (N m s); those the model does not have are ignored.

    Returns
    -------
    ndarray, shape (n_state, N)

    Raises
    ------
    ValueError
        An unknown kind or a state of the wrong number of rows.
    """
    code, n_state, constants = _kind_constants(kind, moments, dict(
        rotor=rotor, mgl=mgl, orbit_rate=orbit_rate, damper_inertia=damper_inertia, damping=damping))
    y = np.ascontiguousarray(y, dtype=float)
    if y.ndim != 2 or y.shape[0] != n_state:
        raise ValueError(f"y must have shape ({n_state}, N) for a {kind} model, got shape {y.shape}")
    out = np.empty_like(y)
    _rhs_columns(code, y, constants, out)
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


def run_model(kind, method, y, moments, h, n_steps, *, rotor=(0.0, 0.0, 0.0), mgl=0.0, orbit_rate=0.0,
              damper_inertia=0.0, damping=0.0, save_every=0, columns=None, weights=None, y_eq=None, probe_steps=None,
              drift=False, drift_limit=0.0, block=BLOCK):
    # size: the kernels' door for the models: keywords per model parameter and observer, packed here into the
    # driver's flat arrays
    """Integrate an ensemble of a model with rk4, rk8 or a splitting, observing only what is asked
    (:func:`propagate_model`).

    Parameters
    ----------
    kind : {"free", "gyrostat", "heavy_top", "gravity_gradient", "damper"}
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
    rotor, mgl, orbit_rate, damper_inertia, damping
        The gyrostat's ``h`` (N m s, body frame), the heavy top's ``M g l`` (N m), the gravity gradient's orbit rate
        ``n`` (rad/s), the damper's ``J`` (kg m²) and ``c`` (N m s); those the model does not have are ignored.
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

    Returns
    -------
    ModelObserved

    Raises
    ------
    ValueError
        An unknown kind or method (a splitting for a gravity gradient or damper), or a state of the wrong rows.
    """
    code, n_state, constants, n_saved, columns, weights, y_eq, probe_steps = model_arguments(
        kind, method, y, moments, n_steps, dict(rotor=rotor, mgl=mgl, orbit_rate=orbit_rate,
                                                damper_inertia=damper_inertia, damping=damping),
        save_every, columns, weights, y_eq, probe_steps)
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
