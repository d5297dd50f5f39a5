"""The phase fit on a CUDA device: a periodic scene's frequencies fitted where its stored states are (issue 28).

Written once: a thread fits its sample with the CPU's own per-sample fit,
:func:`tumble.kernels.fits.phase_fit_sample` (the radius and phase at each time, the unwrapping, the least-squares
slope, the median radius), which numba-cuda compiles for the device. The thread gathers its sample's scaled
transverse components and times into local arrays of the grid's length first (a kernel is made per length,
:func:`kernel`; on a GPU local memory is laid out so that the threads of a warp read it together), as the CPU's
``prange`` body gathers them into its scratch. Only three numbers per sample come back: the frequency, the median
radius and the fit's code; the stored states never leave the device.

The states are read in either layout the device kernels store: ``(n, T, k)`` (the closed form's grid,
:func:`tumble.kernels.cuda_exact.omega_rows`) or time-major ``(T, k, n)`` (a stepping kernel's trajectory,
:func:`tumble.kernels.cuda.run`), each component multiplied by ``sign`` (a splitting's relabelled frame flips the
sign of every component; ``±1``, exact), so that a thread's numbers are the CPU's inputs bit for bit.

Agreement with the CPU: on numba-cuda's simulator the fit runs as compiled CPU code, the same bits. On a GPU the
arithmetic is IEEE (tumble's CUDA options), but NVVM may fuse multiply-adds the CPU's fit does not (it is compiled
without contraction): a few ulps in the phases and so in the slope.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_fits`).
"""

import math

import numpy as np
from numba import cuda, float64

from .fits import phase_fit_sample
from .jit import cuda_jit

__all__ = ["THREADS", "kernel", "make_kernel", "phase_fit"]

#: Threads per block of a launch (one sample each).
THREADS = 128


def make_kernel(t_count, time_major):
    # size: the closure holds the one kernel below (see there)
    """The device kernel of the phase fit over ``t_count`` stored times, reading states ``(T, k, n)`` when
    ``time_major`` else ``(n, T, k)``; both are constants of the closure (the local arrays' length)."""

    @cuda_jit
    def fit(times, row, states, columns, weights, signs, floor, max_step, frequency, radius, code):
        """Fit sample ``cuda.grid(1)``: its times ``times[row[i]]`` (``row`` of one element: row 0 for every sample),
        its components ``columns[i]`` times ``signs[i]`` (``signs`` of one element: the same for every sample)
        weighted by ``sqrt(weights[i])``; the arguments are :func:`tumble.kernels.fits.phase_fit`'s."""
        i = cuda.grid(1)
        n = frequency.shape[0]
        if i >= n:
            return
        r = row[i] if row.shape[0] == n else 0
        sign = signs[i] if signs.shape[0] == n else signs[0]
        t = cuda.local.array(t_count, float64)
        x = cuda.local.array(t_count, float64)
        y = cuda.local.array(t_count, float64)
        gb = math.sqrt(weights[i, 0])
        gc = math.sqrt(weights[i, 1])
        b, c = columns[i, 0], columns[i, 1]
        for j in range(t_count):
            t[j] = times[r, j]
            if time_major:
                x[j] = gb * (sign * states[j, b, i])
                y[j] = gc * (sign * states[j, c, i])
            else:
                x[j] = gb * (sign * states[i, j, b])
                y[j] = gc * (sign * states[i, j, c])
        frequency[i], radius[i], code[i] = phase_fit_sample(t, x, y, floor[i], max_step)

    return fit


_KERNELS = {}


def kernel(t_count, time_major):
    """The device kernel of :func:`make_kernel`, made once per length and layout (compiled on its first launch)."""
    key = (int(t_count), bool(time_major))
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(*key)
    return _KERNELS[key]


def phase_fit(times, row, states, columns, weights, floor, max_step, *, time_major=False, sign=1.0):
    """:func:`tumble.kernels.fits.phase_fit` on the device, over states already there.

    Parameters
    ----------
    times : ndarray, shape (R, T)
        Increasing times, s: sample ``i`` was stored at ``times[row[i]]``.
    row : ndarray of int64, shape (n,) or (1,)
        ``(1,)``: every sample at ``times[0]``.
    states : device array (or ndarray), shape (n, T, k), or (T, k, n) with ``time_major``
        Stored states, rad/s (times ``sign``).
    columns : ndarray of int64, shape (n, 2)
        ``(b, c)``: the columns of the transverse components of each sample, in ``states``' own frame.
    weights : ndarray, shape (n, 2)
        ``(g_b, g_c)``.
    floor : ndarray, shape (n,)
        The no-signal radius of each sample.
    max_step : float
        Largest phase change between two stored times that unwraps safely, rad.
    sign : float or ndarray, shape (n,)
        ``±1``: the states' components times ``sign`` (each sample's) are the body frame's.

    Returns
    -------
    frequency, radius : ndarray, shape (n,)
    code : ndarray of int8, shape (n,)
        As :func:`tumble.kernels.fits.phase_fit` fills them.
    """
    n = len(floor)
    times = np.ascontiguousarray(times, dtype=float)
    frequency, radius = cuda.device_array(n), cuda.device_array(n)
    code = cuda.device_array(n, dtype=np.int8)
    if n:
        threads = THREADS if n >= THREADS else 32 * -(-n // 32)
        kernel(times.shape[1], time_major)[-(-n // threads), threads](
            cuda.to_device(times), cuda.to_device(np.ascontiguousarray(row, dtype=np.int64)), states,
            cuda.to_device(np.ascontiguousarray(columns, dtype=np.int64)),
            cuda.to_device(np.ascontiguousarray(weights, dtype=float)), cuda.to_device(np.atleast_1d(np.asarray(
                sign, dtype=float))),
            cuda.to_device(np.ascontiguousarray(floor, dtype=float)), float(max_step), frequency, radius, code)
    return frequency.copy_to_host(), radius.copy_to_host(), code.copy_to_host()
