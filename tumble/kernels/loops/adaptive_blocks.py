"""The error-controlled run stepped in blocks of lanes: each lane its own sample, time and step, vectorised across them.

:func:`run_share` steps a share of the samples in a block of :data:`BLOCK` lanes: ``attempt(block, rtol, atol, a)``
(generated, :func:`tumble.kernels.steps.model_codegen.attempt_source`) tries every lane's step at once and keeps it or
not (Hairer's control, :func:`tumble.kernels.steps.control.next_step`, as one sample's loop does), each lane's state in
registers from its load to its store, vectorised across the lanes; the loop masks the lanes that are done (their step
is 0) and reads the output times and a section's crossings off a lane's dense output, its stages made again one
sample at a
time by ``rate(t, y, p, dydt)`` (where a step holds one). A lane whose sample is done takes the share's next sample at
once, so that samples of few steps and of many share the block's work (a block that waited for its slowest sample
stepped a third of its lanes idle on an eccentric orbit's ensemble); each sample's steps are the same whichever lane
runs it.

The functions here are written once, over the module's globals ``attempt``, ``rate`` and ``surface``, and run as copies
with those in their globals (:func:`specialised`, :func:`tumble.kernels.jit.rebound`; numba's cache cannot key a
function by another it is handed): a built-in model's (:func:`for_model`: its own generated attempt, the models'
:func:`~tumble.kernels.steps.model_steps.rate_sample` and the component surface, cached on disk under the model's
system module, so that a model compiles its own attempt and no other), a System's (its generated attempt and rate),
or either with a user's surface (compiled in the process that asks).
"""

import math

import numpy as np
from llvmlite import ir
from numba.extending import intrinsic

from ...registry import STATUS_LIMIT, STATUS_NONFINITE, STATUS_OK
from ..jit import jit, rebound
from ..steps import model_codegen, model_steps
from ..steps.control import (ACCEPTED, ACTIVE, BLOCK, FACOLD, FIRST_FACOLD, G0, H, KEPT, LAST_REJECTED, NEXT_OUT, ROUND,
                             STATES, T, T_NEW, T_PREV, TRIAL_H, TRIES)
from .adaptive_loop import (SCRATCH_ROWS, _crossing, _dense, _interpolant, _stages, _step_to_end,
                            _underflow_status)
from .adaptive_loop import component_surface as surface
from ..threads import in_shares, start_shares

__all__ = ["BLOCK", "for_model", "specialised"]  # BLOCK: tumble.kernels.steps.control's

# What the templates read, until a copy reads its own (specialised): the attempt, the start and the rate are always the
# copy's.
attempt = None
start = None
rate = None

# The rows of a block's counters (``counters``, int): each lane's next output, its sample (-1: none), its crossings.
# The block's numbers (``block``) are laid out as :mod:`tumble.kernels.steps.control` says.
_SLOT, _OWNER, _CROSSED = range(3)


@intrinsic
def _lowest_bit(typingctx, bits):
    """The index of the lowest set bit of ``bits`` (an integer, not 0): LLVM's ``cttz``, one instruction."""

    def codegen(context, builder, signature, arguments):
        return builder.cttz(arguments[0], ir.Constant(ir.IntType(1), 0))

    return bits(bits), codegen


@jit(inline=True)
def _stops(active, tries, h, t, max_steps):
    """Whether an active lane stops before its next try: its steps are used up, or its step cannot advance ``t``."""
    return (active != 0.0) & ((tries >= max_steps) | ~(0.1 * h > abs(t) * ROUND))


