"""What a block time loop does to its block of samples: the one time loop's parts
(:func:`tumble.kernels.loops.block_loop.run_block`) that do not depend on the system.

A block's states are a structure of arrays ``ys`` (n_state, m): one row per component, one column per sample. A
sample that stops (a bad status, or its measurement complete) keeps the state it had then in ``frozen`` (n_state, m),
``active[i]`` turns False and ``last[i]`` records the steps it took; the loop's later steps move every sample of the
block together (SIMD lanes) and :func:`restore_frozen` puts the stopped ones back.
"""

import math

import numpy as np

from ...registry import STATUS_NONFINITE, STATUS_OK
from ..jit import jit, subroutine

__all__ = ["check_finite", "freeze", "restore_frozen", "store", "store_initial", "store_rest"]


@subroutine
def freeze(i, k, code, ys, active, frozen, status, last):
    """Stop sample ``i`` of a block after step ``k``: keep its state, record why (``code``, kept unless
    ``STATUS_OK``) and when."""
    active[i] = False
    for j in range(ys.shape[0]):
        frozen[j, i] = ys[j, i]
    if code != STATUS_OK:
        status[i] = code
    last[i] = k


@subroutine
def restore_frozen(ys, active, frozen):
    """The step moved every sample of the block; put the stopped ones back."""
    for i in range(ys.shape[1]):
        if not active[i]:
            for j in range(ys.shape[0]):
                ys[j, i] = frozen[j, i]


@subroutine
def check_finite(ys, active, k, frozen, status, last):
    """Stop the running samples with a non-finite component after step ``k``; returns how many.

    A branch-free pass over the whole block first (component rows outer, samples inner: it vectorises across samples)
    counts the non-finite values; only a block with one looks at its samples one by one. The free body's loop calls
    this after every step while it times flips, the models' while their drifts are recorded: without the screen the
    free body with a scene's observers ran 14 % slower than with its own three-component check; with it, 18 % faster
    (1.28e8 against 1.08e8 sample-steps/s), the heavy top with its drifts recorded 52 % faster (9.9e7 against 6.5e7;
    ``benchmarks/compare_trees.py``, 5 rounds, 2 cores, AVX2, 2026-11-28)."""
    bad = 0
    for j in range(ys.shape[0]):
        for i in range(ys.shape[1]):
            if not math.isfinite(ys[j, i]):
                bad += 1
    if bad == 0:
        return 0
    stopped = 0
    for i in range(ys.shape[1]):
        if active[i]:
            finite = True
            for j in range(ys.shape[0]):
                finite = finite and math.isfinite(ys[j, i])
            if not finite:
                freeze(i, k, np.int64(STATUS_NONFINITE), ys, active, frozen, status, last)  # (int64: one variant)
                stopped += 1
    return stopped


@jit(inline=True)  # (a subroutine called by both subroutines and kernels is compiled twice: numba keys it by its caller's options)
def store(saved, slot, ys, lo):
    """The block's states into ``saved[slot]`` (its columns ``lo``, ...)."""
    for j in range(ys.shape[0]):
        for i in range(ys.shape[1]):
            saved[slot, j, lo + i] = ys[j, i]


@subroutine
def store_initial(saved, ys, lo):
    """The block's initial states into ``saved[0]``; returns the next slot (0 when ``saved`` is empty)."""
    if saved.shape[0] == 0:
        return 0
    store(saved, np.int64(0), ys, lo)  # (not the literal 0: a second compiled variant)
    return 1


@subroutine
def store_rest(saved, slot, ys, lo, ran, n_steps, save_every):
    """The stores a block that stopped after ``ran`` steps still owes (the ``save_every``-th steps and the last one
    after it): its frozen states. ``saved`` empty: nothing."""
    if saved.shape[0] > 0:
        for k in range(ran, n_steps):
            if (k + 1) % save_every == 0 or k + 1 == n_steps:
                store(saved, slot, ys, lo)
                slot += 1
