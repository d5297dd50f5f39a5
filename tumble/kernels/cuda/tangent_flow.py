"""The tangent flow of a system on a CUDA device: one thread per sample, running the CPU's own per-sample loop.

The loop is :func:`tumble.kernels.loops.tangent_loop.make_tangent_loop`'s (steps of the state, the tangent vectors and MEGNO,
Gram–Schmidt, the sums, the stores, the checks, the early stop), compiled for the device by numba-cuda; this module only
launches it: each thread copies its sample's state and tangent vectors into local arrays, runs the loop with local
scratch arrays, and copies them back. On numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernel body runs as
Python and calls the loop as the CPU's compiled function (:func:`tumble.kernels.cuda.launch.loop_array`).

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_tangent_loop`).
"""

import numpy as np
from numba import cuda, float64

from .launch import THREADS, launch_shape, loop_array
from ..jit import cuda_jit
from ..loops.tangent_loop import SCALARS, WORK_EXTRA

__all__ = ["THREADS", "make_kernel", "run"]


def make_kernel(run_sample, n_state, k, stages, n_parameters):
    """The device kernel that runs ``run_sample`` (:func:`tumble.kernels.loops.tangent_loop.make_tangent_loop`) for sample
    ``cuda.grid(1)``; ``n_state``, ``k`` (tangent vectors), ``stages`` and ``n_parameters`` fix the local arrays' sizes
    (:func:`tumble.kernels.loops.tangent_loop.scratch_shapes`)."""
    rows = stages + 2
    work_rows = n_state + WORK_EXTRA  # here, not in the kernel: a local array's shape must be constants to numba-cuda
    n_p = max(n_parameters, 1)

    @cuda_jit
    def drive(y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, logs, saved, megno,
              status, steps_taken):
        i = cuda.grid(1)
        if i >= y.shape[0]:
            return
        state = cuda.local.array(n_state, float64)
        tangent = cuda.local.array((k, n_state), float64)
        scratch = cuda.local.array((rows, n_state), float64)
        tangent_scratch = cuda.local.array((rows, k, n_state), float64)
        work = cuda.local.array((work_rows, n_state), float64)
        megno_scratch = cuda.local.array((rows, 2), float64)
        parameters = cuda.local.array(n_p, float64)
        for j in range(n_state):
            state[j] = y[i, j]
        for r in range(k):
            for j in range(n_state):
                tangent[r, j] = V[i, r, j]
        for j in range(p.shape[0]):
            parameters[j] = p[j]
        code, ran = run_sample(i, state, tangent, parameters[:p.shape[0]], t0, h, n_steps, every, transient,
                               save_every, stop_above, orthogonalise, loop_array(logs), loop_array(saved),
                               loop_array(megno), scratch, tangent_scratch, work, megno_scratch)
        for j in range(n_state):
            y[i, j] = state[j]
        for r in range(k):
            for j in range(n_state):
                V[i, r, j] = tangent[r, j]
        status[i] = code
        steps_taken[i] = ran

    return drive


def run(kernel, y, V, p, t0, h, n_steps, every, transient, save_every, stop_above, orthogonalise, saved):
    """Launch ``kernel`` (:func:`make_kernel`) over the samples of ``y`` (N, n) and their tangent vectors ``V`` (N, k,
    n), both overwritten with the final values; ``saved`` (N, n_saved, k) is copied in (its rows after a stop stay as
    given) and back. Returns ``(logs (N, k), saved, megno (N, SCALARS), status (N,) int8, steps_taken (N,) int64)``,
    as :func:`tumble.kernels.loops.tangent_loop.make_cpu_driver` writes them."""
    n = len(y)
    device_y = cuda.to_device(y)
    device_v = cuda.to_device(V)
    logs = cuda.to_device(np.zeros((n, V.shape[1])))
    device_saved = cuda.to_device(saved)
    megno = cuda.to_device(np.zeros((n, SCALARS)))
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    kernel[launch_shape(n)](device_y, device_v, cuda.to_device(p), float(t0), float(h), int(n_steps), int(every),
                            int(transient), int(save_every), float(stop_above), bool(orthogonalise), logs, device_saved, megno, status,
                            steps_taken)
    y[:] = device_y.copy_to_host()
    V[:] = device_v.copy_to_host()
    return (logs.copy_to_host(), device_saved.copy_to_host(), megno.copy_to_host(), status.copy_to_host(),
            steps_taken.copy_to_host())
