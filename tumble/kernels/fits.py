"""The inner loops of the estimators' fits (:func:`tumble.measure.estimators.oscillation_frequencies`,
:func:`tumble.measure.estimators.growth_rates`).

One pass over each sample's stored times: the scaled transverse components, their radius and phase, the
phase unwrapped as it goes (the rule of ``numpy.unwrap``: a jump beyond π is taken modulo 2π), and the
least-squares slope of phase against time about the mean time and the mean phase. The numpy formulation it
replaced made eight full-size temporaries per call (``arctan2``, ``unwrap``, ``hypot``, masks and sums), about
130 ns per sample and time; here it is one ``atan2`` and one square root per point, in parallel over samples,
and the median radius by selection in place.

Beside the fits, two gathers the estimators feed them from: the weighted transverse norms of stored states
(:func:`transverse_norms`) and the rows of a linear mode (:func:`modal_rows`).

Kernels take plain float64 arrays and scalars and write into arrays they are given.
"""

import math

import numpy as np

from .jit import jit
from .threads import in_parallel
from .trig import _max, _min, atan2

__all__ = ["FIT_NO_SIGNAL", "FIT_OK", "FIT_SHORT_WINDOW", "FIT_UNDERSAMPLED", "GROWTH_WINDOW_START", "growth_fit",
           "fit_sample", "growth_window_add", "growth_window_rate", "modal_rows", "phase_fit", "phase_fit_sample",
           "transverse_norms"]

# Outcomes, as tumble.measure.estimators numbers them (checked there).
FIT_OK = 0
FIT_SHORT_WINDOW = 1
FIT_NO_SIGNAL = 2
FIT_UNDERSAMPLED = 3


# Beyond these magnitudes x² + y² could overflow or lose precision to underflow: hypot there.
_SQUARE_MAX = 1e150
_SQUARE_MIN = 1e-150


@jit(inline=True)
def _radius(x, y):
    """``sqrt(x² + y²)``: one square root where the squares are safe (a scaled perturbation's usual range),
    ``math.hypot`` (a libm call, ten times the cost) outside it."""
    m = _max(abs(x), abs(y))
    if _SQUARE_MIN < m < _SQUARE_MAX:
        return math.sqrt(x * x + y * y)
    return math.hypot(x, y)


@jit
def _select_in_place(a, k):
    """The ``k``-th smallest element of ``a`` (no NaN), reordering ``a`` so that it sits at ``a[k]`` with nothing
    larger before it and nothing smaller after it.

    Quickselect (Hoare's FIND) with a median-of-three pivot and Lomuto's partition written without a branch
    (every element is swapped, the boundary moves by the comparison), which keeps the CPU's branch predictor out
    of the inner loop: about twice as fast as Hoare's partition on a phase fit's radii. A pivot that is the
    smallest value left gets a second pass that gathers its equal copies, so ties (a constant radius) cost
    two passes, not a quadratic number.
    """
    lo, hi = 0, a.shape[0] - 1
    while hi > lo:
        mid = (lo + hi) // 2
        x, y, z = a[lo], a[mid], a[hi]  # the median of the three goes to a[hi]
        if (x <= y) == (y <= z):
            a[mid], a[hi] = z, y
        elif (y <= x) == (x <= z):
            a[lo], a[hi] = z, x
        pivot = a[hi]
        store = lo
        for j in range(lo, hi):
            v = a[j]
            a[j] = a[store]
            a[store] = v
            store += 1 if v < pivot else 0
        if store == lo:  # nothing below the pivot: gather its copies, [lo, store) == pivot
            for j in range(lo, hi):
                v = a[j]
                a[j] = a[store]
                a[store] = v
                store += 1 if v <= pivot else 0
            if k <= store:
                a[hi] = a[store]
                a[store] = pivot
                return pivot
        a[hi] = a[store]
        a[store] = pivot
        if k == store:
            return pivot
        if k < store:
            hi = store - 1
        else:
            lo = store + 1
    return a[k]