@jit(contract=False, refcounts=False)
def _lane_extras(i, s, y0s, k0s, ys, p, block, times, out, slot, crossed, component, value, direction, most,
                 crossing_t, crossing_y, k, stage, y0, y1, f):
    # size: one lane's accepted step's outputs and crossing, with the scratch they are made in
    """Lane ``i``'s (sample ``s``'s) kept step ``(ti, ti + hi = tn)`` from ``y0s`` to ``ys``: the surface's crossing
    and the output times in it, from the dense output (its stages made again, one sample); an output time at ``tn``
    itself is ``y1``."""
    n = ys.shape[0]
    ti, hi, tn = block[T_PREV + i], block[TRIAL_H + i], block[T_NEW + i]
    for j in range(n):
        y0[j] = y0s[j, i]
        y1[j] = ys[j, i]
    before = block[G0 + i]
    g1 = 0.0
    crossing = False
    if most > 0:
        g1 = surface(tn, y1, p, component, value)
        crossing = (direction >= 0.0 and before < 0.0 <= g1) or (direction <= 0.0 and before > 0.0 >= g1)
        block[G0 + i] = g1
    if crossing or block[NEXT_OUT + i] < tn:
        for j in range(n):
            k[0, j] = k0s[j, i]
        _stages(rate, y0, p, ti, hi, k, stage)
        _interpolant(rate, y0, y1, p, ti, hi, k, stage, f)
    if crossing:
        c = crossed[i]
        x = _crossing(surface, f, y0, p, ti, hi, before, g1, component, value, stage)
        crossing_t[s, c] = tn if x == 1.0 else ti + x * hi
        _dense(f, y0, x, crossing_y[s, c])
        crossed[i] += 1
    while slot[i] < times.shape[0] and times[slot[i]] <= tn:
        if times[slot[i]] == tn:
            for j in range(n):
                out[s, slot[i], j] = y1[j]
        else:
            _dense(f, y0, (times[slot[i]] - ti) / hi, out[s, slot[i]])
        slot[i] += 1
    block[NEXT_OUT + i] = times[slot[i]] if slot[i] < times.shape[0] else np.inf


@jit(inline=True, contract=False, refcounts=False)
def _start(i, s, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts, section, block, counters, y0):
    # size: one lane's start on a sample: its state, first outputs, rate, first step and surface value
    """Put sample ``s`` into lane ``i``, its rate ``k0[:, s]`` and first step ``h0`` (0: ``firsts[s]``) made for the
    share by ``start``: True when it steps, False when it is done at once (not finite, or no time to run)."""
    component, value, most = int(section[0]), section[1], int(section[3])
    n = ys.shape[0]
    counters[_OWNER, i] = s
    code = STATUS_OK
    for j in range(n):
        y0[j] = y[s, j]
        ys[j, i] = y0[j]
        if not math.isfinite(y0[j]):
            code = STATUS_NONFINITE
    status[s] = code
    for row in (T, H, LAST_REJECTED, G0):
        block[row + i] = 0.0
    block[ACCEPTED + i] = counts[s, 0]  # the steps the sample took before (0 for a new run): max_steps bounds its total
    block[TRIES + i] = counts[s, 0] + counts[s, 1]
    block[T + i] = t0
    block[FACOLD + i] = FIRST_FACOLD
    slot = 0
    while slot < times.shape[0] and times[slot] <= t0:
        for j in range(n):
            out[s, slot, j] = y0[j]
        slot += 1
    counters[_SLOT, i] = slot
    counters[_CROSSED, i] = 0
    block[NEXT_OUT + i] = times[slot] if slot < times.shape[0] else np.inf
    if code != STATUS_OK or t_end <= t0:
        block[ACTIVE + i] = 0.0
        return False
    block[ACTIVE + i] = 1.0
    for j in range(n):
        ks[j, i] = k0[j, s]
    block[H + i] = h0 if h0 > 0.0 else firsts[s]
    if most > 0:
        block[G0 + i] = surface(t0, y0, p, component, value)
    return True


@jit(inline=True, contract=False, refcounts=False)
def _finish(i, y, ys, times, out, counts, stopped, block, counters):
    """Lane ``i``'s sample is done: its state, counts and time written back; a stopped sample's later outputs are
    the state it stopped with."""
    s = counters[_OWNER, i]
    n = ys.shape[0]
    for j in range(n):
        y[s, j] = ys[j, i]
    counts[s, 0] = int(block[ACCEPTED + i])
    counts[s, 1] = int(block[TRIES + i]) - counts[s, 0]
    counts[s, 2] = counters[_CROSSED, i]
    stopped[s] = block[T + i]
    for slot in range(counters[_SLOT, i], times.shape[0]):
        for j in range(n):
            out[s, slot, j] = ys[j, i]
    counters[_SLOT, i] = times.shape[0]
    counters[_OWNER, i] = -1


@jit(inline=True, contract=False, refcounts=False)
def _fill(i, queued, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts, stopped, section, block,
          counters, y0):
    # size: the share's queue, handed to one lane
    """Lane ``i`` takes the share's next samples from ``queued`` until one steps (those done at once are finished
    here): the next ``queued``."""
    while queued < y.shape[0]:
        started = _start(i, queued, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts, section,
                         block, counters, y0)
        queued += 1
        if started:
            break
        _finish(i, y, ys, times, out, counts, stopped, block, counters)
    return queued

