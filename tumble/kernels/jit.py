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
