"""The closed form of the torque-free motion on a CUDA device: one thread per sample, float64 (issue 28).

Written once: a thread runs the CPU's own per-sample functions of :mod:`tumble.kernels.closed_form.elliptic` (and of
:mod:`tumble.kernels.closed_form.elliptic_attitude`), which numba-cuda compiles for the device.

* :func:`omega_at`, one time: :func:`tumble.kernels.closed_form.elliptic._omega_at_sample`, the scalar path of the CPU's fused
  one-time kernel (the invariants, the set-up and ``sn, cn, dn`` of ``nu t`` moved to the spin by Jacobi's addition
  theorem; no initial argument). The CPU's :func:`~tumble.kernels.closed_form.elliptic.torque_free_omega_at` runs the same
  formulas in SIMD lanes; the two agree to a few ulps of ``|w|``.
* :func:`omega_grid`, a time grid: the per-sample code of the CPU's set-up and evaluation
  (:func:`~tumble.kernels.closed_form.elliptic.torque_free_solve`, :func:`~tumble.kernels.closed_form.elliptic.torque_free_omega`): the set-up of the thread's sample
  (:func:`~tumble.kernels.closed_form.elliptic._solve_sample`, into local arrays of one sample), then its row of values at every
  time (:func:`~tumble.kernels.closed_form.elliptic._omega_row`: the descending Landen transformations, or the hyperbolic series
  near the separatrix, with the per-modulus constants computed once per sample; ``sech, tanh`` on it).
* :func:`attitude_rows`, the attitude on a time grid: the set-up as :func:`omega_grid`'s, the angular velocity at
  ``t = 0`` and at each time by the row's cores, one time at a time (:func:`~tumble.kernels.closed_form.elliptic._sncndn_once`),
  and from them the CPU's per-sample attitude code (:func:`tumble.kernels.closed_form.elliptic_attitude.attitude_constants` once,
  :func:`~tumble.kernels.closed_form.elliptic_attitude.attitude_at` at each time: Carlson's ``R_F`` and ``R_J``, the Landen tables in local arrays).
* :func:`omega_rows_phase_fit`: :func:`omega_rows` whose states stay on the device, where the CPU's per-sample phase
  fit runs on them (:mod:`tumble.kernels.cuda.phase_fit`); only the fits come back.

They return ``(out, tiny, non_finite)`` as the CPU kernels do: the number of spins too close to a principal axis
for the invariants (:data:`tumble.kernels.closed_form.elliptic.TINY_TRANSVERSE`; the caller lifts them) and of samples with a
non-finite value.

This module imports ``numba.cuda``; it is imported only when a run asks for ``device="cuda"``
(:func:`tumble.kernels.device_closed_form`). On numba-cuda's simulator the kernel body runs in Python and the
``@jit`` functions it calls as compiled CPU code (the local arrays are numpy arrays there).
"""

import math

import numpy as np
from numba import cuda, float64, int64

from ..closed_form.elliptic import (KIND_ELLIPTIC, KIND_SEPARATRIX, _column_weights, _count_non_finite,
                                    _omega_at_sample, _omega_row, _sech_tanh, _sncndn_once, _solve_sample, _store)
from .launch import THREADS, launch_shape, loop_array
from ..closed_form.elliptic_attitude import CONSTANTS, LANDEN, attitude_at, attitude_constants
from ..jit import cuda_jit, jit

__all__ = ["THREADS", "attitude_rows", "omega_at", "omega_grid", "omega_rows", "omega_rows_phase_fit"]


_TINY, _NON_FINITE = 1, 2  # bits of a sample's flag


@cuda_jit
def _omega_at_kernel(m0, m1, m2, w, t, out, flags):
    """Sample ``cuda.grid(1)``'s angular velocity at time ``t`` into ``out[i]`` and its flag bits."""
    i = cuda.grid(1)
    if i >= w.shape[0]:
        return
    v0, v1, v2, small = _omega_at_sample(m0, m1, m2, w[i, 0], w[i, 1], w[i, 2], t)
    out[i, 0], out[i, 1], out[i, 2] = v0, v1, v2
    finite = math.isfinite(v0) and math.isfinite(v1) and math.isfinite(v2)
    flags[i] = (_TINY if small else 0) | (0 if finite else _NON_FINITE)


