"""The one time loop: a block of samples of any built-in system through a whole run of any fixed-step method, observers
on the fly, on the CPU and on the device.

:func:`run_block` is written once; its callers are thin. The CPU's drivers run blocks of samples in parallel
(a share of whole blocks per thread, :mod:`tumble.kernels.threads`: the free body's :func:`tumble.kernels.loops.drivers.make_propagate`, the models'
:func:`tumble.kernels.loops.model_loop.make_propagate_model`), where each block is a structure of arrays ``ys`` (n_state, m),
one row per component and one column per sample, so that the per-sample steps vectorise across samples (SIMD lanes);
the device's kernels (:mod:`tumble.kernels.cuda.rigid_body`, :mod:`tumble.kernels.cuda.models`) run a block of one sample per
thread, its scratch in the thread's local memory. Samples never interact: results do not depend on the number of
threads or on the block size.

**The system and the method are literal codes**, constants of the caller (the CPU driver's closure, the device
kernel's). The loop's system parts are overloads on them, :func:`_step`, :func:`_invariants`, :func:`_drift_suspects`
and :func:`_observe_flips`, so that numba compiles one system's and one method's code into the loop and nothing else.
:data:`FREE_BODY` is the free body with its own fused steps (:mod:`tumble.kernels.loops.free_body_parts`: torques too, and
the flips of its spin axis); every other code is a model of :data:`tumble.registry.MODEL_KINDS` stepped by the steps
generated from its system module (:mod:`tumble.kernels.steps.model_steps`, :mod:`tumble.kernels.systems`), and a code from
:data:`tumble.kernels.steps.system_steps.SYSTEM_CODES` up a user's System, stepped by the steps generated from its rewritten
rate (no invariants, no flips). A code that is not a literal is a typing error that says so (a chain of branches would
compile every system's and method's step into the loop: 40 s of a first rk4 ``integrate`` on 2 cores, 78 s of a first
heavy-top ensemble, ``benchmarks/first_call.py``).

**Observers** are runtime switches: an output not asked for is an empty array and its branch, outside the loop over a
block's samples, is skipped. A caller whose run asks for none passes the literal ``observing = False``, and the
observers are not compiled at all (:func:`_if_observing`: a plain integration's first call compiles 3 s less). They
come in one order after each step: flips (the free body's spin-axis component changing sign, timed by cubic Hermite
interpolation), the invariants' drifts, the non-finite check, the stored state, the probes of the transverse norm
``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` (each feeding the sample's growth window,
:func:`tumble.kernels.fits.growth_window_add`, when the growth fit runs in the loop), and the early stop of samples
whose measurement is complete.

**Drift.** Each sample's three invariants ``x`` (each system's own; the free body: the energy and ``|L|²``) against
their initial values: ``|x − x0| / scale0`` (the scale is the invariant itself where it is sign-definite, else the
largest magnitude it can take, so that an invariant that starts at 0 does not divide by 0). While drifts are tracked,
each step first runs a branch-free screen over the block (:mod:`tumble.kernels.steps.drift_screen`); only a block with a
suspect (a drift near the limit, or a non-finite state) runs the exact per-sample checks.

**Status.** ``STATUS_OK``, ``STATUS_NONFINITE`` (a component NaN or infinite: checked before the first step, every
:data:`CHECK_EVERY` steps, at the end, and after every step while flips are timed; under a drift limit the step it
happens, by the drift observer) or ``STATUS_DRIFT`` (a drift beyond the limit of a finite state; torque-free runs
only). A sample with a bad status, or whose measurement is
complete, stops and keeps the state it had then; its later probes are NaN and its later stores repeat that state.
"""

import math

import numpy as np
from numba import types
from numba.core.errors import TypingError
from numba.extending import overload

