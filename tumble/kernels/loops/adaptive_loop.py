"""An error-controlled run of a system given by its rate: DOP853, each sample its own steps, outputs from the dense output.

The method is Dormand & Prince's eighth-order pair as Hairer distributes it (``dop853.f``; Hairer, Norsett & Wanner,
*Solving Ordinary Differential Equations I*, 2nd ed., sect. II.4–II.10), with its coefficients as data
(:data:`tumble.kernels.tableaux.DOP853`):

* the step is rk8's 12 stages, then ``f(t + h, y1)``, which is the next step's first stage;
* the error is the embedded fifth-order estimate, damped by the third-order one: with ``sk = atol + rtol max(|y0|,
  |y1|)`` per component, ``err = |h| e5² / sqrt(n (e5² + 0.01 e3²))``, ``e5² = sum (E5·k / sk)²`` and ``e3²`` the
  same with ``E3``; a step is accepted when ``err <= 1``;
* the next step is ``h / fac``, ``fac = err^(1/8) / facold^(1/16) / 0.9`` kept within ``[1/6, 1/0.333]`` (Hairer's
  ``fac1``, ``fac2``, ``safe`` and ``beta``, his PI control); after a rejection the step does not grow
  (:func:`tumble.kernels.steps.control.next_step`);
* the first step, unless given, is Hairer's ``hinit`` (one more evaluation of the rate);
* the last step ends at ``t_end`` (``dop853.f``: a step within 1 % of it is stretched to it); where the controller's
  step would leave less than itself before ``t_end``, the two steps left are each half of what is left
  (:func:`_step_to_end`): as many tries as the step and the sliver after it, each shorter. A quiet phase before the
  end can grow the step past the error estimate's asymptotic range, where it underestimates the step's error (5-30x on
  the work-precision benchmark's ensemble, whose largest errors came from such steps);
* a step smaller than ``|t| · 2.3e-16 · 10`` cannot advance ``t``: the sample stops with ``STATUS_UNDERFLOW``, or
  ``STATUS_NONFINITE`` where that step's stages still hold a NaN or an infinity (the rate returns one however short
  the step: :func:`_underflow_status`); one that needs more than ``max_steps`` accepted and rejected steps stops with
  ``STATUS_LIMIT``; each keeps the state it had;
* the output times are read off the dense output of order 7 (three more stages, made only in a step that holds an
  output time), so the steps are the tolerance's, never the outputs'.

:func:`make_dop853_sample` writes one sample's whole run; it is scalar code on one sample's arrays, so the CPU's driver
(:func:`make_dop853_driver`, a share of the samples per thread, as :func:`tumble.kernels.loops.sample_loop.make_cpu_driver`)
and a device's one thread per sample (:mod:`tumble.kernels.cuda.adaptive`) can call it alike.
:mod:`tumble.kernels.loops.adaptive_blocks` steps blocks of samples at once instead, each lane at its own time and
step, with a generated trial step vectorised across the lanes: the CPU's path for the built-in models and for a System
with a scalar form. The per-sample loop is written once over module-level names (``rate``, ``surface``) and copied for each
system with its own (:func:`tumble.kernels.jit.rebound`): a copy with a key that names its functions is cached on disk,
as the chaos indicators' augmented rate of the built-in models is (:mod:`tumble.kernels.loops.variational`).
"""

import math

import numpy as np

from ...registry import STATUS_LIMIT, STATUS_NONFINITE, STATUS_OK, STATUS_UNDERFLOW
from ..jit import jit, rebound
from ..steps.control import FIRST_FACOLD, ROUND, next_step, root8
from ..tableaux import DOP853
from ..threads import in_shares
from ..trig import _max, _min

__all__ = ["SCRATCH_ROWS", "component_surface", "make_dop853_driver", "make_dop853_sample", "make_user_surface"]

_STAGES = len(DOP853.tableau.b)  # 12; k[12] = f(t + h, y1), k[13..15] the dense output's stages
_A = np.zeros((16, 16))
_A[:_STAGES, :_STAGES] = DOP853.tableau.A
_A[_STAGES, :_STAGES] = DOP853.tableau.b
_A[_STAGES + 1:] = DOP853.extra_a
_C = np.concatenate([DOP853.tableau.c, [1.0], DOP853.extra_c])
_B = np.concatenate([DOP853.tableau.b, [0.0]])
_E5, _E3_FROM_B, _D = DOP853.e5.copy(), DOP853.e3_from_b, DOP853.dense.copy()