@cuda.jit(device=True)
def _grid_setup(bodies, w, row, i):
    """The set-up of :func:`tumble.kernels.closed_form.elliptic.torque_free_solve` for sample ``i`` of a grid kernel (its body's
    moments ``bodies[r]``, ``r = row[i]``, or row 0 when ``row`` has one element; the one-sample arrays made local):
    ``(r, tiny, kind, weights, k_c, K, phase0, nu, h, q, amplitudes (3,), columns (3,))``, what the grid kernels
    evaluate from."""
    r = row[i] if row.shape[0] == w.shape[0] else 0
    m0, m1, m2 = bodies[r, 0], bodies[r, 1], bodies[r, 2]
    spin = cuda.local.array(3, float64)
    spin[0], spin[1], spin[2] = w[i, 0], w[i, 1], w[i, 2]
    moments = cuda.local.array((1, 3), float64)
    perm = cuda.local.array((1, 3), int64)
    parity = cuda.local.array(1, float64)
    scaled = cuda.local.array((5, 1), float64)
    kind = cuda.local.array(1, int64)
    amp = cuda.local.array((1, 3), float64)
    cols = cuda.local.array((1, 3), int64)
    params = cuda.local.array((5, 1), float64)
    nome = cuda.local.array((2, 1), float64)
    small = _solve_sample(0, m0, m1, m2, spin, moments, perm, parity, scaled, kind, amp, cols, params, nome)
    weights = _column_weights(cols[0, 0], cols[0, 1], cols[0, 2], amp[0, 0], amp[0, 1], amp[0, 2])
    return (r, small, kind[0], weights, params[0, 0], params[2, 0], params[3, 0], params[4, 0], nome[0, 0], nome[1, 0],
            (amp[0, 0], amp[0, 1], amp[0, 2]), (cols[0, 0], cols[0, 1], cols[0, 2]))


@cuda_jit
def _omega_grid_kernel(bodies, w, times, row, out, flags):
    """Sample ``cuda.grid(1)`` set up, then evaluated at every time of its grid into ``out[i]`` (3T,: the (T, 3)
    values flat) by the CPU grid kernel's own per-sample row (:func:`tumble.kernels.closed_form.elliptic._omega_row`, after the
    same set-up): its body's moments are ``bodies[r]`` and its times ``times[r]``, ``r = row[i]`` (``row`` of one
    element: every sample ``r = 0``), so that the samples of many scenes go in one launch."""
    i = cuda.grid(1)
    if i >= w.shape[0]:
        return
    r, small, kind, weights, k_c, K, phase0, nu, h, q, _, _ = _grid_setup(bodies, w, row, i)
    o = loop_array(out)[i]
    _omega_row(kind, k_c, K, h, q, phase0, nu, loop_array(times)[r], o, weights)
    flags[i] = (_TINY if small else 0) | (_NON_FINITE if _count_non_finite(o) else 0)


@jit
def _grid_value(kind, s, k_c, K, h, q, weights, value):
    """A grid kernel's angular velocity at phase ``s`` (``phase0 + nu t``) into ``value`` (3,): ``sn, cn, dn`` of
    ``K + s`` by the CPU grid kernel's cores, ``sech, tanh`` on the separatrix, the constant parts of a steady spin."""
    if kind == KIND_ELLIPTIC:
        sn, cn, dn = _sncndn_once(s, k_c, K, h, q)
        _store(value, 0, weights, cn, sn, dn)
    elif kind == KIND_SEPARATRIX:
        sech, tanh = _sech_tanh(s)
        _store(value, 0, weights, sech, tanh, sech)
    else:
        _store(value, 0, weights, 1.0, 1.0, 1.0)


@cuda_jit
def _attitude_grid_kernel(bodies, w, times, row, out, flags):
    # size: the set-up (_grid_setup), the attitude constants with their Landen tables, then the attitude at each time
    """The closed form's attitude: sample ``cuda.grid(1)`` set up (as :func:`_omega_grid_kernel`), its angular
    velocity evaluated at ``t = 0`` and at each time of its grid, and from them the CPU's per-sample attitude
    (:func:`tumble.kernels.closed_form.elliptic_attitude.attitude_constants`, :func:`~tumble.kernels.closed_form.elliptic_attitude.attitude_at`)
    into ``out[i]`` (T, 4); ``bodies``, ``times`` and ``row`` as :func:`_omega_grid_kernel` reads them."""
    i = cuda.grid(1)
    if i >= w.shape[0]:
        return
    r, small, kind, weights, k_c, K, phase0, nu, h, q, amp, cols = _grid_setup(bodies, w, row, i)
    value = cuda.local.array(3, float64)
    constants = cuda.local.array(CONSTANTS, float64)
    landen_a = cuda.local.array(LANDEN, float64)
    landen_c = cuda.local.array(LANDEN, float64)
    _grid_value(kind, phase0 + nu * 0.0, k_c, K, h, q, weights, value)
    attitude_constants(bodies[r, 0], bodies[r, 1], bodies[r, 2], w[i, 0], w[i, 1], w[i, 2], kind, amp[0], amp[1],
                       cols[0], cols[1], cols[2], k_c, K, phase0, nu, value[0], value[1], value[2], constants,
                       landen_a, landen_c)
    finite = True
    for j in range(times.shape[1]):
        t = times[r, j]
        _grid_value(kind, phase0 + nu * t, k_c, K, h, q, weights, value)
        q0, q1, q2, q3 = attitude_at(constants, landen_a, landen_c, t, value[0], value[1], value[2])
        out[i, j, 0], out[i, j, 1], out[i, j, 2], out[i, j, 3] = q0, q1, q2, q3
        finite = finite and math.isfinite(q0) and math.isfinite(q1) and math.isfinite(q2) and math.isfinite(q3)
    flags[i] = (_TINY if small else 0) | (0 if finite else _NON_FINITE)