from ...registry import STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK
from .block_parts import check_finite, freeze, restore_frozen, store, store_initial, store_rest
from ..steps.drift_screen import SCREEN_ATOL, SCREEN_RTOL
from ..fits import GROWTH_WINDOW_START, growth_window_add, growth_window_rate
from .free_body_parts import drift_suspects as free_body_drift_suspects
from .free_body_parts import invariants as free_body_invariants
from .free_body_parts import method_step, observe_flips
from ..jit import FASTMATH, jit, subroutine
from ..steps.model_steps import drift_suspects, invariants, step
from ..steps.system_steps import SYSTEM_CODES, block_step
from ..systems import N_INVARIANTS
from ..trig import _max

__all__ = ["CHECK_EVERY", "FREE_BODY", "N_INVARIANTS", "PROBE_ROWS", "WINDOW_ROWS", "block_scratch", "run_block"]

#: The system code of the free body with its own fused steps (the models' codes are their index in
#: ``registry.MODEL_KINDS``, from 0).
FREE_BODY = -1

#: Steps between two checks for non-finite states when nothing else checks them.
CHECK_EVERY = 32

#: Rows of a sample's growth window (:func:`_feed_window`).
WINDOW_ROWS = 6

#: Rows of the loop's ``window`` scratch: the growth window's, then the transverse norm's sums of squares.
PROBE_ROWS = WINDOW_ROWS + 1

_TINY = 2.2250738585072014e-308  # smallest normal float: a zero scale gives a zero drift, not 0/0

# --- the system's and the method's code, chosen when the loop is compiled ---------------------------------------------
# Not inlined at numba's IR level: numba-cuda's pipeline cannot take an overload inlined so (LLVM inlines it).
# ``prefer_literal``: numba tries an overload with the arguments' plain types first and keeps what that gives (when
# a plain int had a chain of every branch, it was taken even for literal codes, from 2026-11-29 until
# benchmarks/first_call.py found it: a heavy top's first ensemble compiled every system's steps again).
_OPTIONS = dict(prefer_literal=True, jit_options=dict(fastmath=set(FASTMATH), error_model="numpy"))


def _literal(*codes):
    """Refuse codes that are not literals (a typing error that says so)."""
    for code in codes:
        if not isinstance(code, (types.IntegerLiteral, types.BooleanLiteral)):
            raise TypingError(f"the loop takes its system and method codes as literals, constants of its caller (the "
                              f"driver's closure, the device kernel's), got {code}: a call of more than 30 arguments "
                              f"passes its tuple without the literal")


def _step(system, method, torque_free, ys, active, t, h, params, x0, torque):
    """One step of ``method`` for every sample of a block of ``system``."""


@overload(_step, **_OPTIONS)
def _step_of(system, method, torque_free, ys, active, t, h, params, x0, torque):
    """The free body's step (torque-free: the generated steps of :mod:`tumble.kernels.steps.fused`; with a torque the
    splittings' compositions of sub-flows), or a model's generated step; ``x0`` each sample's initial invariants (the
    free body's splittings end on its ``|L|²``, the gyrostat projects onto its ``|L|``)."""
    _literal(system, method, torque_free)
    system_code, method_code = system.literal_value, method.literal_value
    if system_code >= SYSTEM_CODES:
        user_step = block_step(system_code, method_code)

        def users_step(system, method, torque_free, ys, active, t, h, params, x0, torque):
            user_step(ys, t, h, params)

        return users_step
    if system_code != FREE_BODY:
        def system_step(system, method, torque_free, ys, active, t, h, params, x0, torque):
            step(system_code, method_code, ys, t, h, params, x0)

        return system_step
    free_body_step = method_step(method_code, torque_free.literal_value)

    def fused_step(system, method, torque_free, ys, active, t, h, params, x0, torque):
        torque_kind, torque_params, torque_fn = torque
        free_body_step(ys[0], ys[1], ys[2], active, t, h, params, x0[1], x0[N_INVARIANTS:], torque_kind,
                       torque_params, torque_fn)

    return fused_step


def _invariants(system, ys, i, params):
    """Sample ``i``'s three invariants and their scales."""


