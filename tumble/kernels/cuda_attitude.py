"""The attitude on a CUDA device: angular velocity and orientation together, one thread per sample (issue 28).

Written once: a thread steps its sample's seven-component state ``(w, q)`` (a local array) with the CPU's own steps
of :mod:`tumble.kernels.attitude` (:func:`~tumble.kernels.attitude.runge_kutta_step` from the Butcher tableau,
:func:`~tumble.kernels.attitude.splitting_step` from the splitting's table,
:func:`~tumble.kernels.attitude.midpoint_step`), which numba-cuda compiles for the device; the method's coefficients
are constants of the kernel (constant memory on a GPU), and its frame is the CPU's
(:func:`tumble.kernels.methods.attitude_frame`). :func:`run_attitude` takes
:func:`tumble.kernels.run_attitude`'s arguments and returns the same arrays: the stored angular velocities and
quaternions and the status (non-finite: checked after every step; such a sample stops and keeps its state). A
Python torque function is refused by :func:`tumble.kernels.cuda.refusal` (``device 'cuda': ...``).

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_attitude`). On numba-cuda's simulator the kernel body runs in Python and the ``@jit``
steps it calls as compiled CPU code (the local arrays and the constants are numpy arrays there).
"""

import math

import numpy as np
from numba import cuda, float64

from ..registry import STATUS_NONFINITE, STATUS_OK
from .attitude import FAMILY_RUNGE_KUTTA, FAMILY_SPLITTING, midpoint_step, runge_kutta_step, splitting_step
from .cuda import refusal
from .jit import cuda_jit
from .methods import attitude_frame, from_attitude_frame
from .steppers import TORQUE_CONSTANT, l_squared

__all__ = ["THREADS", "kernel", "make_kernel", "run_attitude"]

#: Threads per block of a launch (one sample each).
THREADS = 128


def make_kernel(frame, torque_free):
    # size: the closure holds the one kernel below (see there)
    """The device kernel of an attitude run of the method and family of ``frame``
    (:func:`tumble.kernels.methods.attitude_frame`), torque-free or with a built-in torque profile. The family, the
    coefficients and ``torque_free`` are constants of the closure."""
    family, A, b, c, flows, fractions = frame.family, frame.A, frame.b, frame.c, frame.flows, frame.fractions
    n_stages = max(1, b.shape[0])

    @cuda_jit
    def propagate(w, q, body, t0, h, n_steps, save_every, saved_w, saved_q, status, axes, sign, torque_kind,
                  torque_params):
        # size: a kernel's flat arguments, packed by run_attitude, and the CPU driver's time loop for one sample
        """Advance sample ``cuda.grid(1)``'s ``(w, q)`` by ``n_steps`` steps of ``h`` from ``t0``, storing the
        initial state, every ``save_every``-th and the last; the arguments are
        :func:`tumble.kernels.attitude.propagate_attitude`'s (``axes`` and the torque's parameters as tuples)."""
        i = cuda.grid(1)
        if i >= w.shape[0]:
            return
        y = cuda.local.array(7, float64)
        k = cuda.local.array((n_stages, 7), float64)
        stage = cuda.local.array(7, float64)
        for j in range(3):
            y[j] = w[i, j]
        for j in range(4):
            y[3 + j] = q[i, j]
        target = l_squared(y[0], y[1], y[2], body)
        code = STATUS_OK
        for j in range(3):
            saved_w[0, i, j] = y[j]
        for j in range(4):
            saved_q[0, i, j] = y[3 + j]
        slot = 1
        for step in range(n_steps):
            if code == STATUS_OK:
                t = t0 + step * h
                if family == FAMILY_RUNGE_KUTTA and torque_free:
                    runge_kutta_step(y, t, h, A, b, c, k, stage, body, torque_kind, None, None)
                elif family == FAMILY_RUNGE_KUTTA:
                    runge_kutta_step(y, t, h, A, b, c, k, stage, body, torque_kind, torque_params, None)
                elif family == FAMILY_SPLITTING and torque_free:
                    splitting_step(y, t, h, flows, fractions, axes, sign, body, target, torque_kind, None, None)
                elif family == FAMILY_SPLITTING:
                    splitting_step(y, t, h, flows, fractions, axes, sign, body, target, torque_kind, torque_params,
                                   None)
                elif torque_free:
                    midpoint_step(y, t, h, body, torque_kind, None, None)
                else:
                    midpoint_step(y, t, h, body, torque_kind, torque_params, None)
                for j in range(7):
                    if not math.isfinite(y[j]):
                        code = STATUS_NONFINITE
            ran = step + 1
            if ran % save_every == 0 or ran == n_steps:
                for j in range(3):
                    saved_w[slot, i, j] = y[j]
                for j in range(4):
                    saved_q[slot, i, j] = y[3 + j]
                slot += 1
        for j in range(3):
            w[i, j] = y[j]
        for j in range(4):
            q[i, j] = y[3 + j]
        status[i] = code

    return propagate


_KERNELS = {}


def kernel(method, frame, torque_free):
    """The device kernel of an attitude run of ``method`` (:func:`make_kernel`, made once per method and torque-free
    or not; compiled on its first launch)."""
    key = (method.name, torque_free)
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(frame, torque_free)
    return _KERNELS[key]


_NO_TORQUE = (0.0, 0.0, 0.0, 0.0)  # the torque argument of a torque-free kernel (never read)


def run_attitude(method, w, q, moments, t0, h, n_steps, *, save_every, torque_kind=TORQUE_CONSTANT,
                 torque_params=None, torque_fn=None):
    # size: the keywords of tumble.kernels.run_attitude, so that the engine calls either the same way
    """:func:`tumble.kernels.run_attitude` on the device: the same arguments and returns
    (``saved_w`` (N, n_saved, 3), ``saved_q`` (N, n_saved, 4), ``status`` (N,) int8). Raises ``ValueError``
    (``device 'cuda': ...``) for a Python torque function."""
    problem = refusal(method, torque_fn=torque_fn)
    if problem:
        raise ValueError(problem)
    frame = attitude_frame(method, w, moments, torque_params, None, n_steps, save_every)
    n = w.shape[0]
    saved_w = cuda.device_array((frame.n_saved, n, 3))
    saved_q = cuda.device_array((frame.n_saved, n, 4))
    status = cuda.device_array(n, dtype=np.int8)
    torque_free = frame.torque_params is None
    params = _NO_TORQUE if torque_free else tuple(float(x) for x in frame.torque_params)
    threads = THREADS if n >= THREADS else 32 * -(-n // 32)
    kernel(method, frame, torque_free)[-(-n // threads), threads](
        cuda.to_device(frame.w), cuda.to_device(np.ascontiguousarray(q, dtype=float)), frame.body, float(t0),
        float(h), int(n_steps), int(save_every), saved_w, saved_q, status, frame.axes, frame.sign, int(torque_kind),
        params)
    return (from_attitude_frame(frame, saved_w.copy_to_host()), saved_q.copy_to_host().transpose(1, 0, 2),
            status.copy_to_host())