def _launch(kernel, n, *args):
    """Launch ``kernel`` over ``n`` samples; returns the flags' counts ``(tiny, non_finite)``."""
    flags = cuda.device_array(n, dtype=np.int8)
    kernel[launch_shape(n)](*args, flags)
    flags = flags.copy_to_host()
    return int(np.count_nonzero(flags & _TINY)), int(np.count_nonzero(flags & _NON_FINITE))


def omega_at(moments, w, t):
    """:func:`tumble.kernels.closed_form.elliptic.torque_free_omega_at` on the device: the body's moments (3,), the spins ``w``
    (n, 3) and the time ``t`` (s) in; ``(out, tiny, non_finite)`` back, ``out`` (n, 3) the angular velocity at
    ``t`` (rad/s) and the counts as the CPU kernel returns them."""
    n = w.shape[0]
    out = cuda.device_array((n, 3))
    tiny, non_finite = _launch(_omega_at_kernel, n, float(moments[0]), float(moments[1]), float(moments[2]),
                               cuda.to_device(np.ascontiguousarray(w, dtype=float)), float(t), out)
    return out.copy_to_host(), tiny, non_finite


def omega_grid(moments, w, times):
    """:func:`tumble.physics.exact.omega` on a time grid, on the device: as :func:`omega_at` at the times
    ``times`` (T,), ``out`` of shape (n, T, 3)."""
    return omega_rows(np.reshape(moments, (1, 3)), w, np.reshape(times, (1, -1)), np.zeros(1, dtype=np.int64))


def omega_rows(bodies, w, times, row):
    """:func:`omega_grid` for the samples of many scenes in one launch: sample ``i`` of the body ``bodies[row[i]]``
    (R, 3) at the times ``times[row[i]]`` (R, T) (``row`` of one element: every sample row 0); ``out`` (n, T, 3)."""
    out, tiny, non_finite = _omega_rows(bodies, w, times, row)
    return out.copy_to_host(), tiny, non_finite


def omega_rows_phase_fit(bodies, w, times, row, columns, weights, floor, max_step):
    """:func:`omega_rows` and the phase fit of each sample's transverse components on the device, where the
    evaluation leaves them (:func:`tumble.kernels.cuda.phase_fit.phase_fit`, the CPU's per-sample fit): ``columns``,
    ``weights`` (n, 2), ``floor`` (n,) and ``max_step`` as :func:`tumble.kernels.fits.phase_fit` takes them. Returns
    ``(fit, tiny, non_finite)``, ``fit`` the ``(frequency, radius, code)`` arrays (n,) each, or None where a sample
    was too close to an axis (``tiny``: the caller evaluates the launch on the CPU); the states never come back."""
    out, tiny, non_finite = _omega_rows(bodies, w, times, row)
    if tiny:
        return None, tiny, non_finite
    from .phase_fit import phase_fit

    return phase_fit(times, row, out, columns, weights, floor, max_step), tiny, non_finite


def attitude_rows(bodies, w, times, row):
    """The closed form's attitude (:func:`tumble.physics.exact.attitude`) on the device, set-up included, for the
    samples of many scenes in one launch (``bodies``, ``w``, ``times``, ``row`` as :func:`omega_rows`): ``(out, tiny,
    non_finite)``, ``out`` (n, T, 4) the body-to-space quaternions (scalar first, ``q(0) = 1``) and the counts as
    :func:`omega_rows` returns them."""
    out, tiny, non_finite = _grid_launch(_attitude_grid_kernel, lambda t: (t, 4), bodies, w, times, row)
    return out.copy_to_host(), tiny, non_finite


def _omega_rows(bodies, w, times, row):
    """:func:`omega_rows` with ``out`` (n, T, 3) left on the device (the kernel writes each sample's values flat)."""
    out, tiny, non_finite = _grid_launch(_omega_grid_kernel, lambda t: (3 * t,), bodies, w, times, row)
    return out.reshape(w.shape[0], -1, 3), tiny, non_finite


def _grid_launch(kernel, sample_shape, bodies, w, times, row):
    """Launch a grid kernel over the samples ``w`` (n, 3): ``(out, tiny, non_finite)``, ``out`` (n, *sample_shape(T))
    left on the device."""
    n = w.shape[0]
    times = np.ascontiguousarray(times, dtype=float)
    out = cuda.device_array((n, *sample_shape(times.shape[1])))
    tiny, non_finite = _launch(kernel, n, cuda.to_device(np.ascontiguousarray(bodies, dtype=float)),
                               cuda.to_device(np.ascontiguousarray(w, dtype=float)), cuda.to_device(times),
                               cuda.to_device(np.ascontiguousarray(row, dtype=np.int64)), out)
    return out, tiny, non_finite
