"""An error-controlled run of a system given by its rate: DOP853, each sample its own steps, outputs from the dense output.

The method is Dormand & Prince's eighth-order pair as Hairer distributes it (``dop853.f``; Hairer, Norsett & Wanner,
*Solving Ordinary Differential Equations I*, 2nd ed., sect. II.4–II.10), with its coefficients as data
(:data:`tumble.kernels.tableaux.DOP853`):

* the step is rk8's 12 stages, then ``f(t + h, y1)``, which is the next step's first stage;
* the error is the embedded fifth-order estimate, damped by the third-order one: with ``sk = atol + rtol max(|y0|,
  |y1|)`` per component, ``err = |h| e5² / sqrt(n (e5² + 0.01 e3²))``, ``e5² = sum (E5·k / sk)²`` and ``e3²`` the
  same with ``E3``; a step is accepted when ``err <= 1``;
* the next step is ``h / fac``, ``fac = err^(1/8) / 0.9`` kept within ``[1/6, 1/0.333]`` (Hairer's ``fac1``, ``fac2``
  and ``safe``, ``beta = 0``); after a rejection the step does not grow;
* the first step, unless given, is Hairer's ``hinit`` (one more evaluation of the rate);
* a step smaller than ``|t| · 2.3e-16 · 10`` cannot advance ``t``: the sample stops with ``STATUS_UNDERFLOW``; one that
  needs more than ``max_steps`` accepted and rejected steps stops with ``STATUS_LIMIT``; both keep the state they had;
* the output times are read off the dense output of order 7 (three more stages, made only in a step that holds an
  output time), so the steps are the tolerance's, never the outputs'.

:func:`make_dop853_sample` writes one sample's whole run; it is scalar code on one sample's arrays, so the CPU's driver
(:func:`make_dop853_driver`, a share of the samples per thread, as :func:`tumble.kernels.loops.sample_loop.make_cpu_driver`)
and a device's one thread per sample can call it alike. Like the fixed-step per-sample loop, it is a closure over the
rate, compiled once per process.
"""

import math

import numpy as np

from ...registry import STATUS_LIMIT, STATUS_NONFINITE, STATUS_OK, STATUS_UNDERFLOW
from ..jit import jit
from ..tableaux import DOP853
from .sample_loop import in_shares

__all__ = ["SCRATCH_ROWS", "make_dop853_driver", "make_dop853_sample"]

_STAGES = len(DOP853.tableau.b)  # 12; k[12] = f(t + h, y1), k[13..15] the dense output's stages
_A = np.zeros((16, 16))
_A[:_STAGES, :_STAGES] = DOP853.tableau.A
_A[_STAGES, :_STAGES] = DOP853.tableau.b
_A[_STAGES + 1:] = DOP853.extra_a
_C = np.concatenate([DOP853.tableau.c, [1.0], DOP853.extra_c])
_B = DOP853.tableau.b.copy()
_E5, _E3, _D = DOP853.e5.copy(), DOP853.e3.copy(), DOP853.dense.copy()
_EXPONENT = 1.0 / (DOP853.error_order + 1)

# Hairer's defaults (dop853.f): safety factor, the step's largest fall and rise per step, the rounding unit.
_SAFE, _FAC1, _FAC2, _UROUND = 0.9, 0.333, 6.0, 2.3e-16

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


