"""One step of each integrator family on a block of samples.

A block is a structure-of-arrays ``y[axis, sample]`` (shape ``(3, B)``) of body-frame angular velocities.
Every step function updates ``y`` in place, uses only the scratch ``work`` it is given, and loops over
samples innermost so that the compiler can vectorise across them.

Euler's equations with body torque ``N`` (Landau & Lifshitz §36):
``I1 w1' = (I2 - I3) w2 w3 + N1`` and cyclic.

The torque is evaluated by :func:`body_torque`. ``torque_params is None`` means torque-free, and numba prunes
every torque branch at compile time; otherwise ``torque_kind`` picks one of the built-in profiles below, or
``torque_fn`` (a user's jitted ``f(t, w1, w2, w3) -> (N1, N2, N3)``) is called.
"""

import math

from .jit import jit
from .tableaux import TORQUE

# Built-in torque profiles (numeric parameters only, so that studies stay data).
TORQUE_CONSTANT = 0  # params = (N1, N2, N3), N m
TORQUE_USER = -1  # torque_fn is called

# Integrator families run by the generic driver.
FAMILY_EXPLICIT_RK = 0
FAMILY_SPLITTING = 1
FAMILY_IMPLICIT_MIDPOINT = 2

# Implicit midpoint: fixed-point iterations stop once the update is below this many ulps of the state.
_MIDPOINT_ULPS = 4.0
_MIDPOINT_MAX_ITERATIONS = 60
_EPS = 2.220446049250313e-16


@jit
def body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn):
    """Body-frame torque (N m) at time ``t`` (s) and angular velocity ``w`` (rad/s)."""
    if torque_fn is not None:
        return torque_fn(t, w1, w2, w3)
    # TORQUE_CONSTANT (the only built-in profile so far)
    return torque_params[0], torque_params[1], torque_params[2]


@jit
def euler_rhs(z, out, t, moments, torque_kind, torque_params, torque_fn):
    """``out[:, i] = w'`` for every sample ``z[:, i]`` of a block."""
    i1, i2, i3 = moments[0], moments[1], moments[2]
    a1, a2, a3 = (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3
    for i in range(z.shape[1]):
        w1, w2, w3 = z[0, i], z[1, i], z[2, i]
        d1, d2, d3 = a1 * w2 * w3, a2 * w3 * w1, a3 * w1 * w2
        if torque_params is not None:
            n1, n2, n3 = body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn)
            d1 += n1 / i1
            d2 += n2 / i2
            d3 += n3 / i3
        out[0, i], out[1, i], out[2, i] = d1, d2, d3


@jit
def explicit_rk_step(y, work, t, h, moments, A, b, c, torque_kind, torque_params, torque_fn):
    """One explicit Runge–Kutta step. ``work`` has shape ``(s + 1, 3, B)``: the stages and one buffer."""
    stages = b.shape[0]
    n = y.shape[1]
    z = work[stages]
    for s in range(stages):
        # z = y + h * sum_j A[s, j] k_j, with the sum formed before adding to y (less round-off).
        for i in range(n):
            z[0, i] = 0.0
            z[1, i] = 0.0
            z[2, i] = 0.0
        for j in range(s):
            a = A[s, j]
            if a != 0.0:
                k = work[j]
                for i in range(n):
                    z[0, i] += a * k[0, i]
                    z[1, i] += a * k[1, i]
                    z[2, i] += a * k[2, i]
        for i in range(n):
            z[0, i] = y[0, i] + h * z[0, i]
            z[1, i] = y[1, i] + h * z[1, i]
            z[2, i] = y[2, i] + h * z[2, i]
        euler_rhs(z, work[s], t + c[s] * h, moments, torque_kind, torque_params, torque_fn)
    for i in range(n):
        z[0, i] = 0.0
        z[1, i] = 0.0
        z[2, i] = 0.0
    for s in range(stages):
        weight = b[s]
        if weight != 0.0:
            k = work[s]
            for i in range(n):
                z[0, i] += weight * k[0, i]
                z[1, i] += weight * k[1, i]
                z[2, i] += weight * k[2, i]
    for i in range(n):
        y[0, i] += h * z[0, i]
        y[1, i] += h * z[1, i]
        y[2, i] += h * z[2, i]


@jit
def rotate_about_axis(y, axis, tau, moments):
    """Exact flow of ``H_a = L_a**2 / (2 I_a)`` for time ``tau``: ``L`` turns about body axis ``a``.

    With ``(a, b, c)`` cyclic, ``w_a`` is constant and ``(L_b, L_c)`` rotates by ``theta = w_a tau``:
    ``L_b <- cos(theta) L_b + sin(theta) L_c``, ``L_c <- -sin(theta) L_b + cos(theta) L_c``
    (McLachlan 1993). ``|L|`` is kept to round-off.
    """
    a = axis
    b = (axis + 1) % 3
    c = (axis + 2) % 3
    ib, ic = moments[b], moments[c]
    r_cb = ic / ib
    r_bc = ib / ic
    for i in range(y.shape[1]):
        theta = y[a, i] * tau
        cs = math.cos(theta)
        sn = math.sin(theta)
        wb, wc = y[b, i], y[c, i]
        y[b, i] = cs * wb + sn * r_cb * wc
        y[c, i] = cs * wc - sn * r_bc * wb