@overload(_invariants, **_OPTIONS)
def _invariants_of(system, ys, i, params):
    _literal(system)
    system_code = system.literal_value
    if system_code == FREE_BODY:
        def free_body(system, ys, i, params):
            return free_body_invariants(ys[0, i], ys[1, i], ys[2, i], params)

        return free_body
    if system_code >= SYSTEM_CODES:
        def none_known(system, ys, i, params):
            return 0.0, 0.0, 0.0, 1.0, 1.0, 1.0  # a user's System declares no invariants

        return none_known

    def system_invariants(system, ys, i, params):
        return invariants(system_code, ys, i, params)

    return system_invariants


def _drift_suspects(system, ys, active, params, x0, inverse_scale, screen):
    """Whether any active sample of the block is non-finite or has drifted beyond ``screen`` (branch-free)."""


@overload(_drift_suspects, **_OPTIONS)
def _drift_suspects_of(system, ys, active, params, x0, inverse_scale, screen):
    _literal(system)
    system_code = system.literal_value
    if system_code == FREE_BODY:
        def free_body(system, ys, active, params, x0, inverse_scale, screen):
            return free_body_drift_suspects(ys, active, params, x0, inverse_scale, screen)

        return free_body
    if system_code >= SYSTEM_CODES:
        def non_finite(system, ys, active, params, x0, inverse_scale, screen):
            return _non_finite(ys, active)

        return non_finite

    def system_drift_suspects(system, ys, active, params, x0, inverse_scale, screen):
        return drift_suspects(system_code, ys, active, params, x0, inverse_scale, screen)

    return system_drift_suspects


def _observe_flips(system, ys, previous, active, axis, t, h, params, times, count, lo, torque):
    """Sign changes of the ``axis`` component during the step (the free body's; a model's are not observed)."""


@overload(_observe_flips, **_OPTIONS)
def _observe_flips_of(system, ys, previous, active, axis, t, h, params, times, count, lo, torque):
    _literal(system)
    if system.literal_value != FREE_BODY:
        def no_flips(system, ys, previous, active, axis, t, h, params, times, count, lo, torque):
            pass  # the models' drivers give no flip slots

        return no_flips

    def free_body(system, ys, previous, active, axis, t, h, params, times, count, lo, torque):
        torque_kind, torque_params, torque_fn = torque
        observe_flips(ys, previous, active, axis, t, h, params, times, count, lo, torque_kind, torque_params,
                      torque_fn)

    return free_body


@jit(inline=True)
def _non_finite(ys, active):
    """Whether an active sample of the block holds a value that is not finite (a user's System: no invariants)."""
    bad = 0.0
    for j in range(ys.shape[0]):
        for i in range(ys.shape[1]):
            bad += 0.0 * ys[j, i] if active[i] else 0.0
    return bad != 0.0


# --- observers, the same for every system -----------------------------------------------------------------------------

@jit(inline=True)
def _initial_invariants(system, ys, params, x0, inverse_scale):
    """Each sample's invariants ``x0`` (3, m) and the inverses of their drift scales (3, m) at the start."""
    for i in range(ys.shape[1]):
        x1, x2, x3, s1, s2, s3 = _invariants(system, ys, i, params)
        x0[0, i], x0[1, i], x0[2, i] = x1, x2, x3
        inverse_scale[0, i] = 1.0 / _max(s1, _TINY)
        inverse_scale[1, i] = 1.0 / _max(s2, _TINY)
        inverse_scale[2, i] = 1.0 / _max(s3, _TINY)


