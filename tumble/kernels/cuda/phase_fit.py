"""The phase fit on a CUDA device: a periodic scene's frequencies fitted where its stored states are (issue 28).

Written once: a thread runs the CPU's own per-sample gather and fit, :func:`tumble.kernels.fits.fit_sample` (its
scaled transverse components gathered into local arrays of the grid's length, a kernel per length, :func:`kernel`;
then the radius and phase at each time, the unwrapping, the least-squares slope, the median radius), which
numba-cuda compiles for the device. Only three numbers per sample come back: the frequency, the median
radius and the fit's code; the stored states never leave the device.

The states are read in either layout the device kernels store: ``(n, T, k)`` (the closed form's grid,
:func:`tumble.kernels.cuda.closed_form.omega_rows`) or time-major ``(T, k, n)`` (a stepping kernel's trajectory,
:func:`tumble.kernels.cuda.rigid_body.run`), each component multiplied by ``sign`` (a splitting's relabelled frame flips the
sign of every component; ``±1``, exact), so that a thread's numbers are the CPU's inputs bit for bit.

Agreement with the CPU: on numba-cuda's simulator the fit runs as compiled CPU code, the same bits. On a GPU the
arithmetic is IEEE (tumble's CUDA options), but NVVM may fuse multiply-adds the CPU's fit does not (it is compiled
without contraction): a few ulps in the phases and so in the slope.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_fits`).
"""

import numpy as np
from numba import cuda, float64

from .launch import THREADS, launch_shape, loop_array
from ..fits import fit_sample
from ..jit import cuda_jit

__all__ = ["THREADS", "kernel", "make_kernel", "phase_fit"]


def make_kernel(t_count, time_major):
    """The device kernel of the phase fit over ``t_count`` stored times, reading states ``(T, k, n)`` when
    ``time_major`` else ``(n, T, k)``; both are constants of the closure (the local arrays' length)."""

    @cuda_jit
    def fit(times, row, states, columns, weights, signs, floor, max_step, frequency, radius, code):
        """Fit sample ``cuda.grid(1)`` by the CPU's :func:`tumble.kernels.fits.fit_sample`, its scratch local; the
        arguments are :func:`tumble.kernels.fits.phase_fit`'s and ``signs`` (one per sample, or one for all)."""
        i = cuda.grid(1)
        if i >= frequency.shape[0]:
            return
        frequency[i], radius[i], code[i] = fit_sample(
            i, loop_array(times), loop_array(row), loop_array(states), loop_array(columns), loop_array(weights),
            loop_array(signs), loop_array(floor), max_step, time_major, cuda.local.array(t_count, float64),
            cuda.local.array(t_count, float64))

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
        kernel(times.shape[1], time_major)[launch_shape(n)](
            cuda.to_device(times), cuda.to_device(np.ascontiguousarray(row, dtype=np.int64)), states,
            cuda.to_device(np.ascontiguousarray(columns, dtype=np.int64)),
            cuda.to_device(np.ascontiguousarray(weights, dtype=float)), cuda.to_device(np.atleast_1d(np.asarray(
                sign, dtype=float))),
            cuda.to_device(np.ascontiguousarray(floor, dtype=float)), float(max_step), frequency, radius, code)
    return frequency.copy_to_host(), radius.copy_to_host(), code.copy_to_host()