#: Rows of the scratch a sample's run needs (its state has ``n`` components): 16 stages, the stage's state, ``y1``,
#: the 7 rows of the interpolant.
SCRATCH_ROWS = 16 + 2 + 7


@jit(inline=True)
def _stage(s, y, h, k, out):
    """``out = y + h sum_{j < s} A[s, j] k[j]`` (a zero coefficient skipped)."""
    for j in range(y.shape[0]):
        total = 0.0
        for r in range(s):
            if _A[s, r] != 0.0:
                total += _A[s, r] * k[r, j]
        out[j] = y[j] + h * total


@jit(inline=True, cache=False, contract=False)
def _stages(rate, y0, p, t, h, k, stage):
    """The step's stages ``k[1..12]`` from ``y0`` at ``t`` over ``h`` (``k[0]`` given)."""
    for s in range(1, _STAGES + 1):
        _stage(s, y0, h, k, stage)
        rate(t + _C[s] * h, stage, p, k[s])


@jit(inline=True, cache=False, contract=False)
def _underflow_status(rate, y0, p, t, h, k, stage):
    """The status of a sample at ``t`` whose next step cannot advance ``t``, ``h`` its last try: ``STATUS_NONFINITE``
    when that try's stages from ``y0`` (``k[0]`` its rate) hold a NaN or an infinity, so that the rate returned one
    however short the step (a rate undefined from here on: its tries were rejected for a non-finite error down to the
    shortest), else ``STATUS_UNDERFLOW`` (a singularity, or a tolerance the arithmetic cannot meet). Made again once,
    at the stop."""
    _stages(rate, y0, p, t, h, k, stage)
    for s in range(_STAGES + 1):
        for j in range(y0.shape[0]):
            if not math.isfinite(k[s, j]):
                return STATUS_NONFINITE
    return STATUS_UNDERFLOW


@jit(inline=True)
def _step_to_end(t, h, t_end, last):
    """The step to try from ``t`` where the controller asks ``h``: ``t_end - t`` for the ``last`` step (``t + 1.01 h >=
    t_end``), half of it where ``h`` would leave less than ``h``, else ``h``."""
    left = t_end - t
    return left if last else (0.5 * left if t + 2.0 * h > t_end else h)


def make_dop853_sample(rate, surface=None, key=None):
    """:func:`run_sample` over ``rate(t, y, p, dydt)`` and ``surface`` (None: :func:`component_surface`), a copy that
    reads them as its globals (:func:`tumble.kernels.jit.rebound`): cached on disk under ``key`` (a string naming what
    they compute in every process), compiled in each process without it."""
    return rebound(("run_sample",), globals(), key, rate=rate,
                   surface=component_surface if surface is None else surface)["run_sample"]


