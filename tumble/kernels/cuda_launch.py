"""What every CUDA launcher of :mod:`tumble.kernels` shares: the launch shape, one thread per sample, and the door
through which a kernel hands its arrays to a time loop written once for both devices.

The time loops (:func:`tumble.kernels.model_loop.run_block`, ...) are ``@jit`` functions: on a device numba-cuda
compiles them into the kernel that calls them; on numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernel's
body runs as Python and calls them as the CPU's compiled functions, which take numpy arrays, not the simulator's
wrapped device arrays. :func:`loop_array` is the identity on a device and unwraps the numpy array on the simulator
(the same memory: what the loop writes is what the launcher copies back).

This module imports ``numba.cuda``; only the device launchers import it.
"""

from numba import config, cuda

__all__ = ["THREADS", "launch_shape", "loop_array"]

#: Threads per block of a launch (one sample each).
THREADS = 128


def launch_shape(n):
    """``(blocks, threads)`` of a launch over ``n`` samples: :data:`THREADS` a block, fewer (a multiple of the warp's
    32) for a small run."""
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    return -(-n // threads), threads


if config.ENABLE_CUDASIM:
    def loop_array(array):
        """The numpy array inside the simulator's kernel argument ``array`` (see the module's note)."""
        item = getattr(array, "_item", array)
        return getattr(item, "_ary", item)
else:
    @cuda.jit(device=True, inline=True)
    def loop_array(array):
        """``array`` itself: on a device the time loop takes the kernel's arrays as they are."""
        return array
