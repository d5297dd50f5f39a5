"""The kernels' parallelism: a run's samples cut into one contiguous share per numba thread, each share run by a
serial kernel that releases the GIL (``nogil``, :func:`tumble.kernels.jit.jit`'s default) on a thread of its own.

Not numba's ``prange``: a ``parallel=True`` kernel pays numba's parallel passes and lowers its loop body twice (the
kernel and the gufunc numba outlines from it), which was 4 of the 10 s of ``exact.omega``'s first call and 6 of the
16 s of a first rk4 ``integrate`` (``benchmarks/first_call.py``, 2 cores, numba 0.68). The shares run the same loop
over the same samples, so the results are the same (the samples never interact; the kernels' reductions are
counts, added here). The thread count is numba's (``numba.get_num_threads()``: ``NUMBA_NUM_THREADS``,
``numba.set_num_threads``); one share runs in the calling thread without the pool.
"""

import os
import platform
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from .jit import jit

__all__ = ["in_parallel", "in_shares", "parallel_block", "start_shares"]


def in_shares(run_share, n, share, granule=1, handoff=False):
    """``run_share(*share(lo, hi))`` for one contiguous share ``lo:hi`` of the ``n`` samples per numba thread (its
    bounds multiples of ``granule``, so that a kernel's blocks stay whole), each on a thread of its own (``run_share``
    releases the GIL): the last in this thread, the others on the process's pool (:func:`_pool`, made once: starting
    threads for each call cost 0.4 ms, more than a small run). Returns the shares' results, in order.

    ``handoff``: ``run_share`` takes one more argument, ``starts``, and calls :func:`start_shares` ``(starts)`` first:
    the other threads' shares then start once this thread's has let the GIL go. Started by this thread in Python, a
    worker's return to Python for its share waited for the GIL this thread held for its own share's call, asleep, 30-90
    us on a 2-core machine: a tenth of a small run."""
    granules = -(-int(n) // granule)
    threads = max(1, min(numba.get_num_threads(), granules))
    bounds = [min(int(n), granule * (granules * k // threads)) for k in range(threads + 1)]
    shares = [share(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:])]
    if handoff:
        shares = [arguments + (_NO_STARTS,) for arguments in shares]
    if len(shares) == 1:
        return [run_share(*shares[0])]
    workers = _workers(len(shares) - 1)
    if workers is None:  # another thread's run holds them: the pool's threads
        others = [_pool().submit(run_share, *arguments) for arguments in shares[:-1]]
    else:
        others = workers
        for worker, arguments in zip(workers, shares[:-1]):
            worker.submit(run_share, arguments, started_by_share=handoff)
        if handoff:
            shares[-1] = shares[-1][:-1] + (_READY[:len(workers)],)
    try:
        last = run_share(*shares[-1])
    finally:
        try:
            if workers is not None:
                for worker in workers:  # a share that failed before it started the others (never in a kernel)
                    worker.start_if_not_taken()
            results = [done.result() for done in others]
        finally:
            if workers is not None:
                _WORKERS_FREE.release()
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

#: Pauses a waiting thread spins through before it sleeps (0.1-0.3 ms: a ``pause`` is 25-50 ns): a share handed to a
#: sleeping thread starts when the system wakes it, 30-90 us later on the 2-core machines measured, a tenth of a small
#: run; a thread that spins longer takes a core from other processes (pytest's workers, a cluster's).
_LINGER = 5000


_X86 = platform.machine().lower() in ("x86_64", "amd64", "i686", "x86")


@intrinsic
def _pause(typingctx):
    """The CPU's spin-wait hint (x86's ``pause``; nothing elsewhere)."""

    def codegen(context, builder, signature, arguments):
        if _X86:
            builder.call(builder.module.declare_intrinsic("llvm.x86.sse2.pause", fnty=ir.FunctionType(ir.VoidType(),
                                                                                                        [])), [])
        return context.get_dummy_value()

    return types.none(), codegen


@intrinsic
def _flag(typingctx, flags):
    """``flags[0]`` read as an atomic load (acquire): read again each time a loop asks, never hoisted out of it."""

    def codegen(context, builder, signature, arguments):
        array = context.make_array(signature.args[0])(context, builder, arguments[0])
        return builder.load_atomic(array.data, "acquire", 8)

    return types.int64(flags), codegen


@intrinsic
def _store(typingctx, flags, value):
    """``flags[0] = value`` as an atomic store (release): what a thread spinning on it sees."""

    def codegen(context, builder, signature, arguments):
        array = context.make_array(signature.args[0])(context, builder, arguments[0])
        builder.store_atomic(arguments[1], array.data, "release", 8)
        return context.get_dummy_value()

    return types.none(flags, types.int64), codegen


@jit
def start_shares(starts):
    """Set every flag of ``starts`` (the other threads' shares: :func:`in_shares`' ``handoff``), from a kernel that has
    let the GIL go."""
    for i in range(starts.shape[0]):
        _store(starts[i:], 1)


@jit
def _tell_and_await(told, value, flags, spins):
    """``told[0] = value``, then :func:`_await` ``(flags, 1, spins)``, both without the GIL: a thread that spins on
    ``told`` takes the GIL, once it sees it, from a thread that no longer holds it (where it would sleep, tens of
    microseconds, until this thread let it go)."""
    _store(told, value)
    return _await(flags, 1, spins)


@jit
def _await(flags, value, spins):
    """Whether ``flags[0] == value`` within ``spins`` pauses, spinning without the GIL."""
    for _ in range(spins):
        if _flag(flags) == value:
            return True
        _pause()
    return _flag(flags) == value


class _Worker:
    """A thread that runs one share at a time, handed over through a flag it spins on for :data:`_LINGER` pauses after
    each share before it sleeps: a run that follows another starts its shares at once."""

    def __init__(self, ready):
        self.ready = ready  # its flag in _READY
        self.done = np.zeros(1, dtype=np.int64)  # the number of the last share done (told without the GIL)
        self.shares = self.taken = 0  # handed over, started
        self.wake = threading.Event()
        self.finished = threading.Event()
        self.job = self.outcome = None
        threading.Thread(target=self._loop, name="tumble", daemon=True).start()

    def _loop(self):
        finished = 0
        while True:
            # the last share's end told from inside a call that let the GIL go: its caller, spinning on ``done``, then
            # takes the GIL at once
            if not _tell_and_await(self.done, finished, self.ready, _LINGER):
                if self.taken < self.shares:  # handed over, to be started by the caller's share: spin on
                    continue
                self.wake.wait()
            self.wake.clear()
            if self.ready[0] == 0:
                continue
            number, function, arguments = self.job
            self.taken = number  # before the flag falls: a caller that sees it taken never starts it again
            self.ready[0] = 0
            try:
                self.outcome = (function(*arguments), None)
            except BaseException as error:  # handed to the caller
                self.outcome = (None, error)
            finished = number
            self.finished.set()

    def submit(self, function, arguments, started_by_share=False):
        self.shares += 1
        self.job, self.outcome = (self.shares, function, arguments), None
        self.finished.clear()
        if not started_by_share:
            self.ready[0] = 1
        self.wake.set()

    def start_if_not_taken(self):
        if self.taken < self.shares:
            self.ready[0] = 1

    def result(self):
        if not _await(self.done, self.shares, _LINGER):
            self.finished.wait()
        value, error = self.outcome
        if error is not None:
            raise error
        return value


_WORKERS = []
_WORKERS_FREE = threading.Lock()
#: The workers' flags, each spinning on its own (a share with ``handoff`` sets those of the others at once).
_READY = np.zeros(max(1, numba.config.NUMBA_NUM_THREADS), dtype=np.int64)
#: ``starts`` of a share that starts no other.
_NO_STARTS = np.zeros(0, dtype=np.int64)


def _workers(count):
    """``count`` :class:`_Worker` threads for the calling run (made on first use), held until it releases
    ``_WORKERS_FREE``; None while another thread's run holds them."""
    if not _WORKERS_FREE.acquire(blocking=False):
        return None
    while len(_WORKERS) < count:
        _WORKERS.append(_Worker(_READY[len(_WORKERS):len(_WORKERS) + 1]))
    return _WORKERS[:count]


def _forget_workers():
    """In a forked child: the parent's threads are not there."""
    global _WORKERS_FREE
    _WORKERS.clear()
    _READY[:] = 0
    _POOL.clear()
    _WORKERS_FREE = threading.Lock()


os.register_at_fork(after_in_child=_forget_workers)


def _pool():
    """The process's threads for :func:`in_shares` (one fewer than numba's threads suffices; made on first use)."""
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max(1, numba.config.NUMBA_NUM_THREADS - 1), thread_name_prefix="tumble"))
    return _POOL[0]
