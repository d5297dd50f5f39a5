"""Orientation alongside the angular velocity, for every fixed-step method.

The attitude is the unit quaternion ``q = (q0, q1, q2, q3)``, scalar first, of the body-to-space rotation
(``v_space = q v_body q*``); it obeys ``q' = ½ q ⊗ (0, w)`` with ``w`` the body-frame angular velocity.
Each method family carries it in the way that keeps its own structure:

* **Runge–Kutta** (``rk4``, ``rk8``): the seven-component state ``(w, q)`` is stepped with the method's
  Butcher tableau and ``q`` is renormalised after every step (the RK step keeps ``|q|`` only to the method's
  order).
* **Splittings** (``symplectic_euler``, ``splitting2``, ``splitting4``): each exact sub-flow of
  ``H_a = L_a² / (2 I_a)`` turns ``L`` by ``-theta`` about body axis ``a`` and the body by ``+theta`` about the
  same axis, ``theta = w_a tau``, so ``q <- q ⊗ (cos(theta/2), sin(theta/2) e_a)``: the angular momentum in
  space, ``q L q*``, is kept to round-off. The torque sub-flow does not turn the body.
* **Implicit midpoint**: with ``z`` the midpoint angular velocity, ``q <- q ⊗ (1, h z / 2) / |(1, h z / 2)|``,
  the Cayley rotation ``cay(h ẑ)``. The midpoint rule maps ``L`` by ``cay(-h ẑ)`` (its linear algebra is
  ``(1 + h ẑ/2) L1 = (1 - h ẑ/2) L0``), so ``q L q*`` is again kept to round-off.

These are per-sample scalar loops (a share of the samples per thread), separate from the SIMD ensemble drivers of
:mod:`tumble.kernels.loops.drivers`: a run that does not ask for the attitude never compiles or runs this code.
The coefficients are the same tables (:mod:`tumble.kernels.tableaux`); the angular velocity of an attitude
run follows the same arithmetic as the SIMD kernels up to rounding.
"""

import math

import numpy as np
from ..jit import jit
from .steppers import (_EPS, _MIDPOINT_MAX_ITERATIONS, _MIDPOINT_ULPS, euler_rate, l_squared, project_l_squared, rotate,
                       torque_subflow)
from ..tableaux import ROTATE_1, ROTATE_2, ROTATE_3
from ..trig import _max, sincos

FAMILY_RUNGE_KUTTA = 0
FAMILY_SPLITTING = 1
FAMILY_MIDPOINT = 2

STATUS_OK = 0
STATUS_NONFINITE = 1


@jit(inline=True)
def quaternion_product(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product ``a ⊗ b`` (scalar first)."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@jit(inline=True)
def attitude_rate(q0, q1, q2, q3, w1, w2, w3):
    """``q' = ½ q ⊗ (0, w)``, 1/s."""
    return (0.5 * (-q1 * w1 - q2 * w2 - q3 * w3),
            0.5 * (q0 * w1 + q2 * w3 - q3 * w2),
            0.5 * (q0 * w2 - q1 * w3 + q3 * w1),
            0.5 * (q0 * w3 + q1 * w2 - q2 * w1))


@jit(inline=True)
def _normalised(y):
    """Scale ``y[3:7]`` (the quaternion) to unit length."""
    size = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5] + y[6] * y[6])
    for j in range(3, 7):
        y[j] /= size


@jit
def runge_kutta_step(y, t, h, A, b, c, k, stage, body, torque_kind, torque_params, torque_fn):
    """One explicit Runge–Kutta step of ``y = (w1, w2, w3, q0, q1, q2, q3)`` in place; ``k`` (s, 7) and
    ``stage`` (7,) are scratch."""
    n_stages = b.shape[0]
    for s in range(n_stages):
        for j in range(7):
            acc = y[j]
            for r in range(s):
                acc += (A[s, r] * h) * k[r, j]
            stage[j] = acc
        k[s, 0], k[s, 1], k[s, 2] = euler_rate(t + c[s] * h, stage[0], stage[1], stage[2], body, torque_kind,
                                               torque_params, torque_fn)
        k[s, 3], k[s, 4], k[s, 5], k[s, 6] = attitude_rate(stage[3], stage[4], stage[5], stage[6], stage[0],
                                                           stage[1], stage[2])
    for j in range(7):
        acc = 0.0
        for s in range(n_stages):
            acc += (b[s] * h) * k[s, j]
        y[j] += acc
    _normalised(y)