@subroutine
def _observe_drift(system, ys, active, params, x0, inverse_scale, drift, lo, drift_limit, k, frozen, status, last):
    """Running maximum of each invariant's drift ``|x − x0| / scale`` into ``drift`` (its rows; not recorded when
    empty); samples past ``drift_limit`` (<= 0: never; NaN counts as past) stop, with ``STATUS_DRIFT``, or
    ``STATUS_NONFINITE`` when their state is not finite. Returns how many it stopped."""
    stopped = 0
    rows = drift.shape[0]
    for i in range(ys.shape[1]):
        if not active[i]:
            continue
        x1, x2, x3, _, _, _ = _invariants(system, ys, i, params)
        d1 = abs(x1 - x0[0, i]) * inverse_scale[0, i]
        d2 = abs(x2 - x0[1, i]) * inverse_scale[1, i]
        d3 = abs(x3 - x0[2, i]) * inverse_scale[2, i]
        if rows > 0:
            drift[0, lo + i] = _max(drift[0, lo + i], d1)
            drift[1, lo + i] = _max(drift[1, lo + i], d2)
        if rows > 2:
            drift[2, lo + i] = _max(drift[2, lo + i], d3)
        if drift_limit > 0.0 and not (d1 <= drift_limit and d2 <= drift_limit and d3 <= drift_limit):
            finite = True
            for j in range(ys.shape[0]):
                finite = finite and math.isfinite(ys[j, i])
            freeze(i, k, STATUS_DRIFT if finite else STATUS_NONFINITE, ys, active, frozen, status, last)
            stopped += 1
    return stopped


@subroutine
def _observe_norm(ys, active, columns, weights, y_eq, probes, lo, row, stop_norm, reached, window, fit_saturation):
    """The weighted transverse norm ``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` of each sample
    into ``probes[row]`` (NaN for stopped samples; not kept when ``probes`` is empty) and into its growth window
    (``window``'s first :data:`WINDOW_ROWS` rows, with ``fit_saturation > 0``); marks samples whose norm reached
    ``stop_norm``. The sums of squares are taken a term at a time over the whole block (``window``'s last row), so
    that they vectorise across samples."""
    squares = window[WINDOW_ROWS]
    for i in range(ys.shape[1]):
        squares[i] = 0.0
    for j in range(columns.shape[0]):
        column, weight, centre = columns[j], weights[j], y_eq[columns[j]]
        for i in range(ys.shape[1]):
            d = ys[column, i] - centre
            squares[i] += weight * d * d
    for i in range(ys.shape[1]):
        norm = math.sqrt(squares[i]) if active[i] else np.nan
        if probes.shape[0] > 0:
            probes[row, lo + i] = norm
        if fit_saturation > 0.0:
            _feed_window(window, i, row, norm, fit_saturation)
        if active[i] and stop_norm > 0.0 and norm >= stop_norm:
            reached[i] = True


@jit(inline=True)
def _window(window, i):
    """Sample ``i``'s growth window, column ``i`` of ``window`` (6, m), as :mod:`tumble.kernels.fits` takes it."""
    return int(window[0, i]), window[1, i], window[2, i], window[3, i], int(window[4, i]), window[5, i]


@jit(inline=True)
def _set_window(window, i, values):
    window[0, i], window[1, i], window[2, i], window[3, i], window[4, i], window[5, i] = values


@jit(inline=True)
def _feed_window(window, i, row, norm, fit_saturation):
    """Probe ``row``'s norm into sample ``i``'s growth window."""
    _set_window(window, i, growth_window_add(row, norm, fit_saturation, _window(window, i)))


@subroutine
def _fit_rates(window, lo, m, fit_saturation, n_probes, fit_h, fit_min_points, fit, fit_points):
    """The growth rate of each sample of the block from its window (when ``fit_saturation > 0``), into ``fit``
    ((3, N): rate, first and last norm) and ``fit_points`` (the window's length) at ``lo:lo + m``."""
    if fit_saturation > 0.0:
        for i in range(m):
            fit[0, lo + i], fit_points[lo + i], fit[1, lo + i], fit[2, lo + i] = growth_window_rate(
                _window(window, i), n_probes, fit_h, fit_min_points)


