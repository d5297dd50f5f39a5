"""The kernels' parallelism: a run's samples cut into one contiguous share per numba thread, each share run by a
serial kernel that releases the GIL (``nogil``, :func:`tumble.kernels.jit.jit`'s default) on a thread of its own.

Not numba's ``prange``: a ``parallel=True`` kernel pays numba's parallel passes and lowers its loop body twice (the
kernel and the gufunc numba outlines from it), which was 4 of the 10 s of ``exact.omega``'s first call and 6 of the
16 s of a first rk4 ``integrate`` (``benchmarks/first_call.py``, 2 cores, numba 0.68). The shares run the same loop
over the same samples, so the results are the same (the samples never interact; the kernels' reductions are
counts, added here). The thread count is numba's (``numba.get_num_threads()``: ``NUMBA_NUM_THREADS``,
``numba.set_num_threads``); one share runs in the calling thread without the pool.
"""

from concurrent.futures import ThreadPoolExecutor

import numba

__all__ = ["in_parallel", "in_shares", "parallel_block"]


def in_shares(run_share, n, share, granule=1):
    """``run_share(*share(lo, hi))`` for one contiguous share ``lo:hi`` of the ``n`` samples per numba thread (its
    bounds multiples of ``granule``, so that a kernel's blocks stay whole), each on a thread of its own (``run_share``
    releases the GIL): the last in this thread, the others on the process's pool (:func:`_pool`, made once: starting
    threads for each call cost 0.4 ms, more than a small run). Returns the shares' results, in order."""
    granules = -(-int(n) // granule)
    threads = max(1, min(numba.get_num_threads(), granules))
    bounds = [min(int(n), granule * (granules * k // threads)) for k in range(threads + 1)]
    shares = [share(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:])]
    if len(shares) == 1:
        return [run_share(*shares[0])]
    others = [_pool().submit(run_share, *arguments) for arguments in shares[:-1]]
    try:
        last = run_share(*shares[-1])
    finally:
        results = [done.result() for done in others]
    return results + [last]


def in_parallel(kernel, n, *arguments, granule=1):
    """``kernel(*arguments, start, stop)``, a kernel whose loop runs over the samples ``start:stop`` of ``n``, for one
    share per numba thread (:func:`in_shares`); the shares' results added up (a kernel returns nothing, a count, or a
    tuple of counts)."""
    results = in_shares(kernel, n, lambda lo, hi: arguments + (lo, hi), granule)
    if results[0] is None:
        return None
    if isinstance(results[0], tuple):
        return tuple(sum(parts) for parts in zip(*results))
    return sum(results)


def parallel_block(n, largest, smallest=64):
    """Samples per block of a block driver for ``n`` samples: ``largest``, or fewer so that the blocks are at least as
    many as numba's threads (a scene of 256 samples in blocks of 256 would run on one thread), never fewer than
    ``smallest`` (a block's SIMD loop keeps its lanes full) and a multiple of 8.

    Results do not depend on the block size (the drivers' samples never interact): this is speed only.
    """
    threads = max(1, numba.get_num_threads())
    share = -(-int(n) // threads)
    return int(max(smallest, min(largest, -(-share // 8) * 8)))


_POOL = []


def _pool():
    """The process's threads for :func:`in_shares` (one fewer than numba's threads suffices; made on first use)."""
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max(1, numba.config.NUMBA_NUM_THREADS - 1), thread_name_prefix="tumble"))
    return _POOL[0]