@jit
def torque_flow(y, t, tau, moments, torque_kind, torque_params, torque_fn):
    """Torque sub-flow ``w' = N(t, w) / I`` over ``tau`` by one classical RK4 step per sample.

    Exact for a constant torque; its local error O(tau**5) keeps the documented order of every composition
    up to four.
    """
    i1, i2, i3 = moments[0], moments[1], moments[2]
    half = 0.5 * tau
    for i in range(y.shape[1]):
        w1, w2, w3 = y[0, i], y[1, i], y[2, i]
        a1, a2, a3 = body_torque(t, w1, w2, w3, torque_kind, torque_params, torque_fn)
        b1, b2, b3 = body_torque(t + half, w1 + half * a1 / i1, w2 + half * a2 / i2, w3 + half * a3 / i3,
                                 torque_kind, torque_params, torque_fn)
        c1, c2, c3 = body_torque(t + half, w1 + half * b1 / i1, w2 + half * b2 / i2, w3 + half * b3 / i3,
                                 torque_kind, torque_params, torque_fn)
        d1, d2, d3 = body_torque(t + tau, w1 + tau * c1 / i1, w2 + tau * c2 / i2, w3 + tau * c3 / i3,
                                 torque_kind, torque_params, torque_fn)
        sixth = tau / 6.0
        y[0, i] = w1 + sixth * (a1 + 2.0 * (b1 + c1) + d1) / i1
        y[1, i] = w2 + sixth * (a2 + 2.0 * (b2 + c2) + d2) / i2
        y[2, i] = w3 + sixth * (a3 + 2.0 * (b3 + c3) + d3) / i3


@jit
def splitting_step(y, target, t, h, moments, axis_order, flows, fractions, torque_kind, torque_params,
                   torque_fn):
    """One step of a composition of exact sub-flows; time advances only inside the torque sub-flow.

    ``axis_order[r]`` is the body axis that rotation sub-flow ``r`` turns about (tumble orders them by
    ascending moment, which measured the smallest errors). Torque-free, every sub-flow keeps ``|L|**2``
    exactly; to stop round-off from random-walking it over millions of steps, the state is rescaled at the end
    of each step onto ``|L|**2 = target`` (each sample's initial value), a projection that moves it by a few
    ulps and leaves the method itself unchanged.
    """
    clock = t
    for j in range(flows.shape[0]):
        flow = flows[j]
        tau = fractions[j] * h
        if flow == TORQUE:
            if torque_params is not None:
                torque_flow(y, clock, tau, moments, torque_kind, torque_params, torque_fn)
            clock += tau
        else:
            rotate_about_axis(y, axis_order[flow], tau, moments)
    if torque_params is None:
        i1, i2, i3 = moments[0], moments[1], moments[2]
        for i in range(y.shape[1]):
            l1, l2, l3 = i1 * y[0, i], i2 * y[1, i], i3 * y[2, i]
            now = l1 * l1 + l2 * l2 + l3 * l3
            scale = math.sqrt(target[i] / now) if now > 0.0 else 1.0
            y[0, i] *= scale
            y[1, i] *= scale
            y[2, i] *= scale


@jit
def implicit_midpoint_step(y, work, t, h, moments, torque_kind, torque_params, torque_fn):
    """Implicit midpoint rule ``y1 = y0 + h f(t + h/2, (y0 + y1)/2)``; keeps every quadratic invariant.

    The midpoint ``z = y0 + (h/2) f(t + h/2, z)`` is found by fixed-point iteration (Hairer, Lubich &
    Wanner, sect. VIII.6); each sample stops iterating once its update is below a few ulps, so its result
    does not depend on its neighbours in the block. Then ``y1 = 2 z - y0``. ``work`` has shape ``(3, 3, B)``.
    """
    z = work[0]
    f = work[1]
    done = work[2, 0]
    n = y.shape[1]
    half = 0.5 * h
    tm = t + half
    for i in range(n):
        z[0, i], z[1, i], z[2, i] = y[0, i], y[1, i], y[2, i]
        done[i] = 0.0
    for _ in range(_MIDPOINT_MAX_ITERATIONS):
        euler_rhs(z, f, tm, moments, torque_kind, torque_params, torque_fn)
        remaining = 0
        for i in range(n):
            if done[i] == 0.0:
                n0 = y[0, i] + half * f[0, i]
                n1 = y[1, i] + half * f[1, i]
                n2 = y[2, i] + half * f[2, i]
                change = abs(n0 - z[0, i]) + abs(n1 - z[1, i]) + abs(n2 - z[2, i])
                size = abs(n0) + abs(n1) + abs(n2)
                z[0, i], z[1, i], z[2, i] = n0, n1, n2
                # A NaN compares false and stops too: a non-finite sample must not keep the loop running.
                if change > _MIDPOINT_ULPS * _EPS * size:
                    remaining += 1
                else:
                    done[i] = 1.0
        if remaining == 0:
            break
    for i in range(n):
        y[0, i] = 2.0 * z[0, i] - y[0, i]
        y[1, i] = 2.0 * z[1, i] - y[1, i]
        y[2, i] = 2.0 * z[2, i] - y[2, i]