def make_dop853_sample(rate):
    """``run_sample(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, scratch) -> (status, accepted,
    rejected)``: one sample's error-controlled run of ``rate(t, y, p, dydt)`` from ``t0`` to ``t_end``.

    ``y`` (n,) is advanced in place to ``t_end`` (or frozen where the sample stopped); ``rtol``, ``atol`` (n,);
    ``h0`` the first step (0: chosen); ``times`` (T,) the output times, increasing, within ``[t0, t_end]``, whose states
    go to ``out`` (T, n) (the state the sample stopped with after a stop); ``scratch`` (:data:`SCRATCH_ROWS`, n)."""

    @jit(cache=False)
    def run_sample(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, scratch):
        # size: Hairer's loop written once: stages, error, step control, dense output, the stops
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
        if code != STATUS_OK or t_end <= t0:
            for s in range(slot, times.shape[0]):
                for j in range(n):
                    out[s, j] = y[j]
            return code, accepted, rejected
        rate(t, y, p, k[0])
        h = h0 if h0 > 0.0 else _first_step(rate, t, y, p, t_end - t, rtol, atol, k[0], stage, y1)
        last_rejected = False
        while t < t_end:
            if accepted + rejected >= max_steps:
                code = STATUS_LIMIT
                break
            if 0.1 * h <= abs(t) * _UROUND or not h > 0.0:
                code = STATUS_UNDERFLOW
                break
            final = t + 1.01 * h >= t_end
            if final:
                h = t_end - t
            for s in range(1, _STAGES + 1):  # the stages, then f(t + h, y1): y1 is the last stage's state
                _stage(s, y, h, k, stage)
                if s == _STAGES:
                    for j in range(n):
                        y1[j] = stage[j]
                rate(t + _C[s] * h, stage, p, k[s])
            err5 = 0.0
            err3 = 0.0
            for j in range(n):
                sk = atol[j] + rtol[j] * max(abs(y[j]), abs(y1[j]))
                e5 = 0.0
                e3 = 0.0
                for s in range(_STAGES + 1):
                    e5 += _E5[s] * k[s, j]
                    e3 += _E3[s] * k[s, j]
                err5 += (e5 / sk) ** 2
                err3 += (e3 / sk) ** 2
            deno = err5 + 0.01 * err3
            err = h * err5 / math.sqrt(n * deno) if deno > 0.0 else 0.0
            if not math.isfinite(err):  # a stage overflowed: a much shorter step
                h /= 1.0 / _FAC1
                last_rejected = True
                rejected += 1
                continue
            fac11 = err ** _EXPONENT
            if err <= 1.0:
                accepted += 1
                t_new = t_end if final else t + h
                if slot < times.shape[0] and times[slot] <= t_new:
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
                grow = max(1.0 / _FAC2, min(1.0 / _FAC1, fac11 / _SAFE))
                h_new = h / grow
                if last_rejected:
                    h_new = min(h_new, h)
                last_rejected = False
                h = h_new
            else:
                h /= min(1.0 / _FAC1, fac11 / _SAFE)
                last_rejected = True
                rejected += 1
        for s in range(slot, times.shape[0]):  # a stopped sample: the state it stopped with
            for j in range(n):
                out[s, j] = y[j]
        return code, accepted, rejected

    return run_sample


@jit(inline=True)
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
    h0 = min(h0, span)
    for j in range(n):
        y_trial[j] = y[j] + h0 * f0[j]
    rate(t + h0, y_trial, p, f1)
    d2 = 0.0
    for j in range(n):
        sk = atol[j] + rtol[j] * abs(y[j])
        d2 += ((f1[j] - f0[j]) / sk) ** 2
    d2 = math.sqrt(d2 / n) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** _EXPONENT
    return min(100.0 * h0, h1, span)


@jit(inline=True)
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


def make_dop853_driver(run_sample):
    """``drive(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, status, accepted, rejected)``: every sample of
    ``y`` (N, n) run by ``run_sample`` (:func:`make_dop853_sample`), ``y`` overwritten with the final (or frozen)
    states, ``out`` (N, T, n) with the states at ``times``, ``status`` (N,) int8 and the steps accepted and rejected
    (N,) int64 written; one share of the samples per numba thread (:func:`tumble.kernels.loops.sample_loop.in_shares`)."""

    @jit(cache=False)
    def run_share(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, status, accepted, rejected):
        n_samples, n = y.shape
        state = np.empty(n)
        scratch = np.empty((SCRATCH_ROWS, n))
        for i in range(n_samples):
            state[:] = y[i]
            code, good, bad = run_sample(state, p, t0, t_end, h0, rtol, atol, max_steps, times, out[i], scratch)
            y[i] = state
            status[i] = code
            accepted[i] = good
            rejected[i] = bad

    def drive(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, status, accepted, rejected):
        in_shares(run_share, len(y), lambda lo, hi: (y[lo:hi], p, t0, t_end, h0, rtol, atol, max_steps, times,
                                                     out[lo:hi], status[lo:hi], accepted[lo:hi], rejected[lo:hi]))

    return drive
