"""The ensemble on a CUDA device: one thread per sample, its state in registers, float64.

A method is written once. numba-cuda compiles the ``@jit`` functions a kernel calls for the device, so a thread
steps its sample with the CPU's own per-sample functions: a Runge–Kutta method's ``<name>_sample``, generated from
its tableau into :mod:`tumble.kernels.fused`; a splitting's table from :mod:`tumble.kernels.tableaux`, run by
:func:`tumble.kernels.steppers.splitting_free_sample` (the sub-flows of :func:`tumble.kernels.steppers.rotate_about`
and the projection onto the sample's own ``|L|**2``, as the CPU's block loop) or, with a torque,
:func:`tumble.kernels.steppers.splitting_with_torque`. A new method in the tables runs here without a line added.
The frame (moments in units, a splitting's axes relabelled) is prepared by the CPU path's own
:func:`tumble.kernels.methods.kernel_frame`.

What the device computes today: the final state, the stored trajectory (``save_every``), the status (non-finite,
checked every :data:`tumble.kernels.drivers.CHECK_EVERY` steps and at the end as on the CPU; invariant drift
past ``drift_limit``, torque-free) and the steps each sample took. A sample that stops keeps its state, as on the
CPU. Probes, flips, drift records, early stop and torque functions are refused with a ``ValueError`` that starts
``device 'cuda':``. The implicit midpoint rule runs as the CPU's, at most the same fixed number of fixed-point sweeps
per step (:func:`tumble.kernels.steppers.implicit_midpoint_sample`).

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_kernels`). With ``NUMBA_ENABLE_CUDASIM=1`` (set before numba is imported) the
kernels run on numba-cuda's simulator, which executes the kernel body in Python and the ``@jit`` functions it
calls as compiled CPU code.
"""

import math

import numpy as np
from numba import cuda

from ..registry import STATUS_DRIFT, STATUS_NONFINITE, STATUS_OK
from . import fused, steppers, tableaux
from .drivers import CHECK_EVERY
from .jit import cuda_jit
from .methods import Observed, from_kernel_frame, kernel_frame
from .steppers import TORQUE_CONSTANT, energy, l_squared, splitting_free_sample, splitting_with_torque

__all__ = ["THREADS", "kernel", "make_kernel", "refusal", "run"]

#: Threads per block of a launch (one sample each).
THREADS = 128

_NOT_YET = "not yet on the device"
_NO_TORQUE = (0.0, 0.0, 0.0, 0.0)  # the torque argument of a torque-free kernel (never read)


def refusal(method, *, torque_fn=None, probe_steps=None, max_flips=0, drift=False, stop_norm=0.0, stop_flips=0):
    """The one-line reason why a run cannot go to the device, or None when it can."""
    if torque_fn is not None:
        return ("device 'cuda': a Python torque function cannot run on the device; use a constant torque or a "
                "named profile (constant, ramp, sine, pulse)")
    asked = [name for name, on in (("probe times", probe_steps is not None), ("flips", max_flips > 0),
                                   ("drift records", drift), ("early stop", stop_norm > 0 or stop_flips > 0)) if on]
    if asked:
        return f"device 'cuda': observing {', '.join(asked)} is {_NOT_YET}; run it with device='cpu'"
    return None


