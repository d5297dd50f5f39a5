"""A satellite under the gravity-gradient torque, in a circular or an elliptic orbit.

State: the body-frame angular velocity ``w1 w2 w3`` (rad/s, inertial) and the attitude ``q0 q1 q2 q3`` relative to
the orbit frame (unit quaternion, scalar first; orbit axes: 1 roll along track, 2 pitch = negative orbit normal, 3
yaw = nadir). ``c2``, ``c3`` are the orbit's pitch and nadir axes in the body frame (rows of ``C(q)``). Parameters:
the orbit's mean motion ``n`` (rad/s) and eccentricity ``e`` in [0, 1), perigee at ``t = 0``. With the true anomaly
``ν(t)`` and the radius ``r`` (Kepler's equation ``E − e sin E = n t``; ``a/r = 1/(1 − e cos E)``), the orbit frame
turns at ``ν' = n sqrt(1 − e²) (a/r)²`` and the gradient's strength is ``3 μ/r³ = 3 n² (a/r)³`` (Hughes,
*Spacecraft Attitude Dynamics*, §8.1)::

    I w' = (I w) × w + 3 n² (a/r)³ (c3 × I c3),    q' = ½ q ⊗ (0, w + ν' c2)

In a circular orbit (``e = 0``: ``ν' = n``, ``a/r = 1``, the equations of the circular model to the last bit) the
motion conserves the Jacobi integral ``½ w_r·I w_r + (3/2) n² c3·I c3 − ½ n² c2·I c2`` (``w_r = w + n c2``); an
eccentric orbit makes the torque periodic in time and conserves none (only ``|q|²``). The quaternion is put back
on the unit sphere after every step (:func:`project`, called by the generated block loop): the right-hand side
keeps ``|q|`` only exactly, a Runge–Kutta step only to its order, and ``c2``, ``c3`` are a rotation's only on the
unit sphere.

Per-sample scalar code, as :mod:`tumble.kernels.systems.gyrostat`.
"""

import math
from collections import namedtuple

from ..jit import jit
from ._rigid import RIGID_BODY, rigid_body

__all__ = ["KEPLER_ITERATIONS", "KINDS", "Constants", "constants", "forcing", "invariants", "orbit", "project", "rate",
           "rate_forced", "tangent", "tangent_forced"]

#: The model kinds of ``registry.MODELS`` this module is the system of (its row).
KINDS = ("gravity_gradient",)

#: Newton iterations at most for Kepler's equation (from Danby's start ``E = M + 0.85 e sign(sin M)``): 8 reach
#: round-off for every mean anomaly up to e = 0.99 (4e-16 of ``M``; 6 suffice to e = 0.9), more near e = 1.
KEPLER_ITERATIONS = 64

_TWO_PI = 2.0 * math.pi


#: The rigid body's fields, the mean motion ``n`` (rad/s), ``n²``, ``3 n²`` (1/s²), the eccentricity ``e`` and
#: ``sqrt(1 − e²)``.
Constants = namedtuple("Constants", (*RIGID_BODY, "n", "n2", "three_n2", "e", "root"))


def constants(moments, orbit_rate, eccentricity=0.0):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²), the orbit's mean motion (rad/s) and eccentricity."""
    n, e = float(orbit_rate), float(eccentricity)
    return Constants(*rigid_body(moments), n, n * n, 3 * (n * n), e, math.sqrt(1.0 - e * e))


@jit(inline=True)
def orbit(t, c):
    """``(ν', 3 μ/r³)`` at time ``t`` (s from perigee): the orbit frame's rate (rad/s) and the gradient's strength
    (1/s²); ``(n, 3 n²)`` exactly in a circular orbit."""
    if c.e == 0.0:
        return c.n, c.three_n2
    mean = c.n * t
    mean -= _TWO_PI * math.floor(mean / _TWO_PI + 0.5)  # in [-pi, pi)
    big = mean + 0.85 * c.e * (1.0 if math.sin(mean) >= 0.0 else -1.0)
    for _ in range(KEPLER_ITERATIONS):
        step = (big - c.e * math.sin(big) - mean) / (1.0 - c.e * math.cos(big))
        big -= step
        if abs(step) <= 1e-15 * (1.0 + abs(big)):
            break
    a_r = 1.0 / (1.0 - c.e * math.cos(big))
    return c.n * c.root * a_r * a_r, c.three_n2 * a_r * a_r * a_r


@jit(inline=True)
def _orbit_rows(q0, q1, q2, q3):
    """Rows ``c2`` (orbit normal, negative) and ``c3`` (nadir) of the orbit frame in the body frame, from the attitude
    quaternion: ``(c21, c22, c23, c31, c32, c33)``."""
    return (2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q1 * q1 + q3 * q3), 2.0 * (q2 * q3 - q0 * q1),
            2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1), 1.0 - 2.0 * (q1 * q1 + q2 * q2))


@jit(inline=True)
def forcing(t, c):
    """What the rate takes from time: :func:`orbit`. The generated steps evaluate it once per stage for a whole block
    of samples (it is the same for every sample), outside the loop over them, so that the loop keeps no branch and
    vectorises."""
    return orbit(t, c)