@subroutine
def _stop_complete(ys, active, reached, stop_norm, stop_flips, flip_count, lo, k, frozen, status, last):
    """Stop the samples whose measurement is complete: their norm reached ``stop_norm`` and they flipped
    ``stop_flips`` times (a criterion <= 0 is met). Returns how many are still running."""
    remaining = 0
    for i in range(ys.shape[1]):
        if active[i]:
            flipped = stop_flips <= 0 or flip_count[lo + i] >= stop_flips
            if (stop_norm <= 0.0 or reached[i]) and flipped:
                freeze(i, k, np.int64(STATUS_OK), ys, active, frozen, status, last)  # (int64: one variant)
            else:
                remaining += 1
    return remaining


def _if_observing(observer, otherwise):
    """A stand-in for ``observer`` that takes the literal ``observing`` first: ``observer(*rest)`` when it is True,
    ``otherwise`` when it is False, and then ``observer`` is never typed nor compiled into the loop (numba types both
    arms of an ``if`` on a literal, so a branch would not keep it out)."""

    def stand_in(observing, *arguments):
        """``observer(*arguments)`` when ``observing`` (a literal), else a constant."""

    @overload(stand_in, **_OPTIONS)
    def stand_in_of(observing, *arguments):
        _literal(observing)
        if observing.literal_value:
            def observe(observing, *arguments):
                return observer(*arguments)

            return observe

        def skip(observing, *arguments):
            return otherwise

        return skip

    return stand_in


# The observers of a run that asks for some (its driver's ``observing``): a run that asks for none (a plain integration:
# ``tumble.integrate``, ``tumble.propagate``) compiles a loop without them, 3 of a first call's 8 s (2 cores).
_observe_flips_if = _if_observing(_observe_flips, None)
_drift_suspects_if = _if_observing(_drift_suspects, False)
_observe_drift_if = _if_observing(_observe_drift, 0)
_observe_norm_if = _if_observing(_observe_norm, None)
_stop_complete_if = _if_observing(_stop_complete, 0)
_fit_rates_if = _if_observing(_fit_rates, None)


@jit(inline=True)
def block_scratch(n_state, m):
    """The scratch of :func:`run_block` for a block of ``m`` samples of ``n_state`` components, on the CPU (a device
    thread's is in its local memory)."""
    return (np.empty((n_state, m)), np.empty((n_state, m)), np.empty((n_state, m)), np.empty((N_INVARIANTS, m)),
            np.empty((N_INVARIANTS, m)), np.empty((PROBE_ROWS, m)), np.empty((2, m), dtype=np.bool_),
            np.empty(m, dtype=np.int64))