@jit(inline=True)
def _turn(q0, q1, q2, q3, theta, axis, sign):
    """``q ⊗ (cos(theta/2), sin(theta/2) sign e_axis)``: the body turns by ``sign theta`` about its axis
    ``axis`` (0-based)."""
    s, c = sincos(0.5 * theta)
    s *= sign
    return quaternion_product(q0, q1, q2, q3, c, s if axis == 0 else 0.0, s if axis == 1 else 0.0,
                              s if axis == 2 else 0.0)


@jit
def splitting_step(y, t, h, flows, fractions, axes, sign, body, target, torque_kind, torque_params, torque_fn):
    """One step of a splitting (``flows``, ``fractions``) of ``y = (w, q)`` in place.

    ``w`` is in the kernel's frame, whose axis ``a`` is the body's axis ``axes[a]`` taken with ``sign`` (the
    splittings turn about the axes by ascending moment, :mod:`tumble.kernels.loops.methods`); ``q`` stays the
    attitude of the body's own axes. Torque-free runs end on the sample's own ``|L|²`` (``target``), as the
    ensemble kernels do.
    """
    clock = t
    w1, w2, w3 = y[0], y[1], y[2]
    q0, q1, q2, q3 = y[3], y[4], y[5], y[6]
    for i in range(flows.shape[0]):
        tau = fractions[i] * h
        flow = flows[i]
        if flow == ROTATE_1:
            theta = w1 * tau
            w2, w3 = rotate(theta, w2, w3, body[9], body[11])
        elif flow == ROTATE_2:
            theta = w2 * tau
            w3, w1 = rotate(theta, w3, w1, body[10], body[7])
        elif flow == ROTATE_3:
            theta = w3 * tau
            w1, w2 = rotate(theta, w1, w2, body[6], body[8])
        else:
            if torque_params is not None:
                w1, w2, w3 = torque_subflow(clock, tau, w1, w2, w3, body, torque_kind, torque_params, torque_fn)
                clock += tau
            continue
        q0, q1, q2, q3 = _turn(q0, q1, q2, q3, theta, axes[flow], sign)
    if torque_params is None:
        w1, w2, w3 = project_l_squared(w1, w2, w3, target, body)
    y[0], y[1], y[2] = w1, w2, w3
    y[3], y[4], y[5], y[6] = q0, q1, q2, q3
    _normalised(y)


@jit
def midpoint_step(y, t, h, body, torque_kind, torque_params, torque_fn):
    """One implicit-midpoint step of ``y = (w, q)`` in place (fixed-point iteration as
    :func:`tumble.kernels.steps.steppers.implicit_midpoint_block`; NaN when it does not converge)."""
    half = 0.5 * h
    tm = t + half
    z1, z2, z3 = y[0], y[1], y[2]
    done = False
    for _ in range(_MIDPOINT_MAX_ITERATIONS):
        f1, f2, f3 = euler_rate(tm, z1, z2, z3, body, torque_kind, torque_params, torque_fn)
        n1, n2, n3 = y[0] + half * f1, y[1] + half * f2, y[2] + half * f3
        change = abs(n1 - z1) + abs(n2 - z2) + abs(n3 - z3)
        size = abs(n1) + abs(n2) + abs(n3)
        z1, z2, z3 = n1, n2, n3
        if not change > _MIDPOINT_ULPS * _EPS * size:  # converged (or NaN: stop, caught by the caller)
            done = True
            break
    if not done:
        for j in range(7):
            y[j] = math.nan
        return
    y[0], y[1], y[2] = 2.0 * z1 - y[0], 2.0 * z2 - y[1], 2.0 * z3 - y[2]
    v1, v2, v3 = half * z1, half * z2, half * z3
    scale = 1.0 / math.sqrt(1.0 + v1 * v1 + v2 * v2 + v3 * v3)
    y[3], y[4], y[5], y[6] = quaternion_product(y[3], y[4], y[5], y[6], scale, scale * v1, scale * v2, scale * v3)
    _normalised(y)


