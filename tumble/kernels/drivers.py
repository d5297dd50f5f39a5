"""The generic ensemble driver: every fixed-step method, every sample, the time loop inside.

Samples are cut into blocks of ``block`` samples; blocks run in parallel (``prange``) and each block is
copied into a contiguous ``(3, B)`` structure-of-arrays buffer so the step functions vectorise across
samples. Samples never interact, so results do not depend on the number of threads.
"""

import numpy as np
from numba import prange

from .jit import jit
from .steppers import (
    FAMILY_EXPLICIT_RK,
    FAMILY_IMPLICIT_MIDPOINT,
    FAMILY_SPLITTING,
    explicit_rk_step,
    implicit_midpoint_step,
    splitting_step,
)


def work_buffers(family, stages):
    """How many ``(3, B)`` scratch buffers a step of ``family`` needs."""
    if family == FAMILY_EXPLICIT_RK:
        return stages + 1
    if family == FAMILY_IMPLICIT_MIDPOINT:
        return 3
    return 1  # splitting: each sample's initial |L|**2


@jit(parallel=True)
def propagate(family, A, b, c, flows, fractions, axis_order, n_work, w, moments, t0, h, n_steps, save_every, saved,
              torque_kind, torque_params, torque_fn, block):
    """Advance every sample ``n_steps`` fixed steps of size ``h``.

    Parameters
    ----------
    family : int
        ``FAMILY_EXPLICIT_RK`` (uses ``A, b, c``), ``FAMILY_SPLITTING`` (uses ``flows, fractions``) or
        ``FAMILY_IMPLICIT_MIDPOINT``.
    axis_order : ndarray, shape (3,), int64
        Body axis turned by each rotation sub-flow of a splitting.
    n_work : int
        Scratch buffers per block (:func:`work_buffers`).
    w : ndarray, shape (3, N)
        Body-frame angular velocity, rad/s; overwritten with the final state.
    moments : ndarray, shape (3,)
        Principal moments, kg m².
    t0, h : float
        Start time and step, s.
    n_steps, save_every : int
        Steps to take; store the state every ``save_every`` steps (0: store nothing).
    saved : ndarray, shape (n_saved, 3, N)
        Receives the initial state, every ``save_every``-th state and the final state.
    torque_kind, torque_params, torque_fn
        See :func:`tumble.kernels.steppers.body_torque`; ``torque_params=None`` compiles the torque out.
    block : int
        Samples per block.
    """
    n = w.shape[1]
    n_blocks = (n + block - 1) // block
    for ib in prange(n_blocks):
        lo = ib * block
        hi = min(lo + block, n)
        y = np.empty((3, hi - lo))
        y[:, :] = w[:, lo:hi]
        work = np.empty((n_work, 3, hi - lo))
        if family == FAMILY_SPLITTING:
            target = work[0, 0]
            for i in range(hi - lo):
                l1, l2, l3 = moments[0] * y[0, i], moments[1] * y[1, i], moments[2] * y[2, i]
                target[i] = l1 * l1 + l2 * l2 + l3 * l3
        slot = 0
        if save_every > 0:
            saved[0, :, lo:hi] = y
            slot = 1
        for k in range(n_steps):
            t = t0 + k * h
            if family == FAMILY_EXPLICIT_RK:
                explicit_rk_step(y, work, t, h, moments, A, b, c, torque_kind, torque_params, torque_fn)
            elif family == FAMILY_SPLITTING:
                splitting_step(y, work[0, 0], t, h, moments, axis_order, flows, fractions, torque_kind, torque_params,
                               torque_fn)
            else:
                implicit_midpoint_step(y, work, t, h, moments, torque_kind, torque_params, torque_fn)
            if save_every > 0 and ((k + 1) % save_every == 0 or k + 1 == n_steps):
                saved[slot, :, lo:hi] = y
                slot += 1
        w[:, lo:hi] = y
