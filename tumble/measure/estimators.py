"""Estimators: growth rates, oscillation frequencies, flip statistics, scene summaries and scan regressions.

Plain numpy in, plain numpy out (no xarray here; :mod:`tumble.measure.records` builds the datasets). The phase
fit's loop over samples and times is a numba kernel (:func:`tumble.kernels.fits.phase_fit`): in numpy it made
eight full-size temporaries and cost about 130 ns per sample and time, ten times the kernel.

The coordinates every estimator works in come from an exact invariant. For a torque-free spin about
principal axis ``a``, ``2 T I_a - |L|² = Σ_i I_i (I_a - I_i) w_i²`` is conserved, and its ``i = a`` term
vanishes: with ``k_i = I_i (I_a - I_i)`` the transverse components ``(w_b, w_c)`` stay on the conic
``k_b w_b² + k_c w_c² = const`` — an ellipse when ``k_b k_c > 0`` (``a`` the largest or smallest axis) and a
hyperbola when ``k_b k_c < 0`` (``a`` the intermediate axis). In the scaled coordinates
``(x, y) = (sqrt(g_b) w_b, sqrt(g_c) w_c)``, ``g_b = sqrt|k_b / k_c|``, ``g_c = sqrt|k_c / k_b|`` (so
``g_b g_c = 1`` and norms keep the units of ``w``), the linearised motion (Landau & Lifshitz, Mechanics §37)
is a uniform rotation at ``ω = W sqrt(q)`` or a uniform hyperbolic rotation at ``λ = W sqrt(-q)``:

* periodic: ``x + i y ∝ exp(± i ω t)`` — the phase ``atan2(y, x)`` advances uniformly whatever the
  ellipticity of the plain components, and by exactly ``2π`` per period of the exact motion;
* exponential: ``x ± y ∝ exp(± λ t)``, so ``x² + y² = 2 (A² e^{2λt} + B² e^{-2λt})`` with no cross term
  and no constant: a sum of two exponentials, whose rate linear prediction recovers exactly
  (:func:`growth_rates`), however much of the decaying mode a sample starts with.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from .. import registry
from ..kernels import fits
from ..physics import exact
from ..physics.bodies import moment_unit

__all__ = [
    "FIT_NAMES",
    "FIT_OK",
    "FIT_SHORT_WINDOW",
    "FIT_NO_SIGNAL",
    "FIT_UNDERSAMPLED",
    "Regression",
    "Summary",
    "closed_form_frequencies_on_device",
    "flip_statistics",
    "growth_rates",
    "growth_window_fit",
    "invariant_weights",
    "medians",
    "median_interval_rank",
    "modal_amplitudes",
    "oscillation_frequencies",
    "phase_fit_arguments",
    "phase_window",
    "regression",
    "summarize",
    "transverse_norms",
]

#: Per-sample outcome of a fit (the engine's statuses, non-finite and drift, come before these).
FIT_OK = fits.FIT_OK
FIT_SHORT_WINDOW = fits.FIT_SHORT_WINDOW  # fewer than MIN_POINTS before saturation, or no growth
FIT_NO_SIGNAL = fits.FIT_NO_SIGNAL  # the transverse perturbation is at round-off level: its phase means nothing
FIT_UNDERSAMPLED = fits.FIT_UNDERSAMPLED  # the phase moved by more than MAX_PHASE_STEP between two samples: unwrapping is unsafe
FIT_NAMES = registry.FIT_NAMES

#: Fewest points in a growth fit window.
MIN_POINTS = 8
#: Largest phase change between two stored times that still unwraps safely, rad.
MAX_PHASE_STEP = 0.5 * np.pi
#: A transverse radius below this fraction of |w| is round-off, not signal.
NO_SIGNAL = 1e-11


def invariant_weights(moments, axis):
    """Weights ``g`` of the scaled transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` about ``axis``.

    ``g_b = sqrt|k_b / k_c|``, ``g_c = sqrt|k_c / k_b|``, ``k_i = I_i (I_a - I_i)`` (see the module
    docstring); ``g_a = 0``. Where ``k_b`` or ``k_c`` vanishes (a symmetric top spun about an axis of its
    degenerate pair, a sphere) the conic degenerates and the weights are 1.

    Parameters
    ----------
    moments : array_like, shape (3,)
        Principal moments, kg m².
    axis : {1, 2, 3}
        Spin axis, 1-based.

    Returns
    -------
    ndarray, shape (3,)
    """
    moments = np.asarray(moments, dtype=float)
    moments = moments / moment_unit(moments)  # no under- or overflow anywhere in the float range, same bits
    a = int(axis) - 1
    b, c = (a + 1) % 3, (a + 2) % 3
    k = moments * (moments[a] - moments)
    weights = np.ones(3)
    weights[a] = 0.0
    scale = np.abs(moments).max() ** 2
    if min(abs(k[b]), abs(k[c])) > 1e-12 * scale:
        ratio = np.sqrt(abs(k[b] / k[c]))
        weights[b], weights[c] = ratio, 1.0 / ratio
    return weights


class GrowthFit(NamedTuple):
    """Per-sample exponential fits (arrays of shape (N,))."""

    rate: np.ndarray  # 1/s, NaN where code != FIT_OK
    t_start: np.ndarray  # s, first time inside the window
    t_stop: np.ndarray  # s, last time inside the window
    norm_start: np.ndarray  # rad/s, norm at t_start
    norm_stop: np.ndarray  # rad/s, norm at t_stop
    points: np.ndarray  # points in the window
    code: np.ndarray  # int8, FIT_OK or FIT_SHORT_WINDOW


def growth_rates(times, norms, saturation, *, row=None):
    """Exponential growth rate of each sample's scaled transverse norm, inside its linear regime.

    In the scaled coordinates (module docstring) the linearised motion gives
    ``s(t) = r(t)² = 2 (A² e^{2λt} + B² e^{-2λt})`` exactly — a sum of two exponentials with no constant term —
    so on equally spaced times ``s(t + h) + s(t - h) = 2 cosh(2λh) s(t)`` holds whatever the mix of growing
    and decaying modes (linear prediction; Prony's method). Each interior point of the window gives
    ``d_k = (s_{k+1} + s_{k-1} - 2 s_k) / (2 s_k) = cosh(2λh) - 1``; their mean ``d`` gives
    ``λ = asinh(sqrt(d/2)) / h`` (the same as ``arccosh(1 + d) / 2h``, without its cancellation).

    The window runs from the first time (the initial amplitude) to the last time before the norm first exceeds
    ``saturation`` (the end of the linear regime; the nonlinear correction to ``d`` is of order
    ``(r/|w|)²``). No time needs to be skipped for the decaying mode to die out: the estimator is exact in
    linear theory for any mix of the two (a sample exactly on the stable direction, which only decays, gives
    the same ``λ``: the rate of its mode). A window with fewer than :data:`MIN_POINTS` points, or in which the
    norm is not exponential at all (``d <= 0``), gives NaN and ``FIT_SHORT_WINDOW``.

    Parameters
    ----------
    times : ndarray, shape (P,) or (N, P)
        Equally spaced, increasing probe times, s (one row per sample: the samples of several scenes).
    norms : ndarray, shape (N, P)
        Scaled transverse norm (:func:`invariant_weights`), rad/s; NaN where a sample had stopped.
    saturation : float or ndarray (N,)
        End of the linear regime, rad/s (scaled norm).
    row : ndarray of int, shape (N,), optional
        With it, ``times`` is one row per time grid (R, P) and sample ``i`` was probed at ``times[row[i]]``.

    Returns
    -------
    GrowthFit

    Raises
    ------
    ValueError
        Times that are not equally spaced.
    """
    norms = np.ascontiguousarray(norms, dtype=float)
    n, p = norms.shape
    if p < 3:
        raise ValueError(f"growth_rates needs at least 3 times, got {p}")
    times = np.ascontiguousarray(np.asarray(times, dtype=float).reshape(-1, p))
    if row is None:
        row = np.zeros(n, dtype=np.int64) if len(times) == 1 else np.arange(n, dtype=np.int64)
    h = (times[:, -1] - times[:, 0]) / (p - 1)
    if not np.allclose(np.diff(times, axis=1), h[:, None], rtol=1e-9, atol=0.0):
        raise ValueError("growth_rates needs equally spaced times (linear prediction)")
    saturation = np.ascontiguousarray(np.broadcast_to(np.asarray(saturation, dtype=float), (n,)))
    rate, points, code = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int8)
    row = np.ascontiguousarray(row, dtype=np.int64)
    fits.growth_fit(times, row, norms, saturation, MIN_POINTS, rate, points, code)
    last = norms[np.arange(n), np.clip(points - 1, 0, p - 1)]
    return growth_window_fit(times[row], rate, points, norms[:, 0], last)


def growth_window_fit(times, rate, points, first, last):
    """The :class:`GrowthFit` of per-sample growth windows fitted already (the engine's ``growth_window``, which the
    device fits in its kernel): ``rate`` (1/s, NaN where the fit failed), ``points`` (0 there), the window's
    ``first`` and ``last`` norm (rad/s), on probe ``times`` (P,) or one row per sample (N, P), s."""
    good = points > 0
    times = np.broadcast_to(times, (len(rate), np.shape(times)[-1]))
    nan = np.full(len(rate), np.nan)
    stop = times[np.arange(len(rate)), np.clip(points - 1, 0, times.shape[1] - 1)]
    return GrowthFit(rate, np.where(good, times[:, 0], nan), np.where(good, stop, nan), np.where(good, first, nan),
                     np.where(good, last, nan), points, np.where(good, FIT_OK, FIT_SHORT_WINDOW).astype(np.int8))


#: Rows (samples x times) a modal projection gathers at a time: a block of rows stays in the CPU's cache between the
#: gather and the product (the whole trajectory's rows, 6 MB a scene, made both run from memory).
MODAL_BLOCK_ROWS = 2048


def transverse_norms(states, columns, weights):
    """Weighted transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` (rad/s), shape (N, T), of stored states (N, T, k):
    sample ``i``'s components ``columns[i]`` (N, 2) with weights ``weights[i]`` (N, 2). One pass in a kernel
    (:func:`tumble.kernels.fits.transverse_norms`), the same bits as the numpy expression."""
    states = np.ascontiguousarray(states, dtype=float)
    out = np.empty(states.shape[:2])
    fits.transverse_norms(states, np.ascontiguousarray(columns, dtype=np.int64),
                          np.ascontiguousarray(weights, dtype=float), out)
    return out


def modal_amplitudes(trajectory, columns, centre, left):
    """A linear mode's complex amplitude ``z = left · (y[columns] − centre)`` at every stored state of a
    time-major trajectory.

    Parameters
    ----------
    trajectory : ndarray, shape (T, n_state, N)
        States of N samples at T times, time-major (:func:`tumble.engine.model_ensemble.run_model_ensemble`'s
        ``time_major``).
    columns : array_like of int, shape (k,)
    centre : float or array_like, shape (k,)
        The equilibrium's value of each column.
    left : array_like of complex, shape (k,)
        The mode's left eigenvector (scaled as the caller's units ask).

    Returns
    -------
    ndarray of complex, shape (N, T)
        A transposed view of a (T, N) array. The same bits as ``(states[..., columns] − centre) @ left`` of the
        (N, T, n_state) trajectory: the rows are gathered by :func:`tumble.kernels.fits.modal_rows` (exact), a few
        times at a time (:data:`MODAL_BLOCK_ROWS`), and numpy's ``matmul`` takes one stack of N rows per time (each
        row's dot product is BLAS's, as before; stacks of N rows stay below the size at which BLAS spreads one
        product over threads, which on a loaded machine cost ten times the product).
    """
    trajectory = np.ascontiguousarray(trajectory, dtype=float)
    columns = np.ascontiguousarray(columns, dtype=np.int64)
    centre = np.ascontiguousarray(np.broadcast_to(np.asarray(centre, dtype=float), columns.shape))
    left = np.asarray(left, dtype=complex)
    t_count, _, n = trajectory.shape
    z = np.empty((t_count, n), dtype=complex)
    step = max(1, MODAL_BLOCK_ROWS // max(n, 1))
    rows = np.empty((min(step, t_count), n, len(columns)), dtype=complex)
    for lo in range(0, t_count, step):
        hi = min(lo + step, t_count)
        block = rows[:hi - lo]
        fits.modal_rows(trajectory[lo:hi], columns, centre, block)
        np.matmul(block, left, out=z[lo:hi])
    return z.T


class PhaseFit(NamedTuple):
    """Per-sample oscillation fits (arrays of shape (N,))."""

    frequency: np.ndarray  # rad/s, >= 0, NaN where code != FIT_OK
    radius: np.ndarray  # rad/s, median scaled transverse radius (the signal)
    code: np.ndarray  # int8


def oscillation_frequencies(times, transverse, weights, spin, *, columns=None, row=None):
    """Angular frequency of each sample's transverse oscillation, from the phase of its scaled components.

    The phase ``θ = atan2(sqrt(g_c) w_c, sqrt(g_b) w_b)`` advances uniformly in linear theory and by exactly
    ``2π`` per period of the exact motion, whatever the ellipticity of the plain components (module
    docstring). It is unwrapped along time and the frequency is ``|slope|`` of its least-squares line.

    Samples whose scaled radius ever falls below ``NO_SIGNAL · |spin|`` give ``FIT_NO_SIGNAL`` (the phase of
    round-off is noise), those whose unwrapped phase steps by more than :data:`MAX_PHASE_STEP` between two
    stored times ``FIT_UNDERSAMPLED``; both get NaN and are left out of scene statistics. The check catches
    true steps between ``MAX_PHASE_STEP`` and ``π``; a step beyond ``π`` aliases and no check on the samples
    alone can see it — the caller stores enough times per period (:mod:`tumble.measure.planning` stores 32).

    Parameters
    ----------
    times : ndarray, shape (T,) or (N, T)
        Increasing times, s (one row per sample: the samples of several scenes).
    transverse : ndarray, shape (N, T, 2)
        ``(w_b, w_c)`` of each sample at each time, rad/s.
    weights : ndarray, shape (2,) or (N, 2)
        ``(g_b, g_c)`` from :func:`invariant_weights`.
    spin : float or ndarray (N,)
        The unperturbed spin, rad/s (scale for the no-signal threshold).

    columns : ndarray of int, shape (N, 2), optional
        With it, ``transverse`` is any stored state (N, T, k) and ``(w_b, w_c)`` are its columns
        ``columns[i]`` for sample ``i`` (the samples of several scenes, spun about different axes).
    row : ndarray of int, shape (N,), optional
        With it, ``times`` is one row per time grid (R, T) and sample ``i`` was stored at ``times[row[i]]``.

    Returns
    -------
    PhaseFit
    """
    transverse = np.ascontiguousarray(transverse, dtype=float)
    n, t = transverse.shape[:2]
    times, row, columns, weights, floor = phase_fit_arguments(n, t, times, weights, spin, columns=columns, row=row)
    frequency, radius, code = np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)
    fits.phase_fit(times, row, transverse, columns, weights, floor, MAX_PHASE_STEP, frequency, radius, code)
    return PhaseFit(frequency, radius, code)


def closed_form_frequencies_on_device(bodies, w0, times, weights, spin, *, columns, row):
    """:func:`oscillation_frequencies` of the closed-form motion of spins ``w0`` (N, 3), sample ``i`` of the body
    ``bodies[row[i]]`` (R, 3) at ``times[row[i]]`` (R, T), evaluated and fitted on the CUDA device
    (:func:`tumble.physics.exact.phase_fit_rows_on_device`): the states stay on the device, where the CPU's
    per-sample fit runs on them, and only the frequency, the radius and the code of each sample come back.
    ``weights``, ``spin`` and ``columns`` as :func:`oscillation_frequencies` takes them (``columns`` in the body
    frame). Returns a :class:`PhaseFit` equal to the CPU's where the device's evaluation is (a few ulps of ``|w|``,
    :func:`tumble.physics.exact.omega_on_device`)."""
    n = len(w0)
    times, row, columns, weights, floor = phase_fit_arguments(n, np.shape(times)[-1], times, weights, spin,
                                                              columns=columns, row=row)
    return PhaseFit(*exact.phase_fit_rows_on_device(np.ascontiguousarray(bodies, dtype=float),
                                                    np.ascontiguousarray(w0, dtype=float), times, row, columns,
                                                    weights, floor, MAX_PHASE_STEP))


def phase_window(moments, axis, kind, plane, spin):
    """The engine's ``phase_window`` (:func:`tumble.engine.ensemble.run_ensemble`) of a scene spun at ``spin``
    (rad/s) about ``axis`` (1-based) of a body of ``moments``: the plane of the fit (``plane``, 0-based, or the two
    axes after ``axis``), its weights (:func:`invariant_weights` for a ``"periodic"`` scene, else 1), the no-signal
    radius and :data:`MAX_PHASE_STEP`: the fit :func:`oscillation_frequencies` makes of the scene's trajectory.
    None for an ``"exponential"`` scene (its growth is fitted instead)."""
    if kind == "exponential":
        return None
    a = int(axis) - 1
    b, c = plane or ((a + 1) % 3, (a + 2) % 3)
    weights = invariant_weights(moments, axis)[[b, c]] if kind == "periodic" else np.ones(2)
    return (b, c), (float(weights[0]), float(weights[1])), NO_SIGNAL * abs(float(spin)), MAX_PHASE_STEP


def phase_fit_arguments(n, t, times, weights, spin, *, columns=None, row=None):
    """:func:`oscillation_frequencies`' arguments for ``n`` samples stored at ``t`` times as the phase fit's kernels
    take them (:func:`tumble.kernels.fits.phase_fit`, and its device counterpart): ``(times (R, t), row (n,),
    columns (n, 2), weights (n, 2), floor (n,))``, contiguous; ``floor`` is ``NO_SIGNAL · |spin|``."""
    times = np.ascontiguousarray(np.asarray(times, dtype=float).reshape(-1, t))
    if row is None:
        row = np.zeros(n, dtype=np.int64) if len(times) == 1 else np.arange(n, dtype=np.int64)
    if columns is None:
        columns = np.tile(np.arange(2, dtype=np.int64), (n, 1))
    weights = np.ascontiguousarray(np.broadcast_to(np.asarray(weights, dtype=float), (n, 2)))
    floor = NO_SIGNAL * np.abs(np.broadcast_to(np.asarray(spin, dtype=float), (n,)))
    return (times, np.ascontiguousarray(row, dtype=np.int64), np.ascontiguousarray(columns, dtype=np.int64), weights,
            np.ascontiguousarray(floor))


class FlipStats(NamedTuple):
    """Per-sample flip timing (arrays of shape (N,))."""

    first: np.ndarray  # s, time of the first flip (NaN: none within the horizon)
    spacing: np.ndarray  # s, mean time between the recorded flips (NaN: fewer than two)


def flip_statistics(flips):
    """First flip time and mean spacing between successive flips of each sample.

    Parameters
    ----------
    flips : ndarray, shape (N, F)
        Flip times, s, NaN where fewer flips happened (the engine's ``flips``).

    Returns
    -------
    FlipStats
    """
    flips = np.asarray(flips, dtype=float)
    if flips.shape[1] == 0:
        return FlipStats(np.full(len(flips), np.nan), np.full(len(flips), np.nan))
    count = np.isfinite(flips).sum(axis=1)
    last = flips[np.arange(len(flips)), np.clip(count - 1, 0, None)]
    with np.errstate(invalid="ignore", divide="ignore"):
        spacing = np.where(count >= 2, (last - flips[:, 0]) / (count - 1), np.nan)
    return FlipStats(flips[:, 0].copy(), spacing)


class Summary(NamedTuple):
    """A statistic over the valid samples of each row (arrays shaped like ``values.shape[:-1]``)."""

    median: np.ndarray
    spread: np.ndarray  # half the interquartile range
    ci_low: np.ndarray  # distribution-free confidence interval of the median (order statistics)
    ci_high: np.ndarray
    used: np.ndarray  # int64: samples that entered
    excluded: np.ndarray  # int64: samples left out (bad status or failed fit)


@functools.lru_cache(maxsize=1024)
def median_interval_rank(n, confidence=0.95):
    """1-based rank ``l`` of the lower end of the distribution-free interval ``[x_(l), x_(n+1-l)]`` of the
    median of ``n`` values.

    For a continuous distribution the number of values below the true median is Binomial(n, 1/2), so the
    interval covers it with probability ``1 - 2 P(B <= l - 1)``; ``l`` is the largest rank for which that is at
    least ``confidence`` (Conover, *Practical Nonparametric Statistics*, 3rd ed., §3.2; Hahn & Meeker,
    *Statistical Intervals*, §5.2). Below ``n = 6`` (at 95 %) no rank reaches it and ``l = 1``: the range of
    the values, whose coverage ``1 - 2^(1-n)`` is then less than asked.
    """
    # P(B <= k), k = 0 .. n-1, in logarithms (no underflow for large n): log C(n, k) by the recurrence
    # C(n, k+1) = C(n, k) (n - k) / (k + 1), summed. The same ranks as scipy.special.bdtr (tests/test_analysis.py:
    # every n up to 5000 and powers of two up to 2**20, at 90, 95 and 99 %), without importing scipy.special (0.1-0.2 s
    # of every `tumble run`; scipy.stats.binom would cost 0.8 s).
    k = np.arange(n - 1, dtype=float)
    log_pmf = np.concatenate(([0.0], np.cumsum(np.log((n - k) / (k + 1.0))))) - n * math.log(2.0)
    log_tail = np.logaddexp.accumulate(log_pmf)
    return max(1, int(np.count_nonzero(log_tail <= math.log(0.5 * (1.0 - confidence)))))


def _lerp(a, b, t):
    """numpy's linear interpolation for percentiles (``numpy.lib._function_base_impl._lerp``), elementwise."""
    diff = b - a
    return np.where(t >= 0.5, b - diff * (1.0 - t), a + diff * t)


def _sorted_rows(values):
    """``(rows sorted with the non-finite values as NaN at the end, valid count per row, leading shape)``."""
    values = np.asarray(values, dtype=float)
    if values.ndim == 0:
        values = values.reshape(1)
    shape = values.shape[:-1]
    rows = values.reshape(int(np.prod(shape)), values.shape[-1])
    finite = np.isfinite(rows)
    return np.sort(np.where(finite, rows, np.nan), axis=1), finite.sum(axis=1), shape


def _order_statistic(ordered, used):
    """``at(index)``: each row's value at its (clipped) 0-based rank among its valid values."""
    rank = np.arange(len(ordered))
    top = np.maximum(used - 1, 0)

    def at(index):
        return ordered[rank, np.clip(index, 0, top)] if ordered.shape[1] else np.full(len(ordered), np.nan)

    return at


def _middle(at, used):
    """The median from the order statistics ``at`` of rows of ``used`` valid values (numpy's: the mean of the two
    middle values for an even count)."""
    return 0.5 * at((np.maximum(used - 1, 0)) // 2) + 0.5 * at(used // 2)


def medians(values):
    """Median over the finite values of each row (NaN for a row with none): :func:`summarize`'s median, without
    its spread and interval.

    Parameters
    ----------
    values : array_like, shape (..., N)

    Returns
    -------
    ndarray, shape (...)
    """
    ordered, used, shape = _sorted_rows(values)
    return np.where(used == 0, np.nan, _middle(_order_statistic(ordered, used), used)).reshape(shape)


def summarize(values, *, confidence=0.95):
    """Median, spread and a confidence interval of the median over the finite values of each row.

    Non-finite entries (bad samples, failed fits) are excluded and counted. The spread is half the
    interquartile range (numpy's linear percentiles). The interval is the distribution-free order-statistic
    interval of the median (:func:`median_interval_rank`): exact coverage of at least ``confidence`` for any
    continuous distribution, no resampling, so it costs one sort whatever the number of rows — a scan's scenes
    are summarised in one call. A row with no valid value gives NaN statistics and ``used = 0``, which the
    caller reports.

    Parameters
    ----------
    values : array_like, shape (..., N)
        Rows of values (a 1-d array is one row).
    confidence : float
        In (0, 1).

    Returns
    -------
    Summary
        Fields shaped ``values.shape[:-1]`` (0-d arrays for one row).

    Examples
    --------
    >>> s = summarize([3.0, 1.0, 2.0, float("nan")])
    >>> float(s.median), int(s.used), int(s.excluded)
    (2.0, 3, 1)
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")
    ordered, used, shape = _sorted_rows(values)
    at = _order_statistic(ordered, used)
    top = np.maximum(used - 1, 0)

    def percentile(q):
        position = q * top
        low = np.floor(position).astype(np.int64)
        return _lerp(at(low), at(np.minimum(low + 1, top)), position - low)

    median = _middle(at, used)
    spread = 0.5 * (percentile(0.75) - percentile(0.25))
    counts, which = np.unique(np.maximum(used, 1), return_inverse=True)
    lower = np.array([median_interval_rank(int(n), confidence) for n in counts], dtype=np.int64)[which] - 1
    ci_low, ci_high = at(lower), at(used - 1 - lower)
    none = used == 0
    fields = [np.where(none, np.nan, x) for x in (median, spread, ci_low, ci_high)]
    fields += [used.astype(np.int64), (ordered.shape[1] - used).astype(np.int64)]
    return Summary(*(field.reshape(shape) for field in fields))


class Regression(NamedTuple):
    """Least-squares line ``y = slope x + intercept`` over a scan, and its worst point."""

    slope: float
    intercept: float
    r2: float
    worst: int  # flat index of the point with the largest relative error |y - x| / |x|
    worst_error: float
    points: int


def regression(x, y):
    """Regress measured ``y`` on ``x`` (theory, or ``ln(1/ε)`` for the flip-time law) over a scan.

    Points where either value is not finite are left out. ``worst`` is the point with the largest relative
    deviation ``|y - x| / |x|`` (meaningful when ``x`` is the theory for ``y``).

    Parameters
    ----------
    x, y : array_like, same shape

    Returns
    -------
    Regression
        NaN fields (and ``worst = -1``) when fewer than two points are usable.
    """
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.shape != y.shape:
        raise ValueError(f"x and y must have the same size, got {x.size} and {y.size}")
    use = np.isfinite(x) & np.isfinite(y)
    if use.sum() < 2 or np.ptp(x[use]) == 0:
        return Regression(np.nan, np.nan, np.nan, -1, np.nan, int(use.sum()))
    slope, intercept = np.polyfit(x[use], y[use], 1)
    residual = y[use] - (slope * x[use] + intercept)
    total = np.sum((y[use] - y[use].mean()) ** 2)
    r2 = 1.0 - np.sum(residual**2) / total if total > 0 else 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(use, np.abs(y - x) / np.abs(x), -np.inf)
    relative = np.where(use & (y == x), 0.0, relative)  # 0/0: a point that matches exactly is no error
    worst = int(np.argmax(relative))
    return Regression(float(slope), float(intercept), float(r2), worst, float(relative[worst]), int(use.sum()))