@jit
def run_block(system, method, torque_free, observing, y, lo, scratch, params, t0, h, n_steps, save_every, saved, norm,
              probe_steps, probes, flips, drift, drift_limit, status, steps_taken, stops, torque, growth):
    # size: the one time loop of every system, method and observer, on either device: flat arrays, scalars and small
    # tuples of them (DESIGN.md: arrays and scalars below the kernels' door), the block's scratch owned by the caller
    """Samples ``lo, ..., lo + m - 1`` of ``y`` through the whole run: the one time loop.

    Parameters
    ----------
    system, method : int, literal
        :data:`FREE_BODY` or a model's code; the method's index in :data:`tumble.registry.STEPPING`.
    torque_free : bool, literal
        The free body without a torque (compiles the torque out; models: True).
    observing : bool, literal
        Whether the run may ask for an observer (the probes and the growth fit, flips, drifts, a drift limit, the
        early stop); False compiles them out, and the run must then ask for none (empty outputs, limits off).
    y : ndarray (n_state, N)
        The states, read at the start and overwritten with the final (or frozen) ones.
    lo : int
        The block's first sample.
    scratch : tuple
        Owned by the caller, ``(ys, frozen, previous, x0, inverse_scale, window, flags, last)``: ``ys``, ``frozen``
        and ``previous`` (n_state, m): the states, the state each stopped sample keeps, the states before the step
        (flips); ``x0`` and ``inverse_scale`` (:data:`N_INVARIANTS`, m): the initial invariants and the inverses of
        their scales; ``window`` (:data:`PROBE_ROWS`, m): the growth windows and a row for the norm's sums; ``flags``
        (2, m) bool: running, its norm reached ``stop_norm``; ``last`` (m,) int64: the steps each sample took.
    params
        The system's constants: the free body's :func:`tumble.kernels.steps.steppers.body_constants` tuple, a model's
        :func:`tumble.kernels.systems.constants` array.
    t0, h, n_steps : float, float, int
        Start time, step (s) and steps.
    save_every, saved : int, ndarray (n_saved, n_state, N)
        The initial state, every ``save_every``-th and the final one (``n_saved = 0``: none).
    norm : tuple
        ``(columns, weights, y_eq)``: (k,) int64, (k,), (n_state,): the transverse norm's terms.
    probe_steps, probes : ndarray (P,) int64 increasing, ndarray (P, N) or (0, N)
        The norm after each listed step (0 = the initial state), NaN once a sample has stopped; ``probes`` may be
        empty while the probe steps are not (the norms then only feed the growth fit).
    flips : tuple
        ``(axis, times, count)``: the component (0-based) whose sign changes are timed, ``times`` (N, F) the first F
        of them (NaN beyond the last; F = 0: not observed), ``count`` (N,) int64 all of them (written when not empty).
    drift, drift_limit : ndarray (rows <= 3, N) or (0, N), float
        Running maximum of each invariant's drift (not recorded when empty); a drift beyond the limit marks a
        sample ``STATUS_DRIFT`` and stops it (<= 0 or a torque: off).
    status, steps_taken : ndarray (N,) int8, ndarray (N,) int64
        Outputs: per-sample status and the steps each sample took.
    stops : tuple
        ``(stop_norm, stop_flips)``: early stop once the sample's norm reached ``stop_norm`` (at a probe) and it
        flipped ``stop_flips`` times; a criterion <= 0 is off, both off disables early stopping.
    torque : tuple
        ``(torque_kind, torque_params, torque_fn)``, :func:`tumble.kernels.steps.steppers.body_torque` (the free body).
    growth : tuple
        ``(fit_saturation, fit_min_points, fit_h, fit, fit_points)``: ``fit_saturation > 0`` feeds each sample's norms
        at the probes (``fit_h`` apart) to its growth window as they come (the CPU fit's own step): ``fit`` (3, N)
        receives the rate (1/s, NaN unless the window has ``fit_min_points``), the first and the last norm of the
        window, ``fit_points`` its length (0 unless the fit is good).

    The loop writes the block's columns of every output and sets them all (an output's initial content does not
    matter). The arguments are grouped in tuples so that a call spells out at most 30: CPython compiles a call with
    more as a star-call (``f(*args)``), whose tuple numba-cuda types without the codes' literals.
    """
    ys, frozen, previous, x0, inverse_scale, window, flags, last = scratch
    columns, weights, y_eq = norm
    flip_axis, flip_times, flip_count = flips
    stop_norm, stop_flips = stops
    fit_saturation, fit_min_points, fit_h, fit, fit_points = growth
    n_state, m = ys.shape
    active, reached = flags[0], flags[1]
    early_stop = stop_norm > 0.0 or stop_flips > 0
    limit = drift_limit if torque_free else 0.0
    n_probes = probe_steps.shape[0]
    storing = saved.shape[0] > 0
    track_flips = flip_times.shape[1] > 0
    record_drift = drift.shape[0] > 0
    track_drift = record_drift or limit > 0.0
    screen = limit * (1.0 - SCREEN_RTOL) - SCREEN_ATOL if limit > 0.0 else math.inf
    block_status = status[lo:lo + m]
    for i in range(m):
        for j in range(n_state):
            ys[j, i] = y[j, lo + i]
        active[i], reached[i] = True, False
        last[i] = n_steps
        block_status[i] = STATUS_OK
        _set_window(window, i, GROWTH_WINDOW_START)
        if flip_count.shape[0] > 0:
            flip_count[lo + i] = 0
        for j in range(flip_times.shape[1]):
            flip_times[lo + i, j] = np.nan
        for j in range(drift.shape[0]):
            drift[j, lo + i] = 0.0
    _initial_invariants(system, ys, params, x0, inverse_scale)  # the splittings' and projections' too
    ran = np.int64(0)  # (not the literal 0: a literal argument would compile a second variant of the check)
    n_frozen = check_finite(ys, active, ran, frozen, block_status, last)
    slot = store_initial(saved, ys, lo)
    probe = np.int64(0)  # (as ``ran``)
    while probe < n_probes and probe_steps[probe] == 0:
        _observe_norm_if(observing, ys, active, columns, weights, y_eq, probes, lo, probe, stop_norm, reached, window,
                         fit_saturation)
        probe += 1
    for k in range(n_steps):
        if n_frozen == m:
            break  # every sample stopped (a device thread's one sample, or a whole block)
        t = t0 + k * h
        if track_flips:
            for j in range(n_state):
                for i in range(m):
                    previous[j, i] = ys[j, i]
        _step(system, method, torque_free, ys, active, t, h, params, x0, torque)
        if n_frozen:
            restore_frozen(ys, active, frozen)
        ran = k + 1
        if track_flips:
            _observe_flips_if(observing, system, ys, previous, active, flip_axis, t, h, params, flip_times, flip_count,
                              lo, torque)
        # with drifts tracked, the exact observer runs only for a block with a suspect (or whose drifts are recorded):
        # the screen's "nothing to stop" is exact (a non-finite state is a suspect: the exact observer stops it with
        # its status), its suspects are checked exactly
        if track_drift and (record_drift or _drift_suspects_if(observing, system, ys, active, params, x0,
                                                               inverse_scale, screen)):
            n_frozen += _observe_drift_if(observing, system, ys, active, params, x0, inverse_scale, drift, lo, limit,
                                          ran, frozen, block_status, last)
        if track_flips or ran % CHECK_EVERY == 0 or ran == n_steps:
            n_frozen += check_finite(ys, active, ran, frozen, block_status, last)
        if storing and (ran % save_every == 0 or ran == n_steps):
            store(saved, slot, ys, lo)
            slot += 1
        while probe < n_probes and probe_steps[probe] == ran:
            _observe_norm_if(observing, ys, active, columns, weights, y_eq, probes, lo, probe, stop_norm, reached,
                             window, fit_saturation)
            probe += 1
        if early_stop:
            remaining = _stop_complete_if(observing, ys, active, reached, stop_norm, stop_flips, flip_count, lo, ran,
                                          frozen, block_status, last)
            n_frozen = m - remaining
            if remaining == 0:
                break
    # A block that stopped early fills the rest of its requested outputs: trajectories hold the frozen state, probes
    # are NaN (no measurement after a sample stopped; the first closes its growth window).
    store_rest(saved, slot, ys, lo, ran, n_steps, save_every)
    for i in range(m):
        active[i] = False
    while probe < n_probes:
        _observe_norm_if(observing, ys, active, columns, weights, y_eq, probes, lo, probe, 0.0, reached, window,
                         fit_saturation)
        probe += 1
    for i in range(m):
        for j in range(n_state):
            y[j, lo + i] = ys[j, i]
        steps_taken[lo + i] = last[i]
    _fit_rates_if(observing, window, lo, m, fit_saturation, n_probes, fit_h, fit_min_points, fit, fit_points)


#: :func:`run_block` as the CPU's drivers call it: inlined into each at numba's IR level, so that its code is generated
#: once, in the driver, instead of alone and again in the driver that links it (numba makes each kernel's machine code
#: for itself and again in every caller): a plain integration's first call compiles about 0.5 s less (rk4, 2 cores).
#: The device's kernels call :func:`run_block` itself.
run_block_inlined = jit(run_block.py_func, inline=True)
