"""The one place where numba options are chosen.

Every kernel in :mod:`tumble.kernels` is compiled through :func:`jit` so that caching, fast-math and the
error model are decided here and nowhere else.

* ``cache=True``: compiled machine code is kept on disk (``__pycache__``) so only the first run pays.
* ``fastmath``: only ``contract`` (fused multiply-add), ``arcp`` (multiply by a reciprocal) and ``nsz``
  (ignore the sign of zero). ``nnan``/``ninf`` are deliberately left out: they let LLVM delete
  ``x != x`` and ``isfinite`` tests, and blow-up detection must keep working (numba issues #9383, #6217).
  ``reassoc`` is left out too: it would let the compiler reorder the compensated and cancellation-free
  formulas the exact solution relies on.
* ``error_model="numpy"``: a division by zero gives inf/NaN (and is caught by the status checks) instead of
  raising, which also lets loops vectorise.

The device kernels (:mod:`tumble.kernels.cuda`) are compiled through :func:`cuda_jit`. The ``@jit`` functions they
call are compiled for the device by numba-cuda with the options above (it copies a CPU function's options).
"""

import numba

FASTMATH = frozenset({"contract", "arcp", "nsz"})

_NUMBA_IR_INLINE = True

_OPTIONS = dict(cache=True, fastmath=set(FASTMATH), error_model="numpy", nogil=True)


def jit(fn=None, *, parallel=False, inline=False, contract=True):
    """Compile ``fn`` with tumble's numba options.

    Parameters
    ----------
    parallel : bool
        Enable ``prange`` (only for ensemble drivers).
    inline : bool
        Inline at the numba IR level (for tiny helpers called in inner loops).
    contract : bool
        Allow fused multiply-adds. ``False`` for kernels whose bits must not depend on how the compiler
        happened to fuse: numba optimises a ``parallel=True`` kernel differently when it compiles it than
        when it loads it from the cache (numba issue #10617), and with contraction allowed the two fuse
        different products, so a cold and a warm run would disagree in the last bits.
    """
    options = dict(_OPTIONS, parallel=parallel)
    if not contract:
        options["fastmath"] = set(FASTMATH - {"contract"})
    if inline and _NUMBA_IR_INLINE:
        options["inline"] = "always"

    def wrap(f):
        return numba.njit(**options)(f)

    return wrap if fn is None else wrap(fn)


def parallel_block(n, largest, smallest=64):
    """Samples per block of a ``prange`` driver for ``n`` samples: ``largest``, or fewer so that the blocks are at
    least as many as numba's threads (a scene of 256 samples in blocks of 256 would run on one thread), never fewer
    than ``smallest`` (a block's SIMD loop keeps its lanes full) and a multiple of 8.

    Results do not depend on the block size (the drivers' samples never interact): this is speed only.
    """
    threads = max(1, numba.get_num_threads())
    share = -(-int(n) // threads)
    return int(max(smallest, min(largest, -(-share // 8) * 8)))


# CUDA kernels: fastmath off, which on the device means IEEE division and square root and no flush of subnormals to
# zero (numba-cuda's fastmath=True turns on all three, and approximate division breaks the 1e-10 agreement with the
# CPU); NVVM fuses multiply-adds by default, as the CPU's ``contract``. No disk cache: a device kernel is a closure
# over the method's step (a dispatcher), and numba's cache key pickles the closure's cells, which for a dispatcher
# differs from one process to the next (measured on the CPU: a new cache entry every run, never a hit), so a cache
# would only fill __pycache__. The simulator ignores the option anyway.
_CUDA_OPTIONS = dict(cache=False, fastmath=False)


def cuda_jit(fn):
    """Compile ``fn`` as a CUDA kernel with tumble's options. Imports ``numba.cuda``: only the device path calls
    this (importing tumble does not import numba.cuda)."""
    from numba import cuda

    return cuda.jit(**_CUDA_OPTIONS)(fn)