@jit
def _median_in_place(a):
    """Median of ``a`` (no NaN), reordering ``a`` (:func:`_select_in_place`), no copy."""
    n = a.shape[0]
    k = (n - 1) // 2
    middle = _select_in_place(a, k)
    if n % 2:
        return middle
    upper = a[k + 1]
    for j in range(k + 2, n):  # the next order statistic: the smallest above position k
        upper = _min(upper, a[j])
    return 0.5 * middle + 0.5 * upper


@jit(contract=False)
def phase_fit_sample(t, x, y, floor, max_step):
    # size: the fit's passes over one sample (radius and phase, unwrapping, slope), the CPU's and the device's
    """The phase fit of one sample (:func:`phase_fit`), written once: the CPU's loop over samples and a device thread
    (:mod:`tumble.kernels.cuda.phase_fit`) call it.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Increasing times, s.
    x, y : ndarray, shape (T,)
        The sample's scaled transverse components ``(sqrt(g_b) w_b, sqrt(g_c) w_c)`` at each time, rad/s; used as
        scratch: ``x`` receives the radii (reordered by the median's selection), ``y`` the unwrapped phase.
    floor : float
        The radius at or below which (or not finite) the sample has no signal.
    max_step : float
        Largest phase change between two stored times that unwraps safely, rad.

    Returns
    -------
    frequency : float
        ``|slope|`` of the phase, rad/s (NaN unless the fit is ``FIT_OK``).
    radius : float
        The median radius, rad/s (NaN if a radius is NaN).
    code : int
        ``FIT_OK``, ``FIT_NO_SIGNAL`` or ``FIT_UNDERSAMPLED``.
    """
    t_count = x.shape[0]
    radii = x
    phases = y
    # 1. radius and raw phase at every time, in place (radii and phases hold x and y). Squares that could over- or
    #    underflow (or NaN) anywhere: every radius by hypot (:func:`_radius`); else straight-line code (the
    #    branch-free atan2, the square root) that packs the times of a sample into SIMD lanes on the CPU
    unsafe = 0
    for j in range(t_count):
        unsafe |= 0 if _SQUARE_MIN < _max(abs(x[j]), abs(y[j])) < _SQUARE_MAX else 1
    if unsafe:
        for j in range(t_count):
            xj = x[j]
            yj = y[j]
            radii[j] = _radius(xj, yj)
            phases[j] = atan2(yj, xj)
    else:
        for j in range(t_count):
            xj = x[j]
            yj = y[j]
            radii[j] = math.sqrt(xj * xj + yj * yj)
            phases[j] = atan2(yj, xj)
    quiet = 0
    any_nan = 0
    for j in range(t_count):
        radius = radii[j]
        quiet |= 0 if floor < radius < math.inf else 1
        any_nan |= 1 if radius != radius else 0
    # 2. unwrap in time order (numpy.unwrap's rule, bit for bit) and the means
    finite = True
    steps_ok = True
    correction = 0.0
    previous_raw = 0.0
    previous = 0.0
    t_mean = 0.0
    phase_mean = 0.0
    for j in range(t_count):
        raw = phases[j]
        if j > 0:
            jump = raw - previous_raw
            if not abs(jump) < math.pi:
                wrapped = (jump + math.pi) % (2.0 * math.pi) - math.pi
                if wrapped == -math.pi and jump > 0.0:
                    wrapped = math.pi
                correction += wrapped - jump
        previous_raw = raw
        phase = raw + correction
        if not math.isfinite(phase):
            finite = False
            phase = 0.0
        elif j > 0 and not abs(phase - previous) <= max_step:
            steps_ok = False
        previous = phase
        phases[j] = phase
        t_mean += t[j]
        phase_mean += phase
    t_mean /= t_count
    phase_mean /= t_count
    # 3. the least-squares slope about both means: a phase that does not move gives 0 to round-off of its own size,
    #    not of the size of the times. The times in units of a power of two near their span, so that the squares
    #    neither overflow nor underflow (a spin of 1e-200 rad/s is stored over 1e200 s, whose squares were infinite
    #    and its frequency 0): the same bits as unscaled within those ranges
    unit = math.ldexp(1.0, -math.frexp(t[t_count - 1] - t[0])[1]) if t_count >= 2 else 1.0
    sxy = 0.0
    sxx = 0.0
    for j in range(t_count):
        dt = (t[j] - t_mean) * unit
        sxy += dt * (phases[j] - phase_mean)
        sxx += dt * dt
    median = np.nan if any_nan else _median_in_place(radii)
    if not finite or quiet:
        code = FIT_NO_SIGNAL
    elif steps_ok:
        code = FIT_OK
    else:
        code = FIT_UNDERSAMPLED
    frequency = abs(sxy / sxx) * unit if code == FIT_OK and t_count >= 2 else np.nan
    return frequency, median, code


