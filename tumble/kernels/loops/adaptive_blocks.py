"""The error-controlled run stepped in blocks of lanes: each lane its own sample, time and step, vectorised across them.

:func:`run_share` steps a share of the samples in a block of :data:`BLOCK` lanes: ``trial(lane_t, lane_h, ys, ks, y1s,
k1s, err, rtol, atol, a)`` (generated, :func:`tumble.kernels.steps.model_codegen.trial_source`) makes every lane's
trial step at once, vectorised across the lanes; the loop then accepts or rejects each lane (Hairer's control, as
:func:`tumble.kernels.loops.adaptive_loop.make_dop853_sample`), masks the lanes that are done (their trial step is 0),
and reads the output times and a section's crossings off a lane's dense output, its stages made again one sample at a
time by ``rate(t, y, p, dydt)`` (where a step holds one). A lane whose sample is done takes the share's next sample at
once, so that samples of few steps and of many share the block's work (a block that waited for its slowest sample
stepped a third of its lanes idle on an eccentric orbit's ensemble); each sample's steps are the same whichever lane
runs it.

The functions here are written once, over the module's globals ``trial``, ``rate`` and ``surface``, and run as copies
with those in their globals (:func:`specialised`, :func:`tumble.kernels.jit.rebound`; numba's cache cannot key a
function by another it is handed): a built-in model's (:func:`for_model`: its own generated trial step, the models'
:func:`~tumble.kernels.steps.model_steps.rate_sample` and the component surface, cached on disk under the model's
system module, so that a model compiles its own trial step and no other), a System's (its generated trial and rate),
or either with a user's surface (compiled in the process that asks).
"""

import math

import numpy as np

from ...registry import STATUS_LIMIT, STATUS_NONFINITE, STATUS_OK, STATUS_UNDERFLOW
from ..jit import jit, rebound
from ..steps import model_steps
from .adaptive_loop import (_C, _FAC1, _FAC2, _SAFE, _STAGES, _UROUND, SCRATCH_ROWS, _crossing, _dense, _first_step,
                            _interpolant, _root8, _stage)
from .adaptive_loop import component_surface as surface
from ..tableaux import DOP853
from ..threads import in_shares
from ..trig import _max, _min

__all__ = ["BLOCK", "for_model", "specialised"]

# What the templates read, until a copy reads its own (specialised): the trial and the rate are always the copy's.
trial = None
rate = None

#: Lanes of a block: a sample's share steps in one block whose lanes take the next sample as theirs is done.
BLOCK = 32

# The rows of a block's lane numbers (``lanes``, float): each lane's time, step, trial step (0: done), whether it steps,
# whether its last step was rejected, whether this one was accepted, the time it reaches, its next output time, its
# surface's value, its error, its steps tried and accepted; and of its counters (int): its next output, its sample (-1:
# none), its crossings. Helpers index the rows (a row's view would cost reference counts on every call).
_T, _H, _TRIAL_H, _ACTIVE, _LAST_REJECTED, _ACCEPTED_NOW, _T_NEW, _NEXT_OUT, _G0, _ERR, _TRIES, _ACCEPTED = range(12)
_SLOT, _OWNER, _CROSSED = range(3)


@jit(inline=True, cache=False, contract=False)
def _stages(rate, y0, p, t, h, k, stage):
    """The step's stages ``k[1..12]`` from ``y0`` at ``t`` over ``h`` (``k[0]`` given): what a lane's dense output
    needs beyond the trial step, which keeps its stages in registers."""
    for s in range(1, _STAGES + 1):
        _stage(s, y0, h, k, stage)
        rate(t + _C[s] * h, stage, p, k[s])


@jit(inline=True)
def _stops(active, tries, h, t, max_steps):
    """Whether an active lane stops before its next try: its steps are used up, or its step cannot advance ``t``."""
    return active != 0.0 and (tries >= max_steps or not 0.1 * h > abs(t) * _UROUND)