@jit(contract=False)
def run_share(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
              counts, stopped, starts):
    # size: as _run_block
    """The samples ``y`` of one share in one block (:func:`_run_block`), with the block's arrays made here; the other
    threads' shares started first (``starts``: :func:`tumble.kernels.threads.in_shares`' ``handoff``)."""
    start_shares(starts)
    n = y.shape[1]
    block = np.zeros(STATES + 4 * n * BLOCK)
    counters = np.zeros((3, BLOCK), dtype=np.int64)
    scratch = np.empty((SCRATCH_ROWS + 1, n))
    k0 = np.empty((n, y.shape[0]))  # a component's rates in a row: the start's stores are contiguous, so it vectorises
    firsts = np.empty(y.shape[0])
    if y.shape[0] > 0:
        start(t0, t_end - t0, y, rtol, atol, a, k0, firsts)  # every sample's rate and first step, vectorised
        _run_block(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
                   counts, stopped, block, block[STATES:].reshape((4, n, BLOCK)), counters, scratch, k0, firsts)


@jit(contract=False, refcounts=False)
def _run_block(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
               counts, stopped, block, rows, counters, scratch, k0, firsts):
    # size: Hairer's control over a block's lanes, with the outputs, the crossings, the stops and the lanes' refills
    """:func:`run_share`'s loop over the block's lanes, with the arrays it made: ``block`` (laid out as
    :mod:`tumble.kernels.steps.control` says), ``rows`` (4, n, BLOCK) its states (``ys``, ``ks``, ``y0s``, ``k0s``)
    and ``counters`` (3, BLOCK), rows named by ``_SLOT`` ...; ``scratch`` (:data:`SCRATCH_ROWS` + 1, n) one sample's
    dense output; ``k0`` (n, N) and ``firsts`` (N,) the samples' rates and first steps. It makes no array, so it runs without numba's reference counts (:func:`tumble.kernels.jit.jit`'s
    ``refcounts``). The passes over every lane index ``block`` at constant offsets, so that they vectorise."""
    n = y.shape[1]
    m = BLOCK
    component, value, direction, most = int(section[0]), section[1], section[2], int(section[3])
    slot, owner, crossed = counters[_SLOT], counters[_OWNER], counters[_CROSSED]
    for i in range(m):
        owner[i] = -1
    ys, ks, y0s, k0s = rows[0], rows[1], rows[2], rows[3]
    k, stage, y0, y1, f = scratch[:16], scratch[16], scratch[17], scratch[18], scratch[19:26]
    for j in range(n):  # a lane without a sample holds the first one's state, masked (its step is 0)
        for i in range(m):
            ys[j, i] = y[0, j]
    queued = 0
    for i in range(m):
        queued = _fill(i, queued, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts, stopped,
                       section, block, counters, y0)
    while True:
        stops = 0  # the lanes that stop before their next try, counted without a branch (the pass vectorises)
        for i in range(m):
            stops += 1 if _stops(block[ACTIVE + i], block[TRIES + i], block[H + i], block[T + i], max_steps) else 0
        if stops > 0:  # rare: those samples finished, their lanes refilled
            for i in range(m):
                if _stops(block[ACTIVE + i], block[TRIES + i], block[H + i], block[T + i], max_steps):
                    status[owner[i]] = STATUS_LIMIT
                    if block[TRIES + i] < max_steps:
                        for j in range(n):
                            y0[j] = ys[j, i]
                            k[0, j] = ks[j, i]
                        status[owner[i]] = _underflow_status(rate, y0, p, block[T + i], block[TRIAL_H + i], k,
                                                             stage)
                    block[ACTIVE + i] = 0.0
                    _finish(i, y, ys, times, out, counts, stopped, block, counters)
                    queued = _fill(i, queued, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts,
                                   stopped, section, block, counters, y0)
        stepping = 0
        for i in range(m):  # each lane's step (as _step_to_end says); 0 for a lane that is done
            on, ti, hi = block[ACTIVE + i], block[T + i], block[H + i]
            stepping += 1 if on != 0.0 else 0
            last = ti + 1.01 * hi >= t_end
            hi = _step_to_end(ti, hi, t_end, last)
            block[H + i] = hi
            block[TRIAL_H + i] = hi * on
            block[T_NEW + i] = t_end if last else ti + hi
            block[T_PREV + i] = ti
        if stepping == 0:
            break
        attempt(block, rtol, atol, a)
        # the lanes whose kept step reaches an output time or t_end, or any of a section's, as the bits of one
        # number (a pass without a branch), then those lanes alone: a step with one is rare but for sections
        events = 0
        for i in range(m):
            tn = block[T_NEW + i]
            events |= (1 << i) if ((block[KEPT + i] != 0.0) & ((block[NEXT_OUT + i] <= tn) | (tn == t_end) |
                                                               (most > 0))) else 0
        while events != 0:
            i = _lowest_bit(events)
            events &= events - 1
            tn = block[T_NEW + i]
            # outputs and crossings, made again (an output at t_end itself is the final state, written by _finish)
            if block[NEXT_OUT + i] < tn or (block[NEXT_OUT + i] == tn and tn != t_end) or most > 0:
                _lane_extras(i, owner[i], y0s, k0s, ys, p, block, times, out, slot, crossed, component, value,
                             direction, most, crossing_t, crossing_y, k, stage, y0, y1, f)
            if tn == t_end or (most > 0 and crossed[i] == most):  # done: the lane's next sample
                block[ACTIVE + i] = 0.0
                _finish(i, y, ys, times, out, counts, stopped, block, counters)
                queued = _fill(i, queued, y, ys, ks, k0, firsts, p, t0, t_end, h0, times, out, status, counts,
                               stopped, section, block, counters, y0)


