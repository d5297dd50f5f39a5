"""An error-controlled run on a CUDA device: one thread per sample, running the CPU's own per-sample DOP853 loop.

The loop is :func:`tumble.kernels.loops.adaptive_loop.make_dop853_sample`'s (steps, error control, dense output,
crossings, stops), compiled for the device by numba-cuda; each thread copies its sample and the parameters into local
arrays, runs the loop with a local scratch, and copies the state back. On numba-cuda's simulator the kernel's body
runs as Python and calls the loop as the CPU's compiled function (:func:`tumble.kernels.cuda.launch.loop_array`).

This module imports ``numba.cuda``; it is imported only when an error-controlled run asks for ``device="cuda"``
(:func:`tumble.kernels.device_adaptive_loop`).
"""

import numpy as np
from numba import cuda, float64

from ..jit import cuda_jit
from ..loops.adaptive_loop import SCRATCH_ROWS
from .launch import launch_shape, loop_array

__all__ = ["make_kernel", "run"]


def make_kernel(run_sample, n_state, n_parameters):
    """The device kernel that runs ``run_sample`` for sample ``cuda.grid(1)``; ``n_state`` and ``n_parameters`` fix
    the sizes of the thread's local arrays (its state, its scratch, its copy of the parameters)."""
    n_p = max(n_parameters, 1)

    @cuda_jit
    def drive(y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status, counts,
              stopped):
        # size: the run's arguments and one output array each (as the CPU's driver)
        i = cuda.grid(1)
        if i >= y.shape[0]:
            return
        state = cuda.local.array(n_state, float64)
        scratch = cuda.local.array((SCRATCH_ROWS, n_state), float64)
        parameters = cuda.local.array(n_p, float64)
        for j in range(n_state):
            state[j] = y[i, j]
        for j in range(p.shape[0]):
            parameters[j] = p[j]
        taken = counts[i, 0] + counts[i, 1]  # as the CPU's driver: max_steps bounds the sample's total
        code, accepted, rejected, crossed, t = run_sample(
            state, parameters[:p.shape[0]], t0, t_end, h0, loop_array(rtol), loop_array(atol), max_steps - taken,
            loop_array(times), loop_array(out)[i], loop_array(section), loop_array(crossing_t)[i],
            loop_array(crossing_y)[i], scratch)
        for j in range(n_state):
            y[i, j] = state[j]
        status[i] = code
        counts[i, 0] += accepted
        counts[i, 1] += rejected
        counts[i, 2] = crossed
        stopped[i] = t

    return drive


def run(kernel, y, p, t0, t_end, h0, rtol, atol, max_steps, times, out, section, crossing_t, crossing_y, status,
        counts, stopped):
    # size: as the CPU's driver: the run's arguments and its output arrays, filled here
    """Launch ``kernel`` (:func:`make_kernel`) over the samples of ``y`` (N, n); fills ``y`` (the final states) and
    the output arrays as the CPU's driver does (:func:`tumble.kernels.loops.adaptive_loop.make_dop853_driver`)."""
    host = (y, out, crossing_t, crossing_y, status, counts, stopped)
    device = [cuda.to_device(np.ascontiguousarray(array)) for array in host]
    device_y, device_out, device_ct, device_cy, device_status, device_counts, device_stopped = device
    kernel[launch_shape(len(y))](device_y, cuda.to_device(p), float(t0), float(t_end), float(h0), cuda.to_device(rtol),
                                 cuda.to_device(atol), int(max_steps), cuda.to_device(times), device_out,
                                 cuda.to_device(section), device_ct, device_cy, device_status, device_counts,
                                 device_stopped)
    for array, on_device in zip(host, device):
        array[...] = on_device.copy_to_host()