@jit(contract=False, refcounts=False)
def _lane_extras(i, s, ys, ks, y1s, p, ti, hi, tn, times, out, slot, next_out, g0, crossed, component, value,
                 direction, most, crossing_t, crossing_y, k, stage, y0, y1, f):
    # size: one lane's accepted step's outputs and crossing, with the scratch they are made in
    """Lane ``i``'s (sample ``s``'s) accepted step ``(ti, ti + hi = tn)``: the surface's crossing and the output
    times in it, from the dense output (its stages made again, one sample); an output time at ``tn`` itself is
    ``y1``."""
    n = ys.shape[0]
    for j in range(n):
        y0[j] = ys[j, i]
        y1[j] = y1s[j, i]
    before = g0[i]
    g1 = 0.0
    crossing = False
    if most > 0:
        g1 = surface(tn, y1, p, component, value)
        crossing = (direction >= 0.0 and before < 0.0 <= g1) or (direction <= 0.0 and before > 0.0 >= g1)
        g0[i] = g1
    if crossing or next_out[i] < tn:
        for j in range(n):
            k[0, j] = ks[j, i]
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
    next_out[i] = times[slot[i]] if slot[i] < times.shape[0] else np.inf


@jit(inline=True, contract=False, refcounts=False)
def _start(i, s, y, ys, ks, p, t0, t_end, h0, rtol, atol, times, out, status, section, lanes, counters, k, stage,
           y0, y1):
    # size: one lane's start on a sample: its state, first outputs, rate, first step and surface value
    """Put sample ``s`` into lane ``i``: True when it steps, False when it is done at once (not finite, or no time
    to run)."""
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
    for row in (_T, _H, _LAST_REJECTED, _TRIES, _ACCEPTED, _G0):
        lanes[row, i] = 0.0
    lanes[_T, i] = t0
    slot = 0
    while slot < times.shape[0] and times[slot] <= t0:
        for j in range(n):
            out[s, slot, j] = y0[j]
        slot += 1
    counters[_SLOT, i] = slot
    counters[_CROSSED, i] = 0
    lanes[_NEXT_OUT, i] = times[slot] if slot < times.shape[0] else np.inf
    if code != STATUS_OK or t_end <= t0:
        lanes[_ACTIVE, i] = 0.0
        return False
    lanes[_ACTIVE, i] = 1.0
    rate(t0, y0, p, k[0])
    for j in range(n):
        ks[j, i] = k[0, j]
    lanes[_H, i] = h0 if h0 > 0.0 else _first_step(rate, t0, y0, p, t_end - t0, rtol, atol, k[0], stage, y1)
    if most > 0:
        lanes[_G0, i] = surface(t0, y0, p, component, value)
    return True


@jit(inline=True, contract=False, refcounts=False)
def _finish(i, y, ys, times, out, counts, stopped, lanes, counters):
    """Lane ``i``'s sample is done: its state, counts and time written back; a stopped sample's later outputs are
    the state it stopped with."""
    s = counters[_OWNER, i]
    n = ys.shape[0]
    for j in range(n):
        y[s, j] = ys[j, i]
    counts[s, 0] = int(lanes[_ACCEPTED, i])
    counts[s, 1] = int(lanes[_TRIES, i]) - counts[s, 0]
    counts[s, 2] = counters[_CROSSED, i]
    stopped[s] = lanes[_T, i]
    for slot in range(counters[_SLOT, i], times.shape[0]):
        for j in range(n):
            out[s, slot, j] = ys[j, i]
    counters[_SLOT, i] = times.shape[0]
    counters[_OWNER, i] = -1


@jit(inline=True, contract=False, refcounts=False)
def _fill(i, queued, y, ys, ks, p, t0, t_end, h0, rtol, atol, times, out, status, counts, stopped, section, lanes,
          counters, k, stage, y0, y1):
    # size: the share's queue, handed to one lane
    """Lane ``i`` takes the share's next samples from ``queued`` until one steps (those done at once are finished
    here): the next ``queued``."""
    while queued < y.shape[0]:
        started = _start(i, queued, y, ys, ks, p, t0, t_end, h0, rtol, atol, times, out, status, section, lanes,
                         counters, k, stage, y0, y1)
        queued += 1
        if started:
            break
        _finish(i, y, ys, times, out, counts, stopped, lanes, counters)
    return queued