@jit(cache=False, contract=False)  # a template over the globals rate, surface: its copies run
def run_sample(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, scratch):
    # size: Hairer's loop written once: stages, error, step control, dense output, crossings, the stops
    """One sample's error-controlled run of ``rate(t, y, p, dydt)`` from ``t0`` to ``t_end``: ``(status, accepted,
    rejected, crossings, t)``.

    ``y`` (n,) is advanced in place to ``t_end`` (or frozen where the sample stopped, at the time ``t`` returned);
    ``rtol``, ``atol`` (n,); ``h0`` the first step (0: chosen); ``times`` (T,) the output times, increasing, within
    ``[t0, t_end]``, whose states go to ``out`` (T, n) (the state the sample stopped with after a stop); ``scratch``
    (:data:`SCRATCH_ROWS`, n).

    The crossings of a surface ``g = 0``: ``section`` (4,) holds ``(component, value, direction, most)``; ``g`` is
    ``surface(t, y, p, component, value)``, by default ``y[component] − value`` (:func:`component_surface`).
    A crossing is a sign change of ``g`` over an accepted step, ``g0 < 0 <= g1`` upward (direction 1), ``g0 > 0 >= g1``
    downward (−1), either (0); it is located on the dense output by a bracketing root finder (Illinois) to a few
    ulps of ``t``, its time and state written to ``crossing_t`` (most,) and ``crossing_y`` (most, n). A sample stops
    (status ok) once it has ``most`` crossings; ``most = 0``: no section (``g`` is never evaluated). A step that
    crosses twice counts neither (as SciPy's events): the tolerance's steps are short against the motion."""
    n = y.shape[0]
    k = scratch[:16]
    stage = scratch[16]
    y1 = scratch[17]
    f = scratch[18:25]
    code = STATUS_OK
    for j in range(n):
        if not math.isfinite(y[j]):
            code = STATUS_NONFINITE
    t = t0
    slot = 0
    while slot < times.shape[0] and times[slot] <= t0:
        for j in range(n):
            out[slot, j] = y[j]
        slot += 1
    accepted = 0
    rejected = 0
    crossed = 0
    component, value, direction, most = int(section[0]), section[1], section[2], int(section[3])
    if code != STATUS_OK or t_end <= t0:
        for s in range(slot, times.shape[0]):
            for j in range(n):
                out[s, j] = y[j]
        return code, accepted, rejected, crossed, t
    g0 = surface(t, y, p, component, value) if most > 0 else 0.0
    rate(t, y, p, k[0])
    h = h0 if h0 > 0.0 else _first_step(rate, t, y, p, t_end - t, rtol, atol, k[0], stage, y1)
    last_rejected = False
    facold = FIRST_FACOLD
    tried = h
    while t < t_end:
        if accepted + rejected >= max_steps:
            code = STATUS_LIMIT
            break
        if 0.1 * h <= abs(t) * ROUND or not h > 0.0:
            code = _underflow_status(rate, y, p, t, tried, k, stage)
            break
        final = t + 1.01 * h >= t_end
        h = _step_to_end(t, h, t_end, final)
        tried = h
        for s in range(1, _STAGES + 1):  # the stages, then f(t + h, y1): y1 is the last stage's state
            _stage(s, y, h, k, stage)
            if s == _STAGES:
                for j in range(n):
                    y1[j] = stage[j]
            rate(t + _C[s] * h, stage, p, k[s])
        err5 = 0.0
        err3 = 0.0
        for j in range(n):
            scale = 1.0 / (atol[j] + rtol[j] * _max(abs(y[j]), abs(y1[j])))
            e5 = 0.0
            increment = 0.0  # the step's over h, as _stage made it: the third-order estimate is it less three stages
            for s in range(_STAGES + 1):
                if _E5[s] != 0.0:
                    e5 += _E5[s] * k[s, j]
                if _B[s] != 0.0:
                    increment += _B[s] * k[s, j]
            e3 = increment
            for s, weight in _E3_FROM_B:
                e3 -= weight * k[s, j]
            err5 += (e5 * scale) * (e5 * scale)
            err3 += (e3 * scale) * (e3 * scale)
        deno = err5 + 0.01 * err3
        # a NaN among the stages (a rate that returned one) is a non-finite error, rejected, never an error of 0
        err = h * err5 / math.sqrt(n * deno) if deno > 0.0 else (0.0 if deno == 0.0 else math.inf)
        h_next, facold = next_step(err, h, 1.0 if last_rejected else 0.0, facold)  # facold: changed by a kept try
        if err <= 1.0:
            accepted += 1
            t_new = t_end if final else t + h
            built = False
            if most > 0:
                g1 = surface(t_new, y1, p, component, value)
                if (direction >= 0.0 and g0 < 0.0 <= g1) or (direction <= 0.0 and g0 > 0.0 >= g1):
                    _interpolant(rate, y, y1, p, t, h, k, stage, f)
                    built = True
                    x = _crossing(surface, f, y, p, t, h, g0, g1, component, value, stage)
                    crossing_t[crossed] = t_new if x == 1.0 else t + x * h
                    _dense(f, y, x, crossing_y[crossed])
                    crossed += 1
                g0 = g1
            if slot < times.shape[0] and times[slot] <= t_new:
                if not built:
                    _interpolant(rate, y, y1, p, t, h, k, stage, f)
                while slot < times.shape[0] and times[slot] <= t_new:
                    if times[slot] == t_new:
                        for j in range(n):
                            out[slot, j] = y1[j]
                    else:
                        _dense(f, y, (times[slot] - t) / h, out[slot])
                    slot += 1
            for j in range(n):
                y[j] = y1[j]
                k[0, j] = k[_STAGES, j]
            t = t_new
            last_rejected = False
            h = h_next
            if most > 0 and crossed == most:
                break  # the section is complete
        else:  # rejected, or a stage overflowed (a non-finite error: the largest fall)
            last_rejected = True
            rejected += 1
            h = h_next
    for s in range(slot, times.shape[0]):  # a stopped sample: the state it stopped with
        for j in range(n):
            out[s, j] = y[j]
    return code, accepted, rejected, crossed, t