def make_kernel(method, torque_free):
    # size: the closure holds the one kernel below (see there)
    """The device kernel of ``method``, torque-free or with a built-in torque profile: one thread per sample.

    The step is the CPU's: a Runge–Kutta method's generated ``<name>_sample``; a splitting's table (its sub-flows
    without the torque ones when torque-free) run by :func:`tumble.kernels.steppers.splitting_free_sample` or
    :func:`tumble.kernels.steppers.splitting_with_torque`. ``splitting`` and ``torque_free`` are constants of the
    closure, so numba compiles only the branch the kernel takes.
    """
    coefficients = method.coefficients
    splitting = isinstance(coefficients, tableaux.Splitting)
    sample = flows = fractions = None
    if splitting:
        table = coefficients.without_torque() if torque_free else coefficients
        flows, fractions = table.flows, table.fractions
    else:
        # generated from the tableau (kernels/codegen.py); the implicit midpoint rule's is written by hand
        sample = getattr(fused, f"{method.name}_sample", None) or steppers.implicit_midpoint_sample

    @cuda_jit
    def propagate(w, body, t0, h, n_steps, save_every, saved, status, steps_taken, drift_limit, torque_kind,
                  torque_params):
        # size: a kernel's flat arguments (DESIGN.md: arrays and scalars below the kernels' door), packed by run(),
        # and one time loop with its status checks and stores, as the CPU driver's
        """Advance sample ``cuda.grid(1)`` by ``n_steps`` steps of ``h`` from ``t0``; the arguments are those of
        :func:`tumble.kernels.drivers.make_propagate`'s driver that the device serves (:func:`run` packs them)."""
        i = cuda.grid(1)
        if i >= w.shape[1]:
            return
        w1, w2, w3 = w[0, i], w[1, i], w[2, i]
        target = l_squared(w1, w2, w3, body)
        e0 = energy(w1, w2, w3, body)
        store = saved.shape[0] > 0
        slot = 0
        if store:
            saved[0, 0, i], saved[0, 1, i], saved[0, 2, i] = w1, w2, w3
            slot = 1
        code = STATUS_OK
        ran = 0
        for k in range(n_steps):
            t = t0 + k * h
            if splitting and torque_free:
                w1, w2, w3 = splitting_free_sample(w1, w2, w3, h, body, target, flows, fractions)
            elif splitting:
                w1, w2, w3 = splitting_with_torque(w1, w2, w3, t, h, body, flows, fractions, torque_kind,
                                                   torque_params, None)
            elif torque_free:
                w1, w2, w3 = sample(w1, w2, w3, t, h, body, torque_kind, None, None)
            else:
                w1, w2, w3 = sample(w1, w2, w3, t, h, body, torque_kind, torque_params, None)
            ran = k + 1
            if drift_limit > 0.0:
                de = abs(energy(w1, w2, w3, body) / e0 - 1.0)
                dl = abs(l_squared(w1, w2, w3, body) / target - 1.0)
                if not (de <= drift_limit and dl <= drift_limit):
                    code = STATUS_DRIFT
            if code == STATUS_OK and (ran % CHECK_EVERY == 0 or ran == n_steps):
                if not (math.isfinite(w1) and math.isfinite(w2) and math.isfinite(w3)):
                    code = STATUS_NONFINITE
            if store and (ran % save_every == 0 or ran == n_steps):
                saved[slot, 0, i], saved[slot, 1, i], saved[slot, 2, i] = w1, w2, w3
                slot += 1
            if code != STATUS_OK:
                break
        if store:  # a sample that stopped keeps its state for the rest of its trajectory, as on the CPU
            for k in range(ran, n_steps):
                if (k + 1) % save_every == 0 or k + 1 == n_steps:
                    saved[slot, 0, i], saved[slot, 1, i], saved[slot, 2, i] = w1, w2, w3
                    slot += 1
        w[0, i], w[1, i], w[2, i] = w1, w2, w3
        status[i] = code
        steps_taken[i] = ran

    return propagate


_KERNELS = {}


def kernel(method, torque_free):
    """The device kernel of ``method`` (:func:`make_kernel`, made once; compiled on its first launch)."""
    key = (method.name, torque_free)
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(method, torque_free)
    return _KERNELS[key]


def run(method, w, moments, t0, h, n_steps, *, save_every=0, axis=0, norm_weights=None, probe_steps=None,
        max_flips=0, drift=False, stop_norm=0.0, stop_flips=0, drift_limit=0.0, torque_kind=TORQUE_CONSTANT,
        torque_params=None, torque_fn=None, block=None):
    # size: the keywords of tumble.kernels.methods.run, so that the engine calls either the same way
    """:func:`tumble.kernels.methods.run` on the device: the same arguments and the same :class:`Observed`.

    ``axis``, ``norm_weights`` and ``block`` are not used (no transverse norm is observed; a thread is a
    sample). Raises ``ValueError`` (``device 'cuda': ...``) for what the device does not do yet
    (:func:`refusal`).
    """
    problem = refusal(method, torque_fn=torque_fn, probe_steps=probe_steps, max_flips=max_flips, drift=drift,
                      stop_norm=stop_norm, stop_flips=stop_flips)
    if problem:
        raise ValueError(problem)
    n = w.shape[1]
    torque_free = torque_params is None
    kernel_w, constants, torque_params, relabel = kernel_frame(method, w, moments, torque_params, None)
    n_saved = 0
    if save_every > 0:
        n_saved = 1 + n_steps // save_every + (1 if n_steps % save_every else 0)
    device_w = cuda.to_device(np.ascontiguousarray(kernel_w))
    saved = cuda.device_array((n_saved, 3, n)) if n_saved else cuda.device_array((0, 3, 1))
    status = cuda.device_array(n, dtype=np.int8)
    steps_taken = cuda.device_array(n, dtype=np.int64)
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    params = _NO_TORQUE if torque_free else tuple(float(x) for x in torque_params)
    kernel(method, torque_free)[-(-n // threads), threads](
        device_w, constants, float(t0), float(h), int(n_steps), int(save_every), saved, status, steps_taken,
        float(drift_limit) if torque_free else 0.0, int(torque_kind), params)
    w[:] = from_kernel_frame(relabel, device_w.copy_to_host())
    out = from_kernel_frame(relabel, saved.copy_to_host(), axis=1) if n_saved else None
    return Observed(out, None, None, None, None, status.copy_to_host(), steps_taken.copy_to_host())