@jit(contract=False)
def run_share(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
              counts, stopped):
    # size: as _run_block
    """The samples ``y`` of one share in one block (:func:`_run_block`), with the block's arrays made here."""
    n = y.shape[1]
    lanes = np.zeros((12, BLOCK))  # the lanes' own numbers (C-contiguous rows: the loops over lanes vectorise)
    counters = np.zeros((3, BLOCK), dtype=np.int64)
    rows = np.zeros((4, n, BLOCK))
    scratch = np.empty((SCRATCH_ROWS + 1, n))
    if y.shape[0] > 0:
        _run_block(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
                   counts, stopped, lanes, counters, rows, scratch)


@jit(contract=False, refcounts=False)
def _run_block(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
               counts, stopped, lanes, counters, rows, scratch):
    # size: Hairer's control over a block's lanes, with the outputs, the crossings, the stops and the lanes' refills
    """:func:`run_share`'s loop over the block's lanes, with the arrays it made: ``lanes`` (12, BLOCK) and ``counters``
    (3, BLOCK), rows named by ``_T`` ... and ``_SLOT`` ...; ``rows`` (4, n, BLOCK) the lanes' states, rates, trial
    states and their rates; ``scratch`` (:data:`SCRATCH_ROWS` + 1, n) one sample's dense output. It makes no array, so
    it runs without numba's reference counts (:func:`tumble.kernels.jit.jit`'s ``refcounts``)."""
    n = y.shape[1]
    m = BLOCK
    component, value, direction, most = int(section[0]), section[1], section[2], int(section[3])
    t, h, trial_h, active, last_rejected, accepted_now, t_new, next_out, g0, err, tries, accepted = (
        lanes[_T], lanes[_H], lanes[_TRIAL_H], lanes[_ACTIVE], lanes[_LAST_REJECTED], lanes[_ACCEPTED_NOW],
        lanes[_T_NEW], lanes[_NEXT_OUT], lanes[_G0], lanes[_ERR], lanes[_TRIES], lanes[_ACCEPTED])
    slot, owner, crossed = counters[_SLOT], counters[_OWNER], counters[_CROSSED]
    for i in range(m):
        owner[i] = -1
    ys, ks, y1s, k1s = rows[0], rows[1], rows[2], rows[3]
    k, stage, y0, y1, f = scratch[:16], scratch[16], scratch[17], scratch[18], scratch[19:26]
    for j in range(n):  # a lane without a sample holds the first one's state, masked (its trial step is 0)
        for i in range(m):
            ys[j, i] = y[0, j]
    queued = 0
    for i in range(m):
        queued = _fill(i, queued, y, ys, ks, p, t0, t_end, h0, rtol, atol, times, out, status, counts, stopped,
                       section, lanes, counters, k, stage, y0, y1)
    while active.any():
        stops = 0  # counted without a branch (an integer sum vectorises, a float one does not)
        for i in range(m):
            stops += 1 if _stops(active[i], tries[i], h[i], t[i], max_steps) else 0
        if stops > 0:  # rare
            for i in range(m):
                if _stops(active[i], tries[i], h[i], t[i], max_steps):
                    status[owner[i]] = STATUS_LIMIT if tries[i] >= max_steps else STATUS_UNDERFLOW
                    active[i] = 0.0
        for i in range(m):  # each lane's step, the last one up to t_end; 0 for a lane that is done
            last = t[i] + 1.01 * h[i] >= t_end
            h[i] = t_end - t[i] if last else h[i]
            trial_h[i] = h[i] * active[i]
            t_new[i] = t_end if last else t[i] + h[i]
        trial(t, trial_h, ys, ks, y1s, k1s, err, rtol, atol, a)
        extras = 0
        for i in range(m):  # accept or reject every lane, branch-free (Hairer's control), in floats: vectorised
            e = err[i]
            good = 1.0 if e <= 1.0 else 0.0
            # the step's factor, kept within [1/6, 1/0.333] (a non-finite error: the smallest, 0.333); an accepted
            # step grows by at most 6 (an error of 0, a steady spin's: 6), a rejected one shrinks by its factor; the
            # step is chosen, not blended (an error of 0 makes the shrunk step h / 0), both made first: vectorised
            factor = _min(1.0 / _FAC1, _root8(e) / _SAFE) if e < 1e300 else 1.0 / _FAC1
            grow = h[i] / _max(1.0 / _FAC2, factor)
            grow = _min(grow, h[i]) if last_rejected[i] != 0.0 else grow
            shrink = h[i] / factor
            on = active[i]
            h[i] = (grow if good != 0.0 else shrink) if on != 0.0 else h[i]
            last_rejected[i] = on * (1.0 - good) + (1.0 - on) * last_rejected[i]
            tries[i] += on
            accepted_now[i] = on * good
            accepted[i] += on * good
            # an accepted step that reaches an output time, or any of a section's
            extras += 1 if accepted_now[i] != 0.0 and (next_out[i] <= t_new[i] or most > 0) else 0
        if extras > 0:
            for i in range(m):  # outputs and crossings: the lane's dense output, made again one sample
                if accepted_now[i] != 0.0 and (next_out[i] <= t_new[i] or most > 0):
                    _lane_extras(i, owner[i], ys, ks, y1s, p, t[i], trial_h[i], t_new[i], times, out, slot,
                                 next_out, g0, crossed, component, value, direction, most, crossing_t,
                                 crossing_y, k, stage, y0, y1, f)
        done = 0
        # the accepted lanes move on, done at t_end or with their crossings (both times read before the choice, and no
        # short-circuit: so that the pass vectorises), and the lanes whose sample is done are counted
        for i in range(m):
            moved, stayed = t_new[i], t[i]
            t[i] = moved if accepted_now[i] != 0.0 else stayed
            finished = (t[i] == t_end) | ((most > 0) & (crossed[i] == most))
            active[i] = 0.0 if finished else active[i]
            done += 1 if (active[i] == 0.0) & (owner[i] >= 0) else 0
        for j in range(n):  # their new states and rates
            for i in range(m):
                ys[j, i] = y1s[j, i] if accepted_now[i] != 0.0 else ys[j, i]
                ks[j, i] = k1s[j, i] if accepted_now[i] != 0.0 else ks[j, i]
        if done > 0:
            for i in range(m):
                if active[i] == 0.0 and owner[i] >= 0:
                    _finish(i, y, ys, times, out, counts, stopped, lanes, counters)
                    queued = _fill(i, queued, y, ys, ks, p, t0, t_end, h0, rtol, atol, times, out, status, counts,
                                   stopped, section, lanes, counters, k, stage, y0, y1)