@jit(inline=True)
def component_surface(t, y, p, component, value):
    """The default surface of a section, ``g = y[component] − value``."""
    return y[component] - value


# What the templates run_sample and run_share read, until a copy reads its own (rebound): the rate is always the copy's.
rate = None
surface = component_surface


@jit(inline=True, cache=False, contract=False)
def _crossing(surface, f, y0, p, t, h, g0, g1, component, value, trial):
    """Where in the step ``(t, t + h)`` the surface is crossed, as ``x = (t* − t) / h`` in ``(0, 1]``: ``g`` (``g0`` at
    0, ``g1`` at 1, of opposite signs or ``g1 = 0``) on the dense output ``f`` (from ``y0``), by regula falsi with the
    Illinois halving (Dahlquist & Björck, *Numerical Methods*, sect. 6.2.3), which keeps the root bracketed; until the
    bracket is a few ulps of ``t`` wide. ``trial`` (n,): scratch for the interpolated state."""
    if g1 == 0.0:
        return 1.0
    a, b, ga, gb = 0.0, 1.0, g0, g1
    side = 0
    width = 4.0 * ROUND * _max(abs(t), abs(t + h)) / h
    for _ in range(200):
        x = (a * gb - b * ga) / (gb - ga)
        if not (a < x < b):
            x = 0.5 * (a + b)
        _dense(f, y0, x, trial)
        gx = surface(t + x * h, trial, p, component, value)
        if gx == 0.0:
            return x
        if (gx > 0.0) == (gb > 0.0):
            b, gb = x, gx
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            a, ga = x, gx
            if side == 1:
                gb *= 0.5
            side = 1
        if b - a <= width:
            break
    return 0.5 * (a + b)


@jit(inline=True, cache=False, contract=False)
def _first_step(rate, t, y, p, span, rtol, atol, f0, y_trial, f1):
    """Hairer's initial step (``hinit`` of dop853.f, as SciPy's ``select_initial_step``): from the sizes of ``y``,
    ``f(t, y)`` (``f0``) and an estimate of the second derivative (one more evaluation of the rate), within
    ``span``."""
    n = y.shape[0]
    d0 = 0.0
    d1 = 0.0
    for j in range(n):
        sk = atol[j] + rtol[j] * abs(y[j])
        d0 += (y[j] / sk) ** 2
        d1 += (f0[j] / sk) ** 2
    d0 = math.sqrt(d0 / n)
    d1 = math.sqrt(d1 / n)
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = _min(h0, span)
    for j in range(n):
        y_trial[j] = y[j] + h0 * f0[j]
    rate(t + h0, y_trial, p, f1)
    d2 = 0.0
    for j in range(n):
        sk = atol[j] + rtol[j] * abs(y[j])
        d2 += ((f1[j] - f0[j]) / sk) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = _max(1e-6, h0 * 1e-3)
    else:
        h1 = root8(0.01 / _max(d1, d2))
    return _min(100.0 * h0, h1, span)


