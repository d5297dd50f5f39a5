"""The models of :mod:`tumble.physics.models` on a CUDA device: one thread per sample, float64 (issue 28).

The time loop is written once: each thread runs the CPU's own loop, :func:`tumble.kernels.loops.block_loop.run_block` (steps,
stores, probes, drift screening and checks, early stop, status), on a block of one sample held in the thread's local
memory; numba-cuda compiles it and the ``@jit`` functions it calls (the steps of :mod:`tumble.kernels.steps.model_steps`,
the splittings of :mod:`tumble.kernels.steps.model_splittings`, the invariants of :mod:`tumble.kernels.systems`) for the
device. A model, a method or an observer added to the CPU's loop runs here without a line added; a sample stops at the
same step with the same status as on the CPU.

:func:`run_model` takes :func:`tumble.kernels.run_model`'s arguments and returns the same
:class:`~tumble.kernels.loops.model_loop.ModelObserved`.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_models`). On numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernel body runs
in Python and calls the loop as the CPU's compiled function (:func:`tumble.kernels.cuda.launch.loop_array`).
"""

import numpy as np
from numba import boolean, cuda, float64, int64

from ...registry import model_kind
from .launch import THREADS, launch_shape, loop_array, loop_with_codes
from ..jit import cuda_jit
from ..loops.block_loop import N_INVARIANTS, PROBE_ROWS, run_block
from ..loops.model_loop import MODEL_CODES, MODEL_METHODS, ModelObserved, model_arguments
from ..systems import N_CONSTANTS

__all__ = ["THREADS", "kernel", "make_kernel", "run_model"]


def make_kernel(model, method, n_state):
    """The device kernel of ``model`` (a :data:`~tumble.kernels.loops.model_loop.MODEL_CODES` value) stepped by ``method``
    (a :data:`~tumble.kernels.loops.model_loop.MODEL_METHODS` value), ``n_state`` components: one thread per sample, running
    the CPU's time loop (:func:`tumble.kernels.loops.block_loop.run_block`) on a block of one sample in the thread's local
    memory. The codes are constants of the closure, handed to the loop as literals (on the simulator through
    :func:`tumble.kernels.cuda.launch.loop_with_codes`: the CPU's compiled loop of that system and method), so that
    the kernel compiles that system's and that method's step only."""
    loop = loop_with_codes(run_block, model, method, True, True)

    @cuda_jit
    def propagate(y, c, h, n_steps, save_every, saved, columns, weights, y_eq, probe_steps, probes, drift,
                  drift_limit, status, steps_taken):
        """Advance sample ``cuda.grid(1)`` by ``n_steps`` steps of ``h``; the arguments are those of
        :func:`tumble.kernels.loops.model_loop.propagate_model` (``c``: the constants as a tuple), :func:`run_model` packs
        them."""
        i = cuda.grid(1)
        if i >= y.shape[1]:
            return
        # the constants in a local array: the CPU driver's argument types, so that on the simulator the CPU's compiled
        # (and cached) loop serves as it is, not a second variant for a tuple
        constants = cuda.local.array(N_CONSTANTS, float64)
        for j in range(N_CONSTANTS):
            constants[j] = c[j]
        scratch = (cuda.local.array((n_state, 1), float64), cuda.local.array((n_state, 1), float64),
                   cuda.local.array((n_state, 1), float64), cuda.local.array((N_INVARIANTS, 1), float64),
                   cuda.local.array((N_INVARIANTS, 1), float64), cuda.local.array((PROBE_ROWS, 1), float64),
                   cuda.local.array((2, 1), boolean), cuda.local.array(1, int64))
        no_flips, no_count = loop_array(probes)[:, :0], loop_array(steps_taken)[:0]  # a model's flips: not observed
        loop(model, method, True, True, loop_array(y), i, scratch, constants, 0.0, h, n_steps, save_every, loop_array(saved),
             (loop_array(columns), loop_array(weights), loop_array(y_eq)), loop_array(probe_steps), loop_array(probes),
             (0, no_flips, no_count), loop_array(drift), drift_limit, loop_array(status), loop_array(steps_taken),
             (0.0, 0), (0, None, None), (0.0, 0, 0.0, no_flips, no_count))

    return propagate


_KERNELS = {}


def kernel(kind, method):
    """The device kernel of model ``kind`` stepped by ``method`` (:func:`make_kernel`, made once; compiled on its
    first launch)."""
    key = (kind, method)
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(MODEL_CODES[kind], MODEL_METHODS[method], len(model_kind(kind).state))
    return _KERNELS[key]


def run_model(kind, method, y, moments, h, n_steps, *, save_every=0, columns=None, weights=None, y_eq=None,
              probe_steps=None, drift=False, drift_limit=0.0, block=None, **parameters):
    # size: the keywords of tumble.kernels.run_model, so that the engine calls either the same way
    """:func:`tumble.kernels.run_model` on the device: the same arguments and the same
    :class:`~tumble.kernels.loops.model_loop.ModelObserved`; ``y`` (n_state, N) is overwritten with the final states.
    ``block`` is not used (a thread is a sample). Raises ``ValueError`` as the CPU's does (an unknown kind or
    method, a state of the wrong rows)."""
    _, n_state, constants, n_saved, columns, weights, y_eq, probe_steps = model_arguments(
        kind, method, y, moments, n_steps, parameters, save_every, columns, weights, y_eq, probe_steps)
    n = y.shape[1]
    device_y = cuda.to_device(y)
    saved = cuda.device_array((n_saved, n_state, n) if n_saved else (0, n_state, 1))
    probes = cuda.device_array((len(probe_steps), n) if len(probe_steps) else (0, n))
    drifts = cuda.to_device(np.zeros((N_INVARIANTS if drift else 0, n)))  # the loop keeps running maxima
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    kernel(kind, method)[launch_shape(n)](
        device_y, tuple(float(x) for x in constants), float(h), int(n_steps), int(save_every), saved,
        cuda.to_device(columns), cuda.to_device(weights), cuda.to_device(y_eq), cuda.to_device(probe_steps), probes,
        drifts, float(drift_limit), status, steps_taken)
    y[:] = device_y.copy_to_host()
    n_invariants = len(model_kind(kind).invariants)
    return ModelObserved(saved.copy_to_host() if n_saved else None,
                         probes.copy_to_host() if len(probe_steps) else None,
                         drifts.copy_to_host()[:n_invariants] if drift else None, status.copy_to_host(),
                         steps_taken.copy_to_host())
