"""The models of :mod:`tumble.physics.models` on a CUDA device: one thread per sample, float64 (issue 28).

A model is written once. Each thread copies its sample's state into a local array of one column and steps it with
the CPU driver's own step, :func:`tumble.kernels.model_steps.step` (rk4 and rk8 generated from the tableaux into
:mod:`tumble.kernels.model_steps`, the gravity gradient's quaternion put back on the unit sphere after each step, the
Lie–Poisson splittings of :mod:`tumble.kernels.model_splittings` for the free body, the gyrostat and the heavy top),
with the invariants of :mod:`tumble.kernels.systems` (:func:`tumble.kernels.model_steps.invariants`). numba-cuda
compiles those ``@jit`` functions for the device; their block loop runs over the thread's one sample. A model or a
method added to the tables runs here without a line added.

:func:`run_model` takes :func:`tumble.kernels.run_model`'s arguments and returns the same
:class:`~tumble.kernels.models.ModelObserved`, sample for sample as the CPU driver observes it: the final (or
frozen) state, the state every ``save_every`` steps, the transverse norm at the probe steps (NaN once a sample has
stopped), the running maximum of each invariant's drift, the status (non-finite: checked before the first step,
every :data:`tumble.kernels.models.CHECK_EVERY` steps, at the end, and every step while drifts are tracked; invariant
drift past ``drift_limit``) and the steps each sample took. A sample that stops keeps the state it had when it was
caught. The CPU's screening pass (:func:`tumble.kernels.model_steps.drift_suspects`) is a SIMD speed-up only: a thread
checks its own sample exactly every step, which is what the screen's "nothing to stop" stands for.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_models`). On numba-cuda's simulator (``NUMBA_ENABLE_CUDASIM=1``) the kernel body runs
in Python and the ``@jit`` functions it calls as compiled CPU code (the local arrays are numpy arrays there).
"""

import math

import numpy as np
from numba import cuda, float64

from ..registry import STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK, model_kind
from .jit import cuda_jit
from .model_steps import invariants, step
from .models import CHECK_EVERY, MODEL_CODES, MODEL_METHODS, ModelObserved, _initial_invariants, model_arguments
from .systems import N_CONSTANTS, N_INVARIANTS

__all__ = ["THREADS", "kernel", "make_kernel", "run_model"]

#: Threads per block of a launch (one sample each).
THREADS = 128


