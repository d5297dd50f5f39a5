"""The free body's CPU driver: blocks of samples in parallel through the one time loop
(:func:`tumble.kernels.loops.block_loop.run_block`), one compiled driver per method and torque type.

Samples are cut into blocks of ``block`` samples; blocks run in parallel (a share of whole blocks per thread,
:func:`tumble.kernels.threads.in_parallel`) and each block is copied into
three contiguous component arrays (structure of arrays) so that the per-sample step (:mod:`tumble.kernels.steps.fused`)
vectorises across samples. Samples never interact, so the results do not depend on the number of threads or on the
block size. The device's kernel (:mod:`tumble.kernels.cuda.rigid_body`) runs the same loop, one sample per thread.

Observers are runtime switches: an output that was not asked for is an empty array (a zero-length axis), and its
branch, outside the loop over the samples of a block, is skipped; the branches cost nothing measurable
(``benchmarks/engine.py``). The method is not: it is a constant of the driver (:func:`make_propagate`) and of the
device kernel, and the loop compiles its one step. So one compiled driver per method and torque type (none, a built-in
profile, a user's function) serves every combination of observers, and a run compiles (or loads) only the driver of
the method it runs; a run that asks for no observer at all (``tumble.integrate``, ``tumble.propagate``) has a driver of
its own with the observers compiled out (``observing``), which cuts a first integration's compile by a third (8 s to
5 s for rk4, 2 cores). Memory is O(samples) unless a trajectory is stored.

Per-sample status (:mod:`tumble.kernels.loops.block_loop`): ``STATUS_OK``, ``STATUS_NONFINITE`` (a component became NaN or
inf) or ``STATUS_DRIFT`` (torque-free only: the energy or ``|L|**2`` drifted by more than ``drift_limit``, relative).
A sample with a bad status stops stepping and keeps the state it had when it was caught; so does a sample whose
measurement is complete (early stop, see ``stop_norm`` and ``stop_flips``).
"""

import numpy as np
from numba import types

from ...registry import STATUS_DRIFT, STATUS_NAMES, STATUS_NONFINITE, STATUS_OK  # noqa: F401
from .block_loop import CHECK_EVERY, FREE_BODY, block_scratch, run_block_inlined  # noqa: F401
from ..jit import jit
from ..trig import _min


