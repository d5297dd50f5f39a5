"""A system given by its rate on a CUDA device: one thread per sample, running the CPU's own per-sample loop.

The loop is :func:`tumble.kernels.loops.sample_loop.make_sample_loop`'s (steps, stores, non-finite check, early stop, status),
compiled for the device by numba-cuda; this module only launches it: each thread copies its sample into a local
array, runs the loop on it with a local scratch array, and copies it back. On numba-cuda's simulator
(``NUMBA_ENABLE_CUDASIM=1``) the kernel body runs as Python and calls the loop as the CPU's compiled function
(:func:`tumble.kernels.cuda.launch.loop_array`).

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_sample_loop`).
"""

import numpy as np
from numba import cuda, float64

from .launch import THREADS, launch_shape, loop_array
from ..jit import cuda_jit

__all__ = ["THREADS", "make_kernel", "run"]



def make_kernel(run_sample, n_state, stages, n_parameters):
    """The device kernel that runs ``run_sample`` (:func:`tumble.kernels.loops.sample_loop.make_sample_loop`) for sample
    ``cuda.grid(1)``; ``n_state``, ``stages`` and ``n_parameters`` fix the local arrays' sizes (the thread's state,
    its scratch, its copy of the parameters)."""
    rows = stages + 2
    n_p = max(n_parameters, 1)

    @cuda_jit
    def drive(y, p, t0, h, n_steps, save_every, saved, status, steps_taken):
        i = cuda.grid(1)
        if i >= y.shape[0]:
            return
        state = cuda.local.array(n_state, float64)
        scratch = cuda.local.array((rows, n_state), float64)
        parameters = cuda.local.array(n_p, float64)
        for j in range(n_state):
            state[j] = y[i, j]
        for j in range(p.shape[0]):
            parameters[j] = p[j]
        code, ran = run_sample(i, state, parameters[:p.shape[0]], t0, h, n_steps, save_every, loop_array(saved),
                               scratch)
        for j in range(n_state):
            y[i, j] = state[j]
        status[i] = code
        steps_taken[i] = ran

    return drive


def run(kernel, y, p, t0, h, n_steps, save_every, n_saved):
    """Launch ``kernel`` (:func:`make_kernel`) over the samples of ``y`` (N, n), overwritten with the final states;
    returns ``(saved (N, n_saved, n), status (N,) int8, steps_taken (N,) int64)``."""
    n, n_state = y.shape
    device_y = cuda.to_device(y)
    saved = cuda.device_array((n, n_saved, n_state))
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    kernel[launch_shape(n)](device_y, cuda.to_device(p), float(t0), float(h), int(n_steps), int(save_every),
                                      saved, status, steps_taken)
    y[:] = device_y.copy_to_host()
    return saved.copy_to_host(), status.copy_to_host(), steps_taken.copy_to_host()
