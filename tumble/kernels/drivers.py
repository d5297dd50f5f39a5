"""The free body's time loop, written once for the CPU and the device: every fixed-step method, every sample,
observers on the fly.

The loop (:func:`make_run_block`) runs a block of samples through the whole run. The CPU's driver
(:func:`make_propagate`) runs blocks in parallel; the device's kernel (:mod:`tumble.kernels.cuda`) runs a block of one
sample per thread. Samples are cut into blocks of ``block`` samples; blocks run in parallel (``prange``) and each block is
copied into three contiguous component arrays (structure of arrays) so that the per-sample step
(:mod:`tumble.kernels.fused`) vectorises across samples. Samples never interact, so the results do not
depend on the number of threads or on the block size.

Observers are runtime switches: an output that was not asked for is an empty array (a zero-length axis), and
its branch, outside the loop over the samples of a block, is skipped; the branches cost nothing measurable
(``benchmarks/engine.py``). The method is not: it is a constant of the driver (:func:`make_propagate`) and of the
device kernel, and the loop compiles its one step (:func:`_method_step`). So one compiled driver per method and
torque type (none, a built-in profile, a user's function) serves every combination of observers, and a run compiles
(or loads) only the driver of the method it runs. Memory is O(samples) unless a trajectory is stored.

Per-sample status: ``STATUS_OK``, ``STATUS_NONFINITE`` (a component became NaN or inf) or ``STATUS_DRIFT``
(torque-free only: ``|L|**2`` or the energy drifted by more than ``drift_limit``, relative). A sample with a
bad status stops stepping and keeps the state it had when it was caught; so does a sample whose measurement
is complete (early stop, see ``stop_norm`` and ``stop_flips``).
"""

import math

import numpy as np
from numba import prange, types
from numba.core.errors import TypingError
from numba.extending import overload

from ..registry import STATUS_DRIFT, STATUS_NAMES, STATUS_NONFINITE, STATUS_OK, STEPPING  # noqa: F401
from .fused import rk4_block, rk8_block, splitting2_block, splitting4_block, symplectic_euler_block
from .block_parts import check_finite, freeze, restore_frozen, store, store_initial, store_rest
from .fits import GROWTH_WINDOW_START, growth_window_add, growth_window_rate
from .jit import FASTMATH, jit
from .steppers import (
    energy,
    euler_rate,
    implicit_midpoint_block,
    l_squared,
    splitting2_torque_block,
    splitting4_torque_block,
    symplectic_euler_torque_block,
)

# Kernel ids: a method's index in the registry's table of fixed-step methods.
RK4, RK8, SYMPLECTIC_EULER, SPLITTING2, SPLITTING4, IMPLICIT_MIDPOINT = (
    STEPPING.index(name)
    for name in ("rk4", "rk8", "symplectic_euler", "splitting2", "splitting4", "implicit_midpoint"))

#: Each method's step of a block: the generated ones (:mod:`tumble.kernels.fused`; torque-free, and the Runge–Kutta
#: methods with a torque too), and the splittings' compositions of sub-flows with a torque.
_FUSED_STEPS = {RK4: rk4_block, RK8: rk8_block, SYMPLECTIC_EULER: symplectic_euler_block, SPLITTING2: splitting2_block,
                SPLITTING4: splitting4_block}
_TORQUE_SPLITTINGS = {SYMPLECTIC_EULER: symplectic_euler_torque_block, SPLITTING2: splitting2_torque_block,
                      SPLITTING4: splitting4_torque_block}


# How often (in steps) samples are checked for non-finite values when no per-step observer runs anyway.
CHECK_EVERY = 32
# Newton iterations on the cubic Hermite interpolant that locates a sign change inside a step.
_FLIP_NEWTON = 4