def make_propagate(torque_free, kernel, observing=True):
    # size: the closure holds the CPU's driver below (see there)
    """The CPU's driver of the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`) for the free body and method
    ``kernel`` (its index in :data:`tumble.registry.STEPPING`), torque-free or with a torque, with its observers or
    without (``observing``: a plain integration asks for none): constants of the closure, which the loop takes as
    literals, so that it compiles the one step it runs and the observers only where a run may ask for them. numba's disk
    cache tells the closures apart by their constants (its index key hashes a closure's cell contents)."""

    @jit
    def propagate(w, body, t0, h, n_steps, block,
                  save_every, saved,
                  axis, norm_weights, probe_steps, probes,
                  flips, flip_count,
                  drift,
                  status, steps_taken,
                  stop_norm, stop_flips, drift_limit,
                  torque_kind, torque_params, torque_fn,
                  start, stop):
        # size: the driver's flat arguments (kernels.loops.methods.run packs them), documented once here
        """Advance every sample ``n_steps`` fixed steps of size ``h`` of the closure's method, observing as asked: the
        CPU's wrapper of the one time loop (:func:`tumble.kernels.loops.block_loop.run_block`), blocks of ``block`` samples in
        parallel: the samples ``start:stop`` (``start`` a multiple of ``block``), one share of
        :func:`tumble.kernels.threads.in_parallel`.

        Parameters
        ----------
        w : ndarray, shape (3, N)
            Body-frame angular velocity, rad/s; overwritten with the final (or frozen) state.
        body : tuple
            :func:`tumble.kernels.steps.steppers.body_constants` of the moments.
        t0, h : float
            Start time and step, s.
        n_steps, block : int
            Steps to take; samples per block.
        save_every : int
            With ``saved`` (shape ``(n_saved, 3, N)``): store the initial state, every ``save_every``-th state and
            the final one. ``n_saved = 0`` stores nothing.
        axis : int
            0-based spin axis.
        norm_weights : ndarray (3,)
            Weights ``g`` of the transverse norm ``sqrt(g_b w_b² + g_c w_c²)`` of the two other components.
        probe_steps, probes : ndarray (P,) int64 increasing, ndarray (P, N) or (0, N)
            Weighted transverse norm (rad/s) after each step listed in ``probe_steps`` (0 = the initial state);
            NaN once a sample has stopped.
        flips, flip_count : ndarray (N, F), ndarray (N,) int64
            Times (s) of the first ``F`` sign changes of the ``axis`` component, located inside the step by cubic
            Hermite interpolation (NaN beyond the last); ``flip_count`` counts all of them. ``F = 0``: flips are not
            observed.
        drift : ndarray (2, N) or (0, N)
            Running maximum of ``|E - E0| / E0`` and ``||L|² - |L0|²| / |L0|²`` (not recorded when empty).
        status, steps_taken : ndarray (N,) int8, ndarray (N,) int64
            Outputs: per-sample status and the number of steps each sample took.
        stop_norm, stop_flips : float, int
            Early stop: a sample stops once its transverse norm has reached ``stop_norm`` (at a probe) and it has
            flipped ``stop_flips`` times; a criterion <= 0 is off, both off disables early stopping.
        drift_limit : float
            Torque-free invariant drift that marks a sample ``STATUS_DRIFT`` (<= 0: off).
        torque_kind, torque_params, torque_fn
            See :func:`tumble.kernels.steps.steppers.body_torque`; ``torque_params=None`` compiles the torque out.
        start, stop : int
            The share of samples this call runs.
        """
        # the transverse norm's two terms: the components off the axis, none subtracted (made with the np.empty
        # variants the blocks' scratch needs: each other numpy constructor is one more to compile)
        columns, rows = np.empty(2, dtype=np.int64), np.empty((2, 3))
        columns[0], columns[1] = (axis + 1) % 3, (axis + 2) % 3
        rows[0, 0], rows[0, 1], rows[0, 2] = norm_weights[columns[0]], norm_weights[columns[1]], 0.0
        rows[1, 0], rows[1, 1], rows[1, 2] = 0.0, 0.0, 0.0
        norm = (columns, rows[0], rows[1])
        no_fit, no_fit_points = np.empty((0, 1)), np.empty(0, dtype=np.int64)  # the growth fit is the caller's
        for lo in range(start, stop, block):
            m = _min(block, stop - lo)
            run_block_inlined(FREE_BODY, kernel, torque_free, observing, w, lo, block_scratch(3, m), body, t0, h,
                              n_steps, save_every, saved, norm, probe_steps, probes, (axis, flips, flip_count), drift,
                              drift_limit, status, steps_taken, (stop_norm, stop_flips),
                              (torque_kind, torque_params, torque_fn), (0.0, 0, 0.0, no_fit, no_fit_points))

    return propagate


# A user's torque function ``f(t, w1, w2, w3) -> (N1, N2, N3)`` is passed as a first-class function of this
# type, so one compiled (and cached) driver per method serves every torque function instead of one variant per
# function (which numba could not cache). The price is an indirect call per sample and stage, which keeps the step
# from vectorising across samples (measured in benchmarks/engine.py).
TORQUE_SIGNATURE = types.UniTuple(types.float64, 3)(types.float64, types.float64, types.float64, types.float64)

#: The drivers made so far, by (method id, torque: None, "profile" or "function", observing); each compiles on its first
#: call.
_DRIVERS = {}


def driver(kernel, torque_free, torque_fn=None, observing=True):
    """The compiled driver for a run of method ``kernel``: torque-free, with a built-in torque profile, or with
    ``torque_fn``, with the observers or without (:func:`make_propagate`, made once per method, torque and
    ``observing``).

    With a torque function, the function is compiled for :data:`TORQUE_SIGNATURE` and a dispatcher of the driver
    with a torque, compiled only for the first-class function type and then closed to further compilation, takes it:
    numba converts any jitted function of that signature to the first-class type instead of compiling a variant for it.
    """
    torque = None if torque_free else "profile" if torque_fn is None else "function"
    if torque_fn is not None:
        torque_fn.compile(TORQUE_SIGNATURE)
    key = (kernel, torque, bool(observing))
    made = _DRIVERS.get(key)
    if made is None:
        made = make_propagate(torque_free, kernel, bool(observing))
        if torque == "function":
            made.compile(_user_torque_types())
            made.disable_compile()
        _DRIVERS[key] = made
    return made


def _user_torque_types():
    """Argument types of the driver for a user torque function (see :func:`driver`)."""
    f8, i8 = types.float64, types.int64
    return (f8[:, ::1], types.UniTuple(f8, 12), f8, f8, i8, i8, i8, f8[:, :, ::1], i8, f8[::1], i8[::1],
            f8[:, ::1], f8[:, ::1], i8[::1], f8[:, ::1], types.int8[::1], i8[::1], f8, i8, f8, i8, f8[::1],
            types.FunctionType(TORQUE_SIGNATURE), i8, i8)