def phase_fit(times, row, states, columns, weights, floor, max_step, frequency, radius, code):
    """Angular frequency of each sample's transverse oscillation from its unwrapped phase.

    Parameters
    ----------
    times : ndarray, shape (R, T)
        Increasing times, s: sample ``i`` was stored at ``times[row[i]]``.
    row : ndarray of int64, shape (n,)
    states : ndarray, shape (n, T, k)
        Stored states of each sample at each time, rad/s.
    columns : ndarray of int64, shape (n, 2)
        ``(b, c)``: the columns of ``states`` holding the transverse components ``(w_b, w_c)`` of each sample.
    weights : ndarray, shape (n, 2)
        ``(g_b, g_c)``: the phase is that of ``(sqrt(g_b) w_b, sqrt(g_c) w_c)``.
    floor : ndarray, shape (n,)
        A sample whose radius ever falls to or below this (or is not finite) has no signal.
    max_step : float
        Largest phase change between two stored times that unwraps safely, rad.
    frequency, radius : ndarray, shape (n,)
        Receive ``|slope|`` of the phase, rad/s (NaN unless the fit is ``FIT_OK``) and the median radius.
    code : ndarray of int8, shape (n,)
        Receives ``FIT_OK``, ``FIT_NO_SIGNAL`` (no signal, or a non-finite phase) or ``FIT_UNDERSAMPLED`` (a
        phase step beyond ``max_step``).

    Notes
    -----
    A sample's gather and fit is :func:`fit_sample`, which the device runs too
    (:func:`tumble.kernels.cuda.phase_fit.phase_fit`): the two components are gathered first (a strided read, which AVX2
    cannot pack cheaply) into the scratch the fit works in.
    """
    in_parallel(phase_fit_share, states.shape[0], times, row, states, columns, weights, floor, max_step, frequency,
                radius, code)


@jit(contract=False)
def phase_fit_share(times, row, states, columns, weights, floor, max_step, frequency, radius, code, start, stop):
    """The samples ``start:stop`` of :func:`phase_fit` (one share of :func:`tumble.kernels.threads.in_parallel`): each
    sample's gather and fit in one pass, so that its scratch stays in cache."""
    t_count = states.shape[1]
    unsigned = np.ones(1)
    x, y = np.empty(t_count), np.empty(t_count)
    for i in range(start, stop):
        frequency[i], radius[i], code[i] = fit_sample(i, times, row, states, columns, weights, unsigned, floor,
                                                      max_step, False, x, y)