@jit(inline=True)
def rate(t, w1, w2, w3, q0, q1, q2, q3, c):
    # size: the time, the state's seven components (scalars: the generated steps keep them in registers), the constants
    """``(w', q')`` at time ``t``: rad/s², then 1/s."""
    return rate_forced(forcing(t, c), w1, w2, w3, q0, q1, q2, q3, c)


@jit(inline=True)
def rate_forced(f, w1, w2, w3, q0, q1, q2, q3, c):
    # size: the forcing, the state's seven components, the constants
    """:func:`rate` with the orbit's ``f = (ν', 3 μ/r³)`` given (:func:`forcing`)."""
    nu_dot, strength = f
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + nu_dot * c21, w2 + nu_dot * c22, w3 + nu_dot * c23  # w_r, relative to the orbit frame
    return (c.a1 * (w2 * w3 - strength * (c32 * c33)),
            c.a2 * (w3 * w1 - strength * (c33 * c31)),
            c.a3 * (w1 * w2 - strength * (c31 * c32)),
            0.5 * (-q1 * v1 - q2 * v2 - q3 * v3),
            0.5 * (q0 * v1 - q3 * v2 + q2 * v3),
            0.5 * (q3 * v1 + q0 * v2 - q1 * v3),
            0.5 * (-q2 * v1 + q1 * v2 + q0 * v3))


@jit(inline=True)
def tangent(t, w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c):
    # size: the time, the state's seven components, the tangent's seven (v along w, u along q), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``q``): the exact derivative
    of :func:`rate` (the attitude rows are quadratic in ``q``)."""
    return tangent_forced(forcing(t, c), w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c)


@jit(inline=True)
def tangent_forced(f, w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c):
    # size: the forcing, the state's seven components, the tangent's seven, the constants
    """:func:`tangent` with the orbit's ``f = (ν', 3 μ/r³)`` given (:func:`forcing`)."""
    nu_dot, strength = f
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    # derivatives of the rows along u
    d21 = 2.0 * (u1 * q2 + q1 * u2 + u0 * q3 + q0 * u3)
    d22 = -4.0 * (q1 * u1 + q3 * u3)
    d23 = 2.0 * (u2 * q3 + q2 * u3 - u0 * q1 - q0 * u1)
    d31 = 2.0 * (u1 * q3 + q1 * u3 - u0 * q2 - q0 * u2)
    d32 = 2.0 * (u2 * q3 + q2 * u3 + u0 * q1 + q0 * u1)
    d33 = -4.0 * (q1 * u1 + q2 * u2)
    r1, r2, r3 = w1 + nu_dot * c21, w2 + nu_dot * c22, w3 + nu_dot * c23
    s1, s2, s3 = v1 + nu_dot * d21, v2 + nu_dot * d22, v3 + nu_dot * d23  # derivative of w_r
    return (c.a1 * ((v2 * w3 + w2 * v3) - strength * (d32 * c33 + c32 * d33)),
            c.a2 * ((v3 * w1 + w3 * v1) - strength * (d33 * c31 + c33 * d31)),
            c.a3 * ((v1 * w2 + w1 * v2) - strength * (d31 * c32 + c31 * d32)),
            0.5 * ((-u1 * r1 - u2 * r2 - u3 * r3) + (-q1 * s1 - q2 * s2 - q3 * s3)),
            0.5 * ((u0 * r1 - u3 * r2 + u2 * r3) + (q0 * s1 - q3 * s2 + q2 * s3)),
            0.5 * ((u3 * r1 + u0 * r2 - u1 * r3) + (q3 * s1 + q0 * s2 - q1 * s3)),
            0.5 * ((-u2 * r1 + u1 * r2 + u0 * r3) + (-q2 * s1 + q1 * s2 + q0 * s3)))


@jit(inline=True)
def project(w1, w2, w3, q0, q1, q2, q3):
    """The state with its quaternion divided by its norm (after each step; ``w`` unchanged)."""
    norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return w1, w2, w3, q0 / norm, q1 / norm, q2 / norm, q3 / norm


@jit(inline=True)
def invariants(w1, w2, w3, q0, q1, q2, q3, c):
    """``(Jacobi integral (J), |q|², 0)`` and their scales ``(T_r + V_g + V_c, |q|², 1)``; in an eccentric orbit the
    Jacobi integral is no invariant: ``(0, |q|², 0)``.

    The Jacobi integral ``T_r + V_g − V_c`` (``T_r = ½ w_r·I w_r``, ``V_g = (3/2) n² c3·I c3``, ``V_c = ½ n²
    c2·I c2``) may vanish, so its scale is the sum of the three terms' magnitudes; ``|q|²`` is its own scale.
    """
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + c.n * c21, w2 + c.n * c22, w3 + c.n * c23
    kinetic = 0.5 * (c.i1 * v1 * v1 + c.i2 * v2 * v2 + c.i3 * v3 * v3)
    gravity = 1.5 * c.n2 * (c.i1 * c31 * c31 + c.i2 * c32 * c32 + c.i3 * c33 * c33)
    centrifugal = 0.5 * c.n2 * (c.i1 * c21 * c21 + c.i2 * c22 * c22 + c.i3 * c23 * c23)
    unit = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    jacobi = kinetic + gravity - centrifugal if c.e == 0.0 else 0.0
    return jacobi, unit, 0.0, kinetic + gravity + centrifugal, unit, 1.0