#: The functions :func:`specialised` copies, callees first.
_FUNCTIONS = ("_lane_extras", "_start", "_finish", "_fill", "_run_block", "run_share")


def specialised(attempt, start, rate, surface=None, key=None):
    """``drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
    counts, stopped)``, as :func:`tumble.kernels.loops.adaptive_loop.make_dop853_driver`'s (``p`` the rate's
    parameters, ``a`` the attempt's and start's constants), over ``attempt``, ``start`` (every sample's rate and first
    step, :func:`tumble.kernels.steps.model_codegen.start_source`), ``rate`` and ``surface`` (None: the component surface):
    this module's functions copied with those in their globals (:func:`tumble.kernels.jit.rebound`), compiled on first
    use; one share of the samples per numba thread, each share in one block (a share is whole blocks: a run of one
    block's samples or fewer stays in the calling thread). Cached on disk under ``key`` (a string that names what they
    compute in every process: a model's system module, a System's code), not cached without it."""
    share = rebound(_FUNCTIONS, globals(), key, attempt=attempt, start=start, rate=rate,
                    surface=surface if surface is not None else globals()["surface"])["run_share"]

    def drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
              counts, stopped):
        # size: as run_share
        in_shares(share, len(y), lambda lo, hi: (y[lo:hi], p, a, t0, t_end, h0, rtol, atol, max_steps, times,
                                                 out[lo:hi], section, crossing_t[lo:hi], crossing_y[lo:hi],
                                                 status[lo:hi], counts[lo:hi], stopped[lo:hi]), BLOCK, handoff=True)

    drive.run_share = share  # the compiled share, for its cache statistics
    return drive


def for_model(module, rate="rate", surface=None):
    """:func:`specialised`'s driver of the built-in models whose equations are in system module ``module`` (the
    registry's ``equations_module``: the free body's are the gyrostat's) and whose rate is its function ``rate`` (the
    registry's ``rate``: the free body's is the gyrostat's without the rotor): its own generated attempt
    (:func:`tumble.kernels.steps.model_codegen.attempt_name`, whose constants ``a`` are the models' parameters after
    their code), the models' rate for the dense output (``p``: the parameters, code first) and ``surface`` (None: the
    component surface, cached on disk under ``module`` and ``rate``). A first run compiles that model's attempt alone:
    one for every model made a first free-body run compile all four (24 s to 14 s on 2 cores)."""
    key = None if surface is not None else module if rate == "rate" else f"{module}_{rate}"
    return specialised(getattr(model_steps, model_codegen.attempt_name(module, rate)),
                       getattr(model_steps, model_codegen.start_name(module, rate)), model_steps.rate_sample, surface,
                       key)