@jit(contract=False)
def fit_sample(i, times, row, states, columns, weights, signs, floor, max_step, time_major, x, y):
    # size: one sample's gather and fit, the CPU's and the device's (flat arrays, the scratch owned by the caller)
    """Sample ``i``'s phase fit, for the CPU (:func:`phase_fit_share`'s loop) and the device
    (:mod:`tumble.kernels.cuda.phase_fit`, one thread per sample): its transverse components gathered into ``x`` and ``y``
    (the scratch, (T,) each, owned by the caller), scaled by ``sqrt(g)`` and by the sign ``signs[i]`` (``signs`` of
    one element: the same for every sample), then :func:`phase_fit_sample` at its times ``times[row[i]]`` (``row`` of
    one element: row 0 for every sample). ``states`` is ``(n, T, k)``, or ``(T, k, n)`` with ``time_major``; the
    other arguments are :func:`phase_fit`'s. Returns ``(frequency, radius, code)``."""
    n = weights.shape[0]
    r = row[i] if row.shape[0] == n else 0
    sign = signs[i] if signs.shape[0] == n else signs[0]
    gb = math.sqrt(weights[i, 0])
    gc = math.sqrt(weights[i, 1])
    b, c = columns[i, 0], columns[i, 1]
    for j in range(x.shape[0]):
        if time_major:
            x[j] = gb * (sign * states[j, b, i])
            y[j] = gc * (sign * states[j, c, i])
        else:
            x[j] = gb * (sign * states[i, j, b])
            y[j] = gc * (sign * states[i, j, c])
    return phase_fit_sample(times[r], x, y, floor[i], max_step)


def transverse_norms(states, columns, weights, out):
    """Weighted transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` of each sample at each stored time, in one pass.

    The operations of numpy's ``np.sqrt(g_b * w_b**2 + g_c * w_c**2)`` in its order and without fused
    multiply-adds, so the same bits.

    Parameters
    ----------
    states : ndarray, shape (n, T, k)
        Stored states, rad/s.
    columns : ndarray of int64, shape (n, 2)
        Columns ``(b, c)`` of sample ``i``'s two transverse components.
    weights : ndarray, shape (n, 2)
        Weights ``(g_b, g_c)`` of sample ``i``.
    out : ndarray, shape (n, T)
        Receives the norms, rad/s.
    """
    in_parallel(transverse_norms_share, states.shape[0], states, columns, weights, out)


@jit(contract=False)
def transverse_norms_share(states, columns, weights, out, start, stop):
    """The samples ``start:stop`` of :func:`transverse_norms` (one share of :func:`tumble.kernels.threads.in_parallel`)."""
    for i in range(start, stop):
        b, c = columns[i, 0], columns[i, 1]
        gb, gc = weights[i, 0], weights[i, 1]
        for j in range(states.shape[1]):
            x = states[i, j, b]
            y = states[i, j, c]
            out[i, j] = math.sqrt(gb * (x * x) + gc * (y * y))


#: A growth window before its first probe (:func:`growth_window_add`): open (stop < 0), no norms, no sums.
GROWTH_WINDOW_START = (-1, np.nan, np.nan, 0.0, 0, np.nan)


@jit(inline=True)
def growth_window_add(j, value, saturation, window):
    """Feed probe ``j``'s scaled norm ``value`` to one sample's growth window, probe after probe (what the device
    kernel does in registers, and :func:`growth_fit` along its stored probes).

    ``window`` is ``(stop, older, old, total, count, first)``: ``stop`` the first probe whose norm is not finite and
    positive or exceeds ``saturation`` (-1 while none has), the last two norms of the window, the sum and count of
    the linear-prediction terms ``d_k = (s_{k+1} + s_{k-1} - 2 s_k) / (2 s_k)`` (``s = norm²``, ``k`` the window's
    interior points) and the first norm. Returns the updated window (unchanged once closed).
    """
    stop, older, old, total, count, first = window
    if stop >= 0:
        return window
    if not (math.isfinite(value) and value > 0.0) or value > saturation:
        return j, older, old, total, count, first
    if j == 0:
        first = value
    if j >= 2:
        s0 = older * older
        s1 = old * old
        s2 = value * value
        total += (s2 + s0 - 2.0 * s1) / (2.0 * s1)
        count += 1
    return stop, old, value, total, count, first