@jit
def run_sample(i, family, A, b, c, flows, fractions, axes, sign, w, q, body, t0, h, n_steps, save_every, saved_w,
               saved_q, status, torque_kind, torque_params, torque_fn, y, k, stage):
    # size: the attitude's one time loop, on either device: flat arrays and scalars, the sample's scratch owned by the
    # caller
    """Sample ``i`` through the whole run: the attitude's one time loop, for the CPU (:func:`propagate_attitude`, a
    loop over a share of the samples) and the device (:mod:`tumble.kernels.cuda.attitude_steps`, one thread per sample). The scratch,
    owned by the caller: ``y`` (7,) the state ``(w, q)``, ``k`` (stages, 7) and ``stage`` (7,) the Runge–Kutta
    stages; the other arguments are :func:`propagate_attitude`'s."""
    y[0], y[1], y[2] = w[i, 0], w[i, 1], w[i, 2]
    y[3], y[4], y[5], y[6] = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    target = l_squared(y[0], y[1], y[2], body)
    code = STATUS_OK
    _store(saved_w, saved_q, 0, i, y)
    slot = 1
    for step in range(n_steps):
        if code == STATUS_OK:
            t = t0 + step * h
            if family == FAMILY_RUNGE_KUTTA:
                runge_kutta_step(y, t, h, A, b, c, k, stage, body, torque_kind, torque_params, torque_fn)
            elif family == FAMILY_SPLITTING:
                splitting_step(y, t, h, flows, fractions, axes, sign, body, target, torque_kind, torque_params,
                               torque_fn)
            else:
                midpoint_step(y, t, h, body, torque_kind, torque_params, torque_fn)
            for j in range(7):
                if not math.isfinite(y[j]):
                    code = STATUS_NONFINITE
        ran = step + 1
        if ran % save_every == 0 or ran == n_steps:
            _store(saved_w, saved_q, slot, i, y)
            slot += 1
    for j in range(3):
        w[i, j] = y[j]
    for j in range(4):
        q[i, j] = y[3 + j]
    status[i] = code


@jit
def _store(saved_w, saved_q, slot, i, y):
    """Sample ``i``'s state ``y`` into ``saved_w[slot, i]`` and ``saved_q[slot, i]``."""
    for j in range(3):
        saved_w[slot, i, j] = y[j]
    for j in range(4):
        saved_q[slot, i, j] = y[3 + j]


@jit
def propagate_attitude(family, A, b, c, flows, fractions, axes, sign, w, q, body, t0, h, n_steps, save_every, saved_w,
                       saved_q, status, torque_kind, torque_params, torque_fn, start, stop):
    # size: flat arrays and scalars (numba): the method's tableau, the state, the torque
    """Advance every sample's angular velocity and attitude ``n_steps`` fixed steps of size ``h``: the CPU's wrapper of
    the one time loop (:func:`run_sample`) for the samples ``start:stop`` (one share of
    :func:`tumble.kernels.threads.in_parallel`).

    Parameters
    ----------
    family : int
        ``FAMILY_RUNGE_KUTTA`` (uses ``A``, ``b``, ``c``), ``FAMILY_SPLITTING`` (uses ``flows``,
        ``fractions``) or ``FAMILY_MIDPOINT``.
    axes, sign : ndarray (3,) int64, float
        The body axis (0-based) of each kernel axis and the sign of the relabelling (splittings only;
        ``w`` is in the kernel's frame, ``q`` is the attitude of the body's own axes).
    w : ndarray, shape (N, 3)
        Body-frame angular velocity, rad/s; overwritten with the final state.
    q : ndarray, shape (N, 4)
        Unit quaternion (scalar first) of the body-to-space rotation; overwritten with the final state.
    body : tuple
        :func:`tumble.kernels.steps.steppers.body_constants` of the moments.
    save_every, saved_w, saved_q : int, ndarray (n_saved, N, 3), ndarray (n_saved, N, 4)
        The initial state, every ``save_every``-th state and the final one.
    status : ndarray (N,) int8
        Output: ``STATUS_NONFINITE`` where a sample became NaN or inf; such a sample stops stepping.
    """
    y, k, stage = np.empty(7), np.empty((_max(1, b.shape[0]), 7)), np.empty(7)
    for i in range(start, stop):
        run_sample(i, family, A, b, c, flows, fractions, axes, sign, w, q, body, t0, h, n_steps, save_every, saved_w,
                   saved_q, status, torque_kind, torque_params, torque_fn, y, k, stage)