@jit(inline=True, cache=False, contract=False)
def _interpolant(rate, y0, y1, p, t, h, k, stage, f):
    """The seven rows ``f`` of the order-7 interpolant of the step ``(t, y0) -> (t + h, y1)``: its three more stages
    (``k[13..15]``), then ``f[0] = y1 − y0``, ``f[1] = h k0 − f[0]``, ``f[2] = 2 f[0] − h (k12 + k0)``, ``f[3..6] =
    h D k`` (SciPy's ``DOP853._dense_output_impl``)."""
    n = y0.shape[0]
    for s in range(_STAGES + 1, 16):
        _stage(s, y0, h, k, stage)
        rate(t + _C[s] * h, stage, p, k[s])
    for j in range(n):
        dy = y1[j] - y0[j]
        f[0, j] = dy
        f[1, j] = h * k[0, j] - dy
        f[2, j] = 2.0 * dy - h * (k[_STAGES, j] + k[0, j])
        for r in range(4):
            total = 0.0
            for s in range(16):
                if _D[r, s] != 0.0:
                    total += _D[r, s] * k[s, j]
            f[3 + r, j] = h * total


@jit(inline=True)
def _dense(f, y0, x, out):
    """The interpolant at ``x = (t − t0) / h`` in ``[0, 1]``: ``y0 + x (f0 + (1 − x) (f1 + x (f2 + ...)))``, Horner's
    form from the last row (SciPy's ``Dop853DenseOutput``)."""
    for j in range(y0.shape[0]):
        acc = 0.0
        for i in range(7):
            acc += f[6 - i, j]
            acc *= x if i % 2 == 0 else 1.0 - x
        out[j] = y0[j] + acc


def make_dop853_driver(run_sample, key=None):
    """``drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
    counts, stopped)``: every sample of ``y`` (N, n) run by ``run_sample`` (:func:`make_dop853_sample`), ``y`` overwritten with
    the final (or frozen) states, ``out`` (N, T, n) with the states at ``times``, ``crossing_t`` (N, most) and
    ``crossing_y`` (N, most, n) with the section's crossings (``section`` as the run's), ``status`` (N,) int8 and
    ``stopped`` (N,) the time each sample reached, written; ``counts`` (N, 3) int64, the steps accepted and rejected
    (and the crossings, written): the steps each sample took before, 0 for a new run, this run's added, and
    ``max_steps`` bounds the total (a run in segments, as the Lyapunov spectrum's, bounds the whole run); one share
    of the samples per numba thread (:func:`tumble.kernels.threads.in_shares`).
    Cached on disk under ``key`` (as ``run_sample``'s), compiled in each process without it."""
    share = rebound(("run_share",), globals(), key, run_sample=run_sample)["run_share"]

    def drive(y, p, a, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
              counts, stopped):
        # size: as run_share (``a``, the block driver's constants, unused)
        in_shares(share, len(y), lambda lo, hi: (y[lo:hi], p, t0, t_end, h0, rtol, atol, max_steps, times,
                                                 out[lo:hi], section, crossing_t[lo:hi], crossing_y[lo:hi],
                                                 status[lo:hi], counts[lo:hi], stopped[lo:hi]))

    drive.run_share = share  # the compiled share, for its cache statistics
    return drive


@jit(cache=False, contract=False)  # a template over the global run_sample: its copies run
def run_share(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status, counts,
              stopped):
    # size: the run's arguments and one output array each, for a share of the samples
    n_samples, n = y.shape
    state = np.empty(n)
    scratch = np.empty((SCRATCH_ROWS, n))
    for i in range(n_samples):
        state[:] = y[i]
        taken = counts[i, 0] + counts[i, 1]  # before this run (0 for a new one): max_steps bounds the sample's total
        code, good, bad, crossed, t = run_sample(state, p, t0, t_end, h0, rtol, atol, max_steps - taken, times, out[i],
                                                 section, crossing_t[i], crossing_y[i], scratch)
        y[i] = state
        status[i] = code
        counts[i, 0] += good
        counts[i, 1] += bad
        counts[i, 2] = crossed
        stopped[i] = t


def make_user_surface(g):
    """A user's surface ``g(t, y, p) -> float`` (compiled) as the run calls a surface,
    ``surface(t, y, p, component, value)`` (the two last unused)."""

    @jit(cache=False, inline=True)
    def surface(t, y, p, component, value):
        return float(g(t, y, p))

    return surface