@jit(inline=True)
def growth_window_rate(window, p, h, min_points):
    """``(rate, points, first, last)`` of a growth window fed ``p`` probes ``h`` apart: the rate
    ``asinh(sqrt(d/2)) / h`` of the mean term ``d`` (1/s) and the window's length, or NaN and 0 when the window has
    fewer than ``min_points`` points or does not grow; its first and last norm, rad/s."""
    stop, _, last, total, count, first = window
    if stop < 0:
        stop = p
    mean = total / count if count else np.nan
    value = math.asinh(math.sqrt(mean / 2.0)) / h if mean > 0.0 else np.nan
    if stop >= min_points and mean > 0.0 and math.isfinite(value):
        return value, stop, first, last
    return np.nan, 0, first, last


def growth_fit(times, row, norms, saturation, min_points, rate, points, code):
    """Exponential growth rate of each sample's norm by linear prediction inside its linear regime.

    The window is ``[0, stop)``, ``stop`` the first time whose norm is not finite and positive or exceeds the
    sample's ``saturation``; each interior point ``k`` of the window (``k + 1 < stop``) gives
    ``d_k = (s_{k+1} + s_{k-1} - 2 s_k) / (2 s_k)`` with ``s = norm²``; the rate is ``asinh(sqrt(d/2)) / h``
    of their mean ``d`` (see :func:`tumble.measure.estimators.growth_rates`). The window is fed probe by probe
    (:func:`growth_window_add`, :func:`growth_window_rate`), as the device kernel feeds it without storing the probes.

    Parameters
    ----------
    times : ndarray, shape (R, P)
        Equally spaced, increasing probe times, s: sample ``i`` was probed at ``times[row[i]]``.
    row : ndarray of int64, shape (n,)
    norms : ndarray, shape (n, P)
        Scaled transverse norms, rad/s (NaN where a sample had stopped).
    saturation : ndarray, shape (n,)
        End of each sample's linear regime, rad/s.
    min_points : int
        Fewest points in a window.
    rate : ndarray, shape (n,)
        Receives the rate, 1/s (NaN unless ``FIT_OK``).
    points : ndarray of int64, shape (n,)
        Receives the window's length (0 unless ``FIT_OK``).
    code : ndarray of int8, shape (n,)
        Receives ``FIT_OK`` or ``FIT_SHORT_WINDOW``.
    """
    in_parallel(growth_fit_share, norms.shape[0], times, row, norms, saturation, min_points, rate, points, code)


@jit(contract=False)
def growth_fit_share(times, row, norms, saturation, min_points, rate, points, code, start, stop):
    """The samples ``start:stop`` of :func:`growth_fit` (one share of :func:`tumble.kernels.threads.in_parallel`)."""
    p = norms.shape[1]
    for i in range(start, stop):
        t = times[row[i]]
        h = (t[p - 1] - t[0]) / (p - 1)
        window = GROWTH_WINDOW_START
        for j in range(p):
            window = growth_window_add(j, norms[i, j], saturation[i], window)
            if window[0] >= 0:
                break
        value, stop, _, _ = growth_window_rate(window, p, h, min_points)
        rate[i] = value
        points[i] = stop
        code[i] = FIT_OK if stop > 0 else FIT_SHORT_WINDOW


@jit
def modal_rows(trajectory, columns, centre, rows):
    """The rows of a modal projection: ``rows[t, i, j] = trajectory[t, columns[j], i] − centre[j]`` (a complex
    array, imaginary parts 0), for :func:`tumble.measure.estimators.modal_amplitudes`.

    A gather and one subtraction per entry (exact IEEE arithmetic, the same bits as numpy's): the transpose of a
    time-major trajectory into rows of the measured columns, which numpy writes strided (ten times this loop).

    Parameters
    ----------
    trajectory : ndarray, shape (T, n_state, N)
        Stored states, time-major (the model kernels' layout).
    columns : ndarray of int64, shape (k,)
    centre : ndarray, shape (k,)
        The equilibrium's value of each column.
    rows : ndarray of complex128, shape (T, N, k)
        Receives the differences.
    """
    for t in range(trajectory.shape[0]):
        for j in range(columns.shape[0]):
            c = columns[j]
            x = centre[j]
            for i in range(trajectory.shape[2]):
                rows[t, i, j] = trajectory[t, c, i] - x
