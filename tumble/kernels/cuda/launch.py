"""What every CUDA launcher of :mod:`tumble.kernels` shares: the launch shape, one thread per sample, and the door
through which a kernel hands its arrays to a time loop written once for both devices.

The time loops (:func:`tumble.kernels.loops.block_loop.run_block`, ...) are ``@jit`` functions: on a device numba-cuda
compiles them into the kernel that calls them; on numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernel's
body runs as Python and calls them as the CPU's compiled functions, which take numpy arrays, not the simulator's
wrapped device arrays. :func:`loop_array` is the identity on a device and unwraps the numpy array on the simulator
(the same memory: what the loop writes is what the launcher copies back). A loop's leading codes (a system's code, a
method's id) choose its step: as literal types it compiles that step only; plain ints are a typing error that says so.
A kernel's constants reach the loop as literals on a device when the call spells its arguments out (at most
30: CPython compiles a call with more as a star-call, whose tuple numba-cuda types as plain ints);
:func:`loop_with_codes` gives the simulator's Python kernel body, whose calls numba types from Python values, a
compiled CPU function that passes them as literals, so that it runs the CPU's own compiled loop.

This module imports ``numba.cuda``; only the device launchers import it.
"""

import inspect

from numba import config, cuda

from ..jit import jit

__all__ = ["THREADS", "launch_shape", "loop_array", "loop_with_codes"]

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



def _with_codes(loop, codes):
    """A compiled CPU function of ``loop``'s parameters that calls ``loop`` with ``codes`` in place of its first
    ones: the codes are globals of the function, which numba types as literals (a star-call, ``loop(a, *args)``,
    would pack them into a tuple of plain ints)."""
    names = list(inspect.signature(loop.py_func).parameters)
    constants = {f"code_{k}": code for k, code in enumerate(codes)}
    arguments = ", ".join([*constants, *names[len(codes):]])
    namespace = {"loop": loop, **constants}
    exec(f"def call({', '.join(names)}):\n    return loop({arguments})\n", namespace)
    return jit(cache=False)(namespace["call"])


if config.ENABLE_CUDASIM:
    def loop_with_codes(loop, *codes):
        """The time loop ``loop`` as the simulator's kernel body calls it: a compiled CPU function that passes ``codes``
        (ints) to ``loop`` as constants, as the CPU's drivers do, and the rest of its arguments as given (the codes
        the kernel body passes in front are not used): the simulator runs the CPU's compiled loop of those codes.
        From Python, numba would type them as plain ints."""
        return _with_codes(loop, codes)
else:
    def loop_with_codes(loop, *codes):
        """``loop`` itself: the kernel passes its codes on as literals (see the module's note)."""
        return loop
