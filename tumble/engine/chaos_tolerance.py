"""The chaos indicators at a tolerance: :func:`tumble.lyapunov`, :func:`tumble.megno` and :func:`tumble.gali` with
``method="dop853"``.

The state, its tangent vectors and what the indicators integrate along them are one ODE
(:mod:`tumble.kernels.loops.variational`), which the error-controlled loop of :mod:`tumble.kernels.loops.adaptive_loop`
steps to the tolerance, each sample its own steps, its outputs read off the dense output. The whole augmented state is
error-controlled, the vectors and their integrals with the state's smallest ``rtol`` and ``atol``: a vector's error
is then small against its own size, as the state's is, and the exponents are accurate to the tolerance rather than
only the orbit (the tangents riding on the state's steps unchecked would be the cheaper choice, and the one that
lets a growing vector's error go unseen).

* MEGNO and GALI keep each vector at unit length continuously: one run from 0 to ``t_end`` (:func:`run_unit`).
* The spectrum steps the plain variational equations and orthonormalises the vectors by a QR factorisation every
  ``renormalise`` seconds, at the transient's end and at ``t_end`` (Benettin et al. 1980, as the fixed steps do):
  :func:`run_spectrum` runs the segments between, each sample starting each segment with Hairer's first step. A
  finite-time exponent at an output time inside a segment is read off the dense output's vectors there.

The CPU runs a share of the samples per thread, one sample at a time; :func:`lyapunov_variables`,
:func:`megno_variables` and :func:`gali_variables` turn a run into each indicator's Dataset variables
(:mod:`tumble.engine.chaos` checks the arguments and builds the Dataset).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import registry
from ..kernels import adaptive_loop, variational
from .adaptive_runs import output_times, run_variables, tolerance_attrs, tolerances, warn_stops

__all__ = ["SpectrumRun", "VariationalRun", "gali_variables", "lyapunov_variables", "megno_variables", "run_spectrum",
           "run_unit"]

#: (rate, tangents) -> the CPU driver of their augmented state (made once per process, for every indicator).
_DRIVERS = {}


class VariationalRun(NamedTuple):
    """What :func:`run_unit` returns (arrays per sample first)."""

    times: np.ndarray  # (T,) s, the output times
    states: np.ndarray  # (N, T, m): the augmented states there (the state a sample stopped with after a stop)
    final: np.ndarray  # (N, m): at t_end, or where the sample stopped
    stopped: np.ndarray  # (N,) s: the time each sample reached
    status: np.ndarray  # (N,) int8, codes of registry.ADAPTIVE_STATUSES
    steps: np.ndarray  # (N,) accepted steps
    rejected: np.ndarray  # (N,) rejected steps
    rtol: np.ndarray  # (n,) the state's
    atol: np.ndarray  # (n,)


class SpectrumRun(NamedTuple):
    """What :func:`run_spectrum` returns (arrays per sample first)."""

    logs: np.ndarray  # (N, k): sums of ln |R_rr| since the transient, to where the sample reached
    finite: np.ndarray  # (N, T, k): the finite-time exponents at the output times, 1/s (NaN past a stop)
    times: np.ndarray  # (T,) s
    final: np.ndarray  # (N, m)
    stopped: np.ndarray  # (N,) s
    status: np.ndarray  # (N,) int8
    steps: np.ndarray  # (N,)
    rejected: np.ndarray  # (N,)
    rtol: np.ndarray  # (n,)
    atol: np.ndarray  # (n,)


def _driver(functions, p, n, k, unit, megno):
    """``(driver, its parameters)``: the CPU driver of the augmented state
    (:func:`tumble.kernels.variational.make_variational_rate`), made once per system, and ``p`` with the layout."""
    rate, tangents, key = functions
    if functions not in _DRIVERS:
        key = None if key is None else f"variational_{key}"  # apart from the system's own loops under its key
        _DRIVERS[functions] = adaptive_loop.make_dop853_driver(
            adaptive_loop.make_dop853_sample(variational.make_variational_rate(rate, tangents, key), key=key), key)
    return _DRIVERS[functions], np.concatenate([p, variational.layout(n, k, unit, megno)])


def _augmented(y, vectors, megno, tolerance, components):
    """``(augmented initial states (N, m), rtol (m,), atol (m,), rtol (n,), atol (n,))``: the vectors after each
    state, the tolerance checked and extended to the vectors and integrals with its smallest values."""
    rtol, atol = tolerances(*tolerance, components)
    n_samples, n = y.shape
    k = len(vectors)
    state = np.zeros((n_samples, variational.augmented_size(n, k, megno)))
    state[:, :n] = y
    state[:, n:n + k * n] = vectors.reshape(-1)
    rest = np.ones(state.shape[1] - n)
    return state, np.concatenate([rtol, rest * rtol.min()]), np.concatenate([atol, rest * atol.min()]), rtol, atol


def _segment(drive, state, p, t0, t1, marks, rtol, atol, first_step, max_steps, taken=None):
    # size: one segment's run, as the driver takes it
    """Run ``state`` (N, m, overwritten) from ``t0`` to ``t1`` with outputs at ``marks``: ``(outputs, status, counts,
    stopped)``, ``counts`` the steps accepted and rejected since the run began (``taken``, (N, 2): those of the
    segments before; ``max_steps`` bounds the total)."""
    n_samples, m = state.shape
    out = np.empty((n_samples, len(marks), m))
    status = np.zeros(n_samples, dtype=np.int8)
    counts = np.zeros((n_samples, 3), dtype=np.int64)
    if taken is not None:
        counts[:, :2] = taken
    stopped = np.zeros(n_samples)
    drive(state, p, np.zeros(0), t0, t1, first_step, rtol, atol, max_steps, marks, out, np.zeros(4),
          np.zeros((n_samples, 0)), np.zeros((n_samples, 0, m)), status, counts, stopped)
    return out, status, counts, stopped


def run_unit(functions, y, p, vectors, *, megno, t_end, times, tolerance, first_step, max_steps, components):
    # size: the checked run's pieces, handed down as the kernel takes them
    """MEGNO's or GALI's run: the samples ``y`` (N, n), each with the unit vectors ``vectors`` (k, n) (and, with
    ``megno``, MEGNO's integrals), from 0 to ``t_end`` with outputs at ``times`` (checked here; None: ``t_end``).
    ``functions``: the system's ``(rate, tangents, key)``; ``p`` the kernels' parameters; ``tolerance`` ``(rtol,
    atol)`` as the user gave them (checked here against ``components``). Returns :class:`VariationalRun`."""
    marks = output_times(times, t_end)
    state, rtol, atol, rtol_state, atol_state = _augmented(y, vectors, megno, tolerance, components)
    drive, p = _driver(functions, p, y.shape[1], len(vectors), True, megno)
    out, status, counts, stopped = _segment(drive, state, p, 0.0, t_end, marks, rtol, atol, first_step, max_steps)
    return VariationalRun(marks, out, state, stopped, status, counts[:, 0].copy(), counts[:, 1].copy(), rtol_state,
                          atol_state)


def _orthonormalised(vectors):
    """``(Q, ln |diag R|)`` of the rows of ``vectors`` (N, k, n): ``vectors = R^T Q`` row-wise, Q's rows orthonormal,
    signed so that ``diag R > 0`` (each row keeps its direction within the span of those before it)."""
    q, r = np.linalg.qr(np.swapaxes(vectors, 1, 2))
    diagonal = np.diagonal(r, axis1=1, axis2=2)
    with np.errstate(divide="ignore"):
        logs = np.log(np.abs(diagonal))
    return np.swapaxes(q * np.where(diagonal < 0, -1.0, 1.0)[:, None, :], 1, 2), logs


def run_spectrum(functions, y, p, vectors, *, t_end, renormalise, transient, times, tolerance, first_step, max_steps,
                 components):
    # size: the checked run's pieces, handed down as the kernel takes them
    """The spectrum's run: the samples ``y`` (N, n) with the orthonormal ``vectors`` (k, n), in segments that end at
    each multiple of ``renormalise``, at ``transient`` and at ``t_end``, where the vectors are orthonormalised and
    ``ln |R_rr|`` summed (from the transient on); the finite-time exponents at ``times`` (after the transient, checked
    by the caller). Returns :class:`SpectrumRun`."""
    state, rtol, atol, rtol_state, atol_state = _augmented(y, vectors, False, tolerance, components)
    n_samples, n = y.shape
    k = len(vectors)
    drive, p = _driver(functions, p, n, k, False, False)
    ends = np.arange(1, math.ceil(t_end / renormalise)) * renormalise
    ends = np.unique(np.concatenate([ends[ends < t_end], [transient] if transient > 0 else [], [t_end]]))
    marks = np.zeros(0) if times is None else np.asarray(times, dtype=float)
    logs = np.zeros((n_samples, k))
    finite = np.full((n_samples, len(marks), k), np.nan)
    status = np.zeros(n_samples, dtype=np.int8)
    counts = np.zeros((n_samples, 3), dtype=np.int64)
    stopped = np.zeros(n_samples)
    t0 = 0.0
    for t1 in ends:
        run = np.flatnonzero(status == registry.STATUS_OK)
        if not len(run):
            break
        inside = np.flatnonzero((marks > t0) & (marks <= t1))
        part = np.ascontiguousarray(state[run])
        out, code, steps, reached = _segment(drive, part, p, t0, t1, marks[inside], rtol, atol, first_step, max_steps,
                                             counts[run, :2])
        state[run], status[run], stopped[run] = part, code, reached
        counts[run] = steps
        if t0 >= transient and len(inside):
            _, grown = _orthonormalised(out[:, :, n:n + k * n].reshape(-1, k, n))
            so_far = (logs[run][:, None, :] + grown.reshape(len(run), len(inside), k)) / (
                marks[inside] - transient)[None, :, None]
            finite[np.ix_(run, inside)] = np.where((marks[inside][None, :] <= reached[:, None])[:, :, None], so_far,
                                                   np.nan)
        frame, grown = _orthonormalised(part[:, n:n + k * n].reshape(-1, k, n))
        state[run, n:n + k * n] = frame.reshape(len(run), -1)
        logs[run] = np.where(t0 >= transient, logs[run] + np.where(np.isfinite(grown), grown, 0.0), 0.0)
        t0 = t1
    return SpectrumRun(logs, finite, marks, state, stopped, status, counts[:, 0], counts[:, 1], rtol_state,
                       atol_state)


def _common(run, name):
    """The variables and attributes every indicator's result at a tolerance holds (and the warning for samples that
    stopped)."""
    warn_stops(run.status, len(run.status), name, stacklevel=4)
    variables = {**run_variables(run),
                 "sample": ("sample", np.arange(len(run.status)), {"long_name": "ensemble member"})}
    attrs = tolerance_attrs(run)
    return variables, attrs


def lyapunov_variables(run, k, transient, name):
    """``(variables, attributes)`` of :func:`tumble.lyapunov` at a tolerance (``run``: :class:`SpectrumRun`): exponent
    ``r`` is the sum of ``ln |R_rr|`` over ``T − transient``, ``T`` the time the sample reached (NaN where it stopped
    before the transient)."""
    covered = run.stopped - transient
    with np.errstate(invalid="ignore", divide="ignore"):
        exponent = np.where(covered[:, None] > 0, run.logs / covered[:, None], np.nan)
    variables, attrs = _common(run, name)
    variables["exponent"] = (("sample", "index"), -np.sort(-exponent, axis=1),
                             {"units": "1/s", "long_name": "Lyapunov exponent, sorted descending"})
    variables["index"] = ("index", np.arange(1, k + 1), {"long_name": "exponent index (1: the largest)"})
    if len(run.times):
        variables["finite_time"] = (("sample", "time", "index"), -np.sort(-run.finite, axis=2),
                                    {"units": "1/s", "long_name": "finite-time Lyapunov exponent since the transient, "
                                                                  "sorted descending"})
        variables["time"] = ("time", run.times, {"units": "s", "long_name": "time"})
    return variables, {**attrs, "transient": transient, "exponents": k}


def megno_variables(run, n, name):
    """``(variables, attributes)`` of :func:`tumble.megno` at a tolerance: ``<Y> = Yss(T) / T`` and twice the
    least-squares slope of ``<Y>`` against ``t`` over ``[0, T]``, ``12 (T ∫ t <Y> − T²/2 ∫ <Y>) / T⁴``, from the run's
    scalars (``T``: the time each sample reached)."""
    scalars = run.final[:, variational.augmented_size(n, 1, False):]
    T = run.stopped
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(T > 0, scalars[:, 1] / T, np.nan)
        slope = np.where(T > 0, 12.0 * (T * scalars[:, 2] - 0.5 * T ** 2 * scalars[:, 3]) / T ** 4, np.nan)
    variables, attrs = _common(run, name)
    variables.update({
        "megno": ("sample", mean, {"units": "1", "long_name": "mean MEGNO <Y>"}),
        "lyapunov": ("sample", 2.0 * slope, {"units": "1/s", "long_name": "maximal Lyapunov exponent from the slope "
                                                                        "of <Y> (2 x slope)"}),
        "time_run": ("sample", T.copy(), {"units": "s", "long_name": "time the sample ran"}),
    })
    return variables, {**attrs, "stop_above": math.inf}


def gali_variables(run, n, k, name):
    """``(variables, attributes)`` of :func:`tumble.gali` at a tolerance: at each output time the product of the
    singular values of the ``k`` unit vectors (normalised again: their length is kept only to the tolerance); NaN
    past a sample's stop."""
    vectors = run.states[:, :, n:n + k * n].reshape(len(run.status), len(run.times), k, n)
    vectors = vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)
    gali = np.prod(np.linalg.svd(vectors, compute_uv=False), axis=-1)
    stopped = (run.times[None, :] > run.stopped[:, None]) | (
        (run.status != registry.STATUS_OK)[:, None] & (run.times[None, :] >= run.stopped[:, None]))
    variables, attrs = _common(run, name)
    variables["gali"] = (("sample", "time"), np.where(stopped, np.nan, gali), {"units": "1", "long_name": f"GALI_{k}"})
    variables["time"] = ("time", run.times, {"units": "s", "long_name": "time"})
    return variables, {**attrs, "k": k}