@jit(inline=True)
def _hermite_root(y0, d0, y1, d1, h):
    """Fraction ``s`` in [0, 1] of the step where the cubic Hermite interpolant of ``(y0, d0), (y1, d1)``
    vanishes; linear interpolation refined by Newton steps (O(h**4) accurate in time)."""
    s = y0 / (y0 - y1)
    for _ in range(_FLIP_NEWTON):
        s2 = s * s
        s3 = s2 * s
        p = ((2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * d0 + (-2 * s3 + 3 * s2) * y1
             + (s3 - s2) * h * d1)
        dp = ((6 * s2 - 6 * s) * y0 + (3 * s2 - 4 * s + 1) * h * d0 + (-6 * s2 + 6 * s) * y1
              + (3 * s2 - 2 * s) * h * d1)
        if dp != 0.0:
            s = s - p / dp
        s = min(1.0, max(0.0, s))
    return s


# --- per-sample observers: one sample's state in scalars, shared by the block loops below and the device kernels
# (tumble/kernels/cuda.py, which numba-cuda compiles them for) ------------------------------------------------------

@jit(inline=True)
def component(w1, w2, w3, k):
    """Component ``k`` (0-based) of ``(w1, w2, w3)``."""
    if k == 0:
        return w1
    return w2 if k == 1 else w3


@jit(inline=True)
def transverse_norm(w1, w2, w3, axis, weights):
    """Weighted transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` about ``axis`` (0-based), ``weights`` (3,) rad/s."""
    b, c = (axis + 1) % 3, (axis + 2) % 3
    wb, wc = component(w1, w2, w3, b), component(w1, w2, w3, c)
    return math.sqrt(weights[b] * wb * wb + weights[c] * wc * wc)


@jit(inline=True)
def flip_in_step(axis, t, h, p1, p2, p3, w1, w2, w3, body, torque_kind, torque_params, torque_fn):
    """``(flipped, time)``: whether the ``axis`` component changed sign during the step ``[t, t + h]`` from
    ``(p1, p2, p3)`` to ``(w1, w2, w3)``, and when (cubic Hermite interpolation, s; 0.0 when it did not)."""
    ya, yp = component(w1, w2, w3, axis), component(p1, p2, p3, axis)
    if (ya < 0.0 < yp) or (yp < 0.0 < ya) or (ya == 0.0 and yp != 0.0):
        r1, r2, r3 = euler_rate(t, p1, p2, p3, body, torque_kind, torque_params, torque_fn)
        d0 = component(r1, r2, r3, axis)
        r1, r2, r3 = euler_rate(t + h, w1, w2, w3, body, torque_kind, torque_params, torque_fn)
        d1 = component(r1, r2, r3, axis)
        return True, t + h * _hermite_root(yp, d0, ya, d1, h)
    return False, 0.0


@jit(inline=True)
def invariant_errors(w1, w2, w3, body, e0, l0):
    """``(|E/E0 - 1|, ||L|²/|L0|² - 1|)``: the relative errors of the energy and ``|L|**2``."""
    return abs(energy(w1, w2, w3, body) / e0 - 1.0), abs(l_squared(w1, w2, w3, body) / l0 - 1.0)


@jit(inline=True)
def drifted(de, dl, drift_limit):
    """The invariant errors are past ``drift_limit`` (<= 0: never); NaN counts as past."""
    return drift_limit > 0.0 and not (de <= drift_limit and dl <= drift_limit)


@jit(inline=True)
def measurement_complete(reached, stop_norm, stop_flips, flip_count):
    """A sample's measurement is complete: its norm reached ``stop_norm`` and it flipped ``stop_flips`` times (a
    criterion <= 0 is met)."""
    return (stop_norm <= 0.0 or reached) and (stop_flips <= 0 or flip_count >= stop_flips)


@jit
def _observe_flips(ys, previous, active, axis, t, h, body, flips, flip_count, lo, torque_kind, torque_params,
                   torque_fn):
    """Record sign changes of the ``axis`` component during the step ``[t, t + h]``."""
    for i in range(ys.shape[1]):
        if active[i]:
            flipped, time = flip_in_step(axis, t, h, previous[0, i], previous[1, i], previous[2, i], ys[0, i],
                                         ys[1, i], ys[2, i], body, torque_kind, torque_params, torque_fn)
            if flipped:
                count = flip_count[lo + i]
                if count < flips.shape[1]:
                    flips[lo + i, count] = time
                flip_count[lo + i] = count + 1


@jit
def _observe_drift(ys, active, body, e0, l0, drift, lo, drift_limit, k, frozen, status, last):
    """Running maximum of the relative energy and ``|L|**2`` errors; samples past ``drift_limit`` stop.

    Returns how many samples it stopped."""
    stopped = 0
    for i in range(ys.shape[1]):
        if not active[i]:
            continue
        de, dl = invariant_errors(ys[0, i], ys[1, i], ys[2, i], body, e0[i], l0[i])
        if drift.shape[0] > 0:
            drift[0, lo + i] = max(drift[0, lo + i], de)
            drift[1, lo + i] = max(drift[1, lo + i], dl)
        if drifted(de, dl, drift_limit):
            freeze(i, k, STATUS_DRIFT, ys, active, frozen, status, last)
            stopped += 1
    return stopped


@jit
def _observe_norm(ys, active, axis, weights, probes, lo, row, stop_norm, reached, window, fit_saturation):
    """Weighted transverse norm (:func:`transverse_norm`) about ``axis`` into ``probes[row]`` (NaN for stopped
    samples; not kept when ``probes`` is empty) and into each sample's growth window (``window`` (6, m), with
    ``fit_saturation > 0``: :func:`tumble.kernels.fits.growth_window_add`); marks samples whose norm reached
    ``stop_norm``."""
    for i in range(ys.shape[1]):
        norm = transverse_norm(ys[0, i], ys[1, i], ys[2, i], axis, weights) if active[i] else np.nan
        if probes.shape[0] > 0:
            probes[row, lo + i] = norm
        if fit_saturation > 0.0:
            _feed_window(window, i, row, norm, fit_saturation)
        if active[i] and stop_norm > 0.0 and norm >= stop_norm:
            reached[i] = True


@jit(inline=True)
def _feed_window(window, i, row, norm, fit_saturation):
    """Probe ``row``'s norm into sample ``i``'s growth window, kept as column ``i`` of ``window`` (6, m); ``row < 0``
    opens the window (:data:`tumble.kernels.fits.GROWTH_WINDOW_START`)."""
    if row < 0:
        stop, older, old, total, count, first = GROWTH_WINDOW_START
    else:
        stop, older, old, total, count, first = growth_window_add(
            row, norm, fit_saturation, (int(window[0, i]), window[1, i], window[2, i], window[3, i],
                                        int(window[4, i]), window[5, i]))
    window[0, i], window[1, i], window[2, i], window[3, i], window[4, i], window[5, i] = (
        stop, older, old, total, count, first)


@jit
def _stop_complete(ys, active, reached, stop_norm, stop_flips, flip_count, lo, k, frozen, status, last):
    """Stop the samples whose measurement is complete; returns how many are still running."""
    remaining = 0
    for i in range(ys.shape[1]):
        if active[i]:
            if measurement_complete(reached[i], stop_norm, stop_flips, flip_count[lo + i]):
                freeze(i, k, STATUS_OK, ys, active, frozen, status, last)
            else:
                remaining += 1
    return remaining


def _method_step(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params,
                 torque_fn):
    """One step of method ``kernel`` for every running sample of a block, torque-free or with a torque: the step is
    chosen when the loop is compiled (:func:`_method_step_of`)."""


@overload(_method_step, prefer_literal=True, jit_options=dict(fastmath=set(FASTMATH), error_model="numpy"))
def _method_step_of(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params,
                    torque_fn):
    """The method's id and ``torque_free`` are literal types (constants of the caller: the CPU driver's closure, the
    device kernel's): each method compiles its own loop with its one step in it (a chain of branches over the methods
    compiled all six steps into every driver, whichever it ran: 40 s of a first ``integrate`` rk4 on 2 cores,
    ``benchmarks/first_call.py``). The torque-free splittings are the generated ones of :mod:`tumble.kernels.fused`
    (ending on each sample's own ``|L|**2``), with a torque their compositions of sub-flows.

    A method id that is not a literal (a caller passing it as a run-time int, or through a star-call's tuple, which
    numba-cuda types as plain ints) is a typing error that says so, not a silent chain of every method's step."""
    if not isinstance(torque_free, types.BooleanLiteral):
        return None
    if not isinstance(kernel, types.IntegerLiteral):
        raise TypingError(f"the loop's method id must be a literal, a constant of its caller (the driver's closure, "
                          f"the device kernel's), got {kernel}: a call of more than 30 arguments passes its tuple "
                          f"without the literal")
    free = torque_free.literal_value
    method = kernel.literal_value
    if method == IMPLICIT_MIDPOINT:
        def midpoint_step(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind,
                          torque_params, torque_fn):
            implicit_midpoint_block(y1, y2, y3, active, t, h, body, work, torque_kind, torque_params, torque_fn)

        return midpoint_step
    if not free and method in _TORQUE_SPLITTINGS:
        torque_splitting = _TORQUE_SPLITTINGS[method]

        def torque_splitting_step(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind,
                                  torque_params, torque_fn):
            torque_splitting(y1, y2, y3, t, h, body, torque_kind, torque_params, torque_fn)

        return torque_splitting_step
    fused_step = _FUSED_STEPS[method]

    def step(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params, torque_fn):
        fused_step(y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params, torque_fn)

    return step


#: Rows of a block's float scratch ``values`` (m columns) besides its states: each sample's initial ``|L|**2``
#: (the splittings project onto it), its initial energy, and its growth window (6 rows, :func:`_feed_window`).
TARGET, ENERGY, WINDOW = 0, 1, 2
VALUE_ROWS = 8


def make_run_block(torque_free):
    # size: the closure holds the one time loop below (see there)
    """The one time loop of the free body (documented inside), torque-free or with a torque.

    ``torque_free`` is a constant of the returned closure, so numba prunes the other case before compiling: the
    torque-free loop calls the generated steps of :mod:`tumble.kernels.fused` (the splittings spelled out, ending on
    each sample's own ``|L|**2``), the loop with a torque calls the splittings through
    :func:`tumble.kernels.steppers.make_splitting_torque_block`, the loop over their sub-flows with torque sub-flows,
    and never compiles the spelled-out torque-free splittings (splitting4's alone costs about 40 s). (A test of
    ``torque_params is None`` would not do: numba prunes on it only when it is None.) The method (``kernel``) comes in
    as a literal (a constant of the caller), and the loop compiles that method's step only (:func:`_method_step`)."""

    @jit
    def run_block(kernel, w, lo, scratch,
                  body, t0, h, n_steps, save_every, saved,
                  axis, norm_weights, probe_steps, probes,
                  flips, flip_count, drift,
                  status, steps_taken,
                  stop_norm, stop_flips, drift_limit,
                  torque_kind, torque_params, torque_fn,
                  growth):
        # size: the one time loop of every method and observer, on either device: flat arrays and scalars
        # (DESIGN.md: arrays and scalars below the kernels' door), the block's scratch owned by the caller, the
        # observers the helpers above, in one order of step, flips, drift, status, store, probes and early stop
        """Samples ``lo, ..., lo + m - 1`` of ``w`` through the whole run: the free body's one time loop, for the CPU
        and the device.

        The CPU's driver (:func:`make_propagate`) calls it for each block of samples in parallel, where the block's
        samples move together in SIMD lanes (the steps of :mod:`tumble.kernels.fused` loop over them); the device's
        kernel (:mod:`tumble.kernels.cuda`) for one sample per thread (``m = 1``, the scratch in the thread's local
        memory).

        The scratch, owned by the caller, ``scratch = (ys, frozen, previous, values, flags, last)``: ``ys``,
        ``frozen`` and ``previous`` (3, m): the states, the state each stopped sample keeps, the states before the step
        (flips); ``values`` (:data:`VALUE_ROWS`, m) float; ``flags`` (2, m) bool: running, its norm reached
        ``stop_norm``; ``last`` (m,) int64: the steps each sample took. The other arguments are the CPU driver's, and
        the growth fit's, ``growth = (fit_saturation, fit_min_points, fit_h, fit, fit_points)``: ``fit_saturation >
        0`` feeds each sample's norms at the probes (``fit_h`` apart) to its growth window as they come
        (:func:`tumble.kernels.fits.growth_window_add`, the CPU fit's own step): ``fit`` (3, N) receives the rate (1/s,
        NaN unless the window has ``fit_min_points``), the first and the last norm of the window, ``fit_points`` its
        length (0 unless the fit is good). The loop writes the block's columns of every output, and sets them all (an
        output's initial content does not matter).

        The scratch and the growth fit come as tuples so that a call spells out at most 30 arguments: CPython compiles
        a call with more as a star-call (``f(*args)``), whose tuple numba-cuda types without the method's literal, and
        the device's loop would compile every method's step.
        """
        ys, frozen, previous, values, flags, last = scratch
        fit_saturation, fit_min_points, fit_h, fit, fit_points = growth
        m = ys.shape[1]
        y1, y2, y3 = ys[0], ys[1], ys[2]
        active, reached = flags[0], flags[1]
        target, e0, window = values[TARGET], values[ENERGY], values[WINDOW:WINDOW + 6]
        work = values[VALUE_ROWS:]  # the steps' scratch rows: none needs any
        early_stop = stop_norm > 0.0 or stop_flips > 0
        limit = drift_limit if torque_params is None else 0.0
        n_probes = probe_steps.shape[0]
        storing = saved.shape[0] > 0
        track_flips = flips.shape[1] > 0
        track_drift = drift.shape[0] > 0
        block_status = status[lo:lo + m]
        for i in range(m):
            y1[i], y2[i], y3[i] = w[0, lo + i], w[1, lo + i], w[2, lo + i]
            active[i], reached[i] = True, False
            last[i] = n_steps
            block_status[i] = STATUS_OK
            target[i] = l_squared(y1[i], y2[i], y3[i], body)
            e0[i] = energy(y1[i], y2[i], y3[i], body)
            _feed_window(window, i, -1, 0.0, 0.0)
            flip_count[lo + i] = 0
            for j in range(flips.shape[1]):
                flips[lo + i, j] = np.nan
            if track_drift:
                drift[0, lo + i] = drift[1, lo + i] = 0.0
        n_frozen = 0
        slot = store_initial(saved, ys, lo)
        probe = 0
        while probe < n_probes and probe_steps[probe] == 0:
            _observe_norm(ys, active, axis, norm_weights, probes, lo, probe, stop_norm, reached, window, fit_saturation)
            probe += 1
        ran = 0
        for k in range(n_steps):
            if n_frozen == m:
                break  # every sample stopped (a device thread's one sample, or a whole block)
            t = t0 + k * h
            if track_flips:
                for i in range(m):
                    previous[0, i], previous[1, i], previous[2, i] = y1[i], y2[i], y3[i]
            _method_step(kernel, torque_free, y1, y2, y3, active, t, h, body, target, work, torque_kind, torque_params,
                         torque_fn)
            if n_frozen:
                restore_frozen(ys, active, frozen)
            ran = k + 1
            if track_flips:
                _observe_flips(ys, previous, active, axis, t, h, body, flips, flip_count, lo, torque_kind,
                               torque_params, torque_fn)
            if track_drift or limit > 0.0:
                n_frozen += _observe_drift(ys, active, body, e0, target, drift, lo, limit, ran, frozen, block_status,
                                           last)
            if track_flips or ran % CHECK_EVERY == 0 or ran == n_steps:
                n_frozen += check_finite(ys, active, ran, frozen, block_status, last)
            if storing and (ran % save_every == 0 or ran == n_steps):
                store(saved, slot, ys, lo)
                slot += 1
            while probe < n_probes and probe_steps[probe] == ran:
                _observe_norm(ys, active, axis, norm_weights, probes, lo, probe, stop_norm, reached, window,
                              fit_saturation)
                probe += 1
            if early_stop:
                remaining = _stop_complete(ys, active, reached, stop_norm, stop_flips, flip_count, lo, ran, frozen,
                                           block_status, last)
                n_frozen = m - remaining
                if remaining == 0:
                    break
        # A block that stopped early fills the rest of its requested outputs: trajectories hold the frozen state, probes
        # are NaN (no measurement after a sample stopped; the first closes its growth window).
        store_rest(saved, slot, ys, lo, ran, n_steps, save_every)
        for i in range(m):
            active[i] = False
        while probe < n_probes:
            _observe_norm(ys, active, axis, norm_weights, probes, lo, probe, 0.0, reached, window, fit_saturation)
            probe += 1
        for i in range(m):
            w[0, lo + i], w[1, lo + i], w[2, lo + i] = y1[i], y2[i], y3[i]
            steps_taken[lo + i] = last[i]
            if fit_saturation > 0.0:
                stop, older, old, total, count, first = (int(window[0, i]), window[1, i], window[2, i], window[3, i],
                                                         int(window[4, i]), window[5, i])
                fit[0, lo + i], fit_points[lo + i], fit[1, lo + i], fit[2, lo + i] = growth_window_rate(
                    (stop, older, old, total, count, first), n_probes, fit_h, fit_min_points)

    return run_block


#: The one time loop, torque-free and with a torque (:func:`make_run_block`), each compiled on first use.
RUN_BLOCK_FREE = make_run_block(True)
RUN_BLOCK_TORQUE = make_run_block(False)


def make_propagate(torque_free, kernel):
    # size: the closure holds the CPU's driver below (see there)
    """The CPU's driver of the one time loop for method ``kernel`` (its index in :data:`tumble.registry.STEPPING`),
    torque-free (:data:`RUN_BLOCK_FREE`) or with a torque (:data:`RUN_BLOCK_TORQUE`): both constants of the closure,
    so that the loop compiles the one step it runs (:func:`_method_step`). numba's disk cache tells the closures apart
    by their constants (its index key hashes a closure's cell contents)."""

    @jit(parallel=True)
    def propagate(w, body, t0, h, n_steps, block,
                  save_every, saved,
                  axis, norm_weights, probe_steps, probes,
                  flips, flip_count,
                  drift,
                  status, steps_taken,
                  stop_norm, stop_flips, drift_limit,
                  torque_kind, torque_params, torque_fn):
        # size: the driver's flat arguments (kernels.methods.run packs them), documented once here
        """Advance every sample ``n_steps`` fixed steps of size ``h`` of the closure's method, observing as asked: the
        CPU's wrapper of the one time loop (:func:`make_run_block`), blocks of ``block`` samples in parallel.

        Parameters
        ----------
        w : ndarray, shape (3, N)
            Body-frame angular velocity, rad/s; overwritten with the final (or frozen) state.
        body : tuple
            :func:`tumble.kernels.steppers.body_constants` of the moments.
        t0, h : float
            Start time and step, s.
        n_steps, block : int
            Steps to take; samples per block.
        save_every : int
            With ``saved`` (shape ``(n_saved, 3, N)``): store the initial state, every ``save_every``-th state and
            the final one. ``n_saved = 0`` stores nothing.
        axis : int
            0-based spin axis.
        norm_weights : ndarray (3,)
            Weights ``g`` of the transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` of the two other components.
        probe_steps, probes : ndarray (P,) int64 increasing, ndarray (P, N) or (0, N)
            Weighted transverse norm (rad/s) after each step listed in ``probe_steps`` (0 = the initial state);
            NaN once a sample has stopped.
        flips, flip_count : ndarray (N, F), ndarray (N,) int64
            Times (s) of the first ``F`` sign changes of the ``axis`` component, located inside the step by cubic
            Hermite interpolation (NaN beyond the last); ``flip_count`` counts all of them. ``F = 0``: flips are not
            observed.
        drift : ndarray (2, N) or (0, N)
            Running maximum of ``|E/E0 - 1|`` and ``||L|²/|L0|² - 1|`` (not recorded when empty).
        status, steps_taken : ndarray (N,) int8, ndarray (N,) int64
            Outputs: per-sample status and the number of steps each sample took.
        stop_norm, stop_flips : float, int
            Early stop: a sample stops once its transverse norm has reached ``stop_norm`` (at a probe) and it has
            flipped ``stop_flips`` times; a criterion <= 0 is off, both off disables early stopping.
        drift_limit : float
            Torque-free invariant drift that marks a sample ``STATUS_DRIFT`` (<= 0: off).
        torque_kind, torque_params, torque_fn
            See :func:`tumble.kernels.steppers.body_torque`; ``torque_params=None`` compiles the torque out.
        """
        n = w.shape[1]
        no_fit, no_fit_points = np.empty((0, 1)), np.empty(0, dtype=np.int64)  # the growth fit is the caller's
        for ib in prange((n + block - 1) // block):
            lo = ib * block
            m = min(block, n - lo)
            scratch = (np.empty((3, m)), np.empty((3, m)), np.empty((3, m)), np.empty((VALUE_ROWS, m)),
                       np.empty((2, m), dtype=np.bool_), np.empty(m, dtype=np.int64))
            run = (kernel, w, lo, scratch, body, t0, h, n_steps, save_every, saved, axis, norm_weights, probe_steps,
                   probes, flips, flip_count, drift, status, steps_taken, stop_norm, stop_flips, drift_limit,
                   torque_kind, torque_params, torque_fn, (0.0, 0, 0.0, no_fit, no_fit_points))
            if torque_free:
                RUN_BLOCK_FREE(*run)
            else:
                RUN_BLOCK_TORQUE(*run)

    return propagate


# A user's torque function ``f(t, w1, w2, w3) -> (N1, N2, N3)`` is passed as a first-class function of this
# type, so one compiled (and cached) driver per method serves every torque function instead of one variant per
# function (which numba could not cache). The price is an indirect call per sample and stage, which keeps the step
# from vectorising across samples (measured in benchmarks/engine.py).
TORQUE_SIGNATURE = types.UniTuple(types.float64, 3)(types.float64, types.float64, types.float64, types.float64)

#: The drivers made so far, by (method id, torque: None, "profile" or "function"); each compiles on its first call.
_DRIVERS = {}


def driver(kernel, torque_free, torque_fn=None):
    """The compiled driver for a run of method ``kernel``: torque-free, with a built-in torque profile, or with
    ``torque_fn`` (:func:`make_propagate`, made once per method and torque).

    With a torque function, the function is compiled for :data:`TORQUE_SIGNATURE` and a dispatcher of the driver
    with a torque, compiled only for the first-class function type and then closed to further compilation, takes it:
    numba converts any jitted function of that signature to the first-class type instead of compiling a variant for it.
    """
    torque = None if torque_free else "profile" if torque_fn is None else "function"
    if torque_fn is not None:
        torque_fn.compile(TORQUE_SIGNATURE)
    key = (kernel, torque)
    made = _DRIVERS.get(key)
    if made is None:
        made = make_propagate(torque_free, kernel)
        if torque == "function":
            made.compile(_user_torque_types())
            made.disable_compile()
        _DRIVERS[key] = made
    return made


def _user_torque_types():
    """Argument types of the driver for a user torque function (see :func:`driver`)."""
    f8, i8 = types.float64, types.int64
    return (f8[:, ::1], types.UniTuple(f8, 12), f8, f8, i8, i8, i8, f8[:, :, ::1], i8, f8[::1], i8[::1],
            f8[:, ::1], f8[:, ::1], i8[::1], f8[:, ::1], types.int8[::1], i8[::1], f8, i8, f8, i8, f8[::1],
            types.FunctionType(TORQUE_SIGNATURE))