def make_kernel(model, method, n_state):
    # size: the closure holds the one kernel below (see there)
    """The device kernel of ``model`` (a :data:`~tumble.kernels.models.MODEL_CODES` value) stepped by ``method``
    (a :data:`~tumble.kernels.models.MODEL_METHODS` value), ``n_state`` components: one thread per sample. The
    three are constants of the closure, so numba compiles the kernel for that model and method."""

    @cuda_jit
    def propagate(y, c, h, n_steps, save_every, saved, columns, weights, y_eq, probe_steps, probes, drift,
                  drift_limit, status, steps_taken):
        # size: a kernel's flat arguments (DESIGN.md: arrays and scalars below the kernels' door), packed by
        # run_model, and one time loop with the CPU driver's observers written per sample
        """Advance sample ``cuda.grid(1)`` by ``n_steps`` steps of ``h``; the arguments are those of
        :func:`tumble.kernels.models.propagate_model` (``c``: the constants as a tuple), :func:`run_model` packs
        them."""
        i = cuda.grid(1)
        if i >= y.shape[1]:
            return
        ys = cuda.local.array((n_state, 1), float64)
        x0 = cuda.local.array((N_INVARIANTS, 1), float64)
        scale = cuda.local.array((N_INVARIANTS, 1), float64)
        finite = True
        for j in range(n_state):
            ys[j, 0] = y[j, i]
            finite = finite and math.isfinite(ys[j, 0])
        # the constants in a local array: the CPU driver's argument types, so that on the simulator the CPU's compiled
        # (and cached) step and invariants serve as they are, not a second variant for a tuple
        constants = cuda.local.array(N_CONSTANTS, float64)
        for j in range(N_CONSTANTS):
            constants[j] = c[j]
        _initial_invariants(model, ys, constants, x0, scale)
        record = drift.shape[0] > 0
        track = record or drift_limit > 0.0
        if record:
            for j in range(N_INVARIANTS):
                drift[j, i] = 0.0
        code = STATUS_OK if finite else STATUS_NONFINITE
        ran = 0
        slot = 0
        if saved.shape[0] > 0:
            for j in range(n_state):
                saved[0, j, i] = ys[j, 0]
            slot = 1
        probe = 0
        while probe < probe_steps.shape[0] and probe_steps[probe] == 0:
            probes[probe, i] = _norm(ys, columns, weights, y_eq) if code == STATUS_OK else math.nan
            probe += 1
        for k in range(n_steps):
            if code == STATUS_OK:
                step(model, method, ys, k * h, h, constants, x0)
                ran = k + 1
                if track or ran % CHECK_EVERY == 0 or ran == n_steps:
                    for j in range(n_state):
                        if not math.isfinite(ys[j, 0]):
                            code = STATUS_NONFINITE
                if track and code == STATUS_OK:
                    x1, x2, x3, _, _, _ = invariants(model, ys, 0, constants)
                    d1 = abs(x1 - x0[0, 0]) / scale[0, 0]
                    d2 = abs(x2 - x0[1, 0]) / scale[1, 0]
                    d3 = abs(x3 - x0[2, 0]) / scale[2, 0]
                    if record:
                        drift[0, i] = max(drift[0, i], d1)
                        drift[1, i] = max(drift[1, i], d2)
                        drift[2, i] = max(drift[2, i], d3)
                    if drift_limit > 0.0 and not (d1 <= drift_limit and d2 <= drift_limit and d3 <= drift_limit):
                        code = STATUS_DRIFT
            if saved.shape[0] > 0 and ((k + 1) % save_every == 0 or k + 1 == n_steps):
                for j in range(n_state):
                    saved[slot, j, i] = ys[j, 0]
                slot += 1
            while probe < probe_steps.shape[0] and probe_steps[probe] == k + 1:
                probes[probe, i] = _norm(ys, columns, weights, y_eq) if code == STATUS_OK else math.nan
                probe += 1
            if code != STATUS_OK and saved.shape[0] == 0 and probe == probe_steps.shape[0]:
                break  # nothing left to store: the stopped sample's state is final
        while probe < probe_steps.shape[0]:
            probes[probe, i] = math.nan
            probe += 1
        for j in range(n_state):
            y[j, i] = ys[j, 0]
        status[i] = code
        steps_taken[i] = ran

    return propagate


def _norm(ys, columns, weights, y_eq):
    """The transverse norm ``sqrt(sum_j weights[j] (y[columns[j]] − y_eq[columns[j]])²)`` of a thread's sample (as
    :func:`tumble.kernels.models._observe_norm`); a device function, compiled into the kernel that calls it."""
    total = 0.0
    for j in range(columns.shape[0]):
        d = ys[columns[j], 0] - y_eq[columns[j]]
        total += weights[j] * d * d
    return math.sqrt(total)


_norm = cuda.jit(device=True)(_norm)

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
    :class:`~tumble.kernels.models.ModelObserved`; ``y`` (n_state, N) is overwritten with the final states.
    ``block`` is not used (a thread is a sample). Raises ``ValueError`` as the CPU's does (an unknown kind or
    method, a state of the wrong rows)."""
    _, n_state, constants, n_saved, columns, weights, y_eq, probe_steps = model_arguments(
        kind, method, y, moments, n_steps, parameters, save_every, columns, weights, y_eq, probe_steps)
    n = y.shape[1]
    device_y = cuda.to_device(y)
    saved = cuda.device_array((n_saved, n_state, n) if n_saved else (0, n_state, 1))
    probes = cuda.device_array((len(probe_steps), n) if len(probe_steps) else (0, 1))
    drifts = cuda.device_array((N_INVARIANTS, n) if drift else (0, 1))
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    kernel(kind, method)[-(-n // threads), threads](
        device_y, tuple(float(x) for x in constants), float(h), int(n_steps), int(save_every), saved,
        cuda.to_device(columns), cuda.to_device(weights), cuda.to_device(y_eq), cuda.to_device(probe_steps), probes,
        drifts, float(drift_limit), status, steps_taken)
    y[:] = device_y.copy_to_host()
    n_invariants = len(model_kind(kind).invariants)
    return ModelObserved(saved.copy_to_host() if n_saved else None,
                         probes.copy_to_host() if len(probe_steps) else None,
                         drifts.copy_to_host()[:n_invariants] if drift else None, status.copy_to_host(),
                         steps_taken.copy_to_host())