#: The functions :func:`specialised` copies, callees first.
_FUNCTIONS = ("_lane_extras", "_start", "_finish", "_fill", "_run_block", "run_share")


def specialised(trial, rate, surface=None, key=None):
    """``drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
    counts, stopped)``, as :func:`tumble.kernels.loops.adaptive_loop.make_dop853_driver`'s (``p`` the rate's
    parameters, ``a`` the trial's constants), over ``trial``, ``rate`` and ``surface`` (None: the component surface):
    this module's functions copied with those in their globals (:func:`tumble.kernels.jit.rebound`), compiled on first
    use; one share of the samples per numba thread, each share in one block (a share is whole blocks: a run of one
    block's samples or fewer stays in the calling thread). Cached on disk under ``key`` (a string that names what they
    compute in every process: a model's system module, a System's code), not cached without it."""
    share = rebound(_FUNCTIONS, globals(), key, trial=trial, rate=rate,
                    surface=surface if surface is not None else globals()["surface"])["run_share"]

    def drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
              counts, stopped):
        # size: as run_share
        in_shares(share, len(y), lambda lo, hi: (y[lo:hi], p, a, t0, t_end, h0, rtol, atol, max_steps, times,
                                                 out[lo:hi], section, crossing_t[lo:hi], crossing_y[lo:hi],
                                                 status[lo:hi], counts[lo:hi], stopped[lo:hi]), BLOCK)

    drive.run_share = share  # the compiled share, for its cache statistics
    return drive


def for_model(module, surface=None):
    """:func:`specialised`'s driver of the built-in models whose equations are in system module ``module`` (the
    registry's ``equations_module``: the free body's are the gyrostat's): its own generated trial step
    (``model_steps.<module>_dop853_trial``, whose constants ``a`` are the models' parameters after their code), the
    models' rate (``p``: the parameters, code first) and ``surface`` (None: the component surface, cached on disk under
    ``module``). A first run compiles that model's trial alone: one trial for every model made a first free-body run
    compile all four (24 s to 14 s on 2 cores)."""
    return specialised(getattr(model_steps, f"{module}_{DOP853.name}_trial"), model_steps.rate_sample, surface,
                       module if surface is None else None)
