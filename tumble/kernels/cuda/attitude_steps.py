"""The attitude on a CUDA device: angular velocity and orientation together, one thread per sample (issue 28).

Written once: a thread runs the CPU's own time loop (:func:`tumble.kernels.steps.attitude.run_sample`) on its sample's
seven-component state ``(w, q)`` (a local array), with the CPU's own steps of :mod:`tumble.kernels.steps.attitude` (:func:`~tumble.kernels.steps.attitude.runge_kutta_step` from the Butcher tableau,
:func:`~tumble.kernels.steps.attitude.splitting_step` from the splitting's table,
:func:`~tumble.kernels.steps.attitude.midpoint_step`), which numba-cuda compiles for the device; the method's coefficients
are arrays on the device, and its frame is the CPU's
(:func:`tumble.kernels.loops.methods.attitude_frame`). :func:`run_attitude` takes
:func:`tumble.kernels.run_attitude`'s arguments and returns the same arrays: the stored angular velocities and
quaternions and the status (non-finite: checked after every step; such a sample stops and keeps its state). A
Python torque function is refused by :func:`tumble.kernels.cuda.rigid_body.refusal` (``device 'cuda': ...``).

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_attitude`). On numba-cuda's simulator the kernel body runs in Python and the ``@jit``
steps it calls as compiled CPU code (the local arrays and the constants are numpy arrays there).
"""

import numpy as np
from numba import cuda, float64

from ..steps.attitude import run_sample
from .rigid_body import refusal
from .launch import THREADS, launch_shape, loop_array
from ..jit import cuda_jit
from ..loops.methods import attitude_frame, attitude_spin_scale, from_attitude_frame
from ..steps.steppers import TORQUE_CONSTANT

__all__ = ["THREADS", "kernel", "make_kernel", "run_attitude"]

def make_kernel(frame, torque_free):
    """The device kernel of an attitude run of the method and family of ``frame``
    (:func:`tumble.kernels.loops.methods.attitude_frame`), torque-free or with a built-in torque profile: one thread per
    sample, running the CPU's time loop (:func:`tumble.kernels.steps.attitude.run_sample`) with its scratch in the thread's
    local memory. ``torque_free`` and the number of stages are constants of the closure."""
    n_stages = max(1, frame.b.shape[0])

    @cuda_jit
    def propagate(family, A, b, c, flows, fractions, axes, sign, w, q, body, t0, h, n_steps, save_every, saved_w,
                  saved_q, status, torque_kind, torque_params):
        """Advance sample ``cuda.grid(1)``'s ``(w, q)``; the arguments are
        :func:`tumble.kernels.steps.attitude.propagate_attitude`'s, :func:`run_attitude` packs them."""
        i = cuda.grid(1)
        if i >= w.shape[0]:
            return
        run = (i, family, loop_array(A), loop_array(b), loop_array(c), loop_array(flows), loop_array(fractions),
               loop_array(axes), sign, loop_array(w), loop_array(q), body, t0, h, n_steps, save_every,
               loop_array(saved_w), loop_array(saved_q), loop_array(status), torque_kind)
        scratch = (cuda.local.array(7, float64), cuda.local.array((n_stages, 7), float64),
                   cuda.local.array(7, float64))
        if torque_free:  # a constant: numba compiles one of the two
            run_sample(*run, None, None, *scratch)
        else:
            run_sample(*run, loop_array(torque_params), None, *scratch)

    return propagate


_KERNELS = {}


def kernel(method, frame, torque_free):
    """The device kernel of an attitude run of ``method`` (:func:`make_kernel`, made once per method and torque-free
    or not; compiled on its first launch)."""
    key = (method.name, torque_free)
    if key not in _KERNELS:
        _KERNELS[key] = make_kernel(frame, torque_free)
    return _KERNELS[key]


_NO_TORQUE = np.zeros(4)  # the torque argument of a torque-free kernel (never read)


def run_attitude(method, w, q, moments, t0, h, n_steps, *, save_every, torque_kind=TORQUE_CONSTANT,
                 torque_params=None, torque_fn=None):
    # size: the keywords of tumble.kernels.run_attitude, so that the engine calls either the same way
    """:func:`tumble.kernels.run_attitude` on the device: the same arguments and returns
    (``saved_w`` (N, n_saved, 3), ``saved_q`` (N, n_saved, 4), ``status`` (N,) int8). Raises ``ValueError``
    (``device 'cuda': ...``) for a Python torque function."""
    problem = refusal(method, torque_fn=torque_fn)
    if problem:
        raise ValueError(problem)
    w, t0, h, unit = attitude_spin_scale(w, t0, h, torque_params is None)  # as the CPU's, beyond 2**±256 rad/s
    frame = attitude_frame(method, w, moments, torque_params, None, n_steps, save_every)
    n = w.shape[0]
    saved_w = cuda.device_array((frame.n_saved, n, 3))
    saved_q = cuda.device_array((frame.n_saved, n, 4))
    status = cuda.device_array(n, dtype=np.int8)
    torque_free = frame.torque_params is None
    kernel(method, frame, torque_free)[launch_shape(n)](
        frame.family, cuda.to_device(frame.A), cuda.to_device(frame.b), cuda.to_device(frame.c),
        cuda.to_device(frame.flows), cuda.to_device(frame.fractions),
        cuda.to_device(np.asarray(frame.axes, dtype=np.int64)), frame.sign, cuda.to_device(frame.w),
        cuda.to_device(np.ascontiguousarray(q, dtype=float)), frame.body, float(t0), float(h), int(n_steps),
        int(save_every), saved_w, saved_q, status, int(torque_kind),
        cuda.to_device(_NO_TORQUE if torque_free else np.ascontiguousarray(frame.torque_params, dtype=float)))
    return (from_attitude_frame(frame, saved_w.copy_to_host() / unit), saved_q.copy_to_host().transpose(1, 0, 2),
            status.copy_to_host())
