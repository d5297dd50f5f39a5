"""The heavy top (Euler–Poisson): a rigid body on a fixed pivot in uniform gravity.

Moments about the pivot; ``c`` the direction of the centre of mass from the pivot in body axes (a unit vector:
the top's axis 3 by default), at distance ``l``, ``mgl = M g l`` (N m); ``g`` the unit vector pointing up, in body
axes. The torque of the weight ``r × F = l c × (−M g g) = mgl (g × c)`` (Arnold, *Mathematical Methods of Classical
Mechanics*, §30; Goldstein §5.7)::

    I w' = (I w) × w + mgl (g × c),    g' = g × w

State ``w1 w2 w3`` (rad/s), ``g1 g2 g3`` (1); parameters ``mgl`` and ``centre``. Kept: the energy ``½ w·I w + mgl
g·c``, ``L·g`` and ``|g|²``. With ``c = e3`` these are today's equations to the last bit (the products with the
zero components of ``c`` add exact zeros).

Per-sample scalar code, as :mod:`tumble.kernels.systems.gyrostat`.
"""

import math
from collections import namedtuple

import numpy as np

from ..jit import jit
from ._rigid import RIGID_BODY, rigid_body

__all__ = ["KINDS", "Constants", "constants", "invariants", "rate", "tangent"]

#: The model kinds of ``registry.MODELS`` this module is the system of (its row).
KINDS = ("heavy_top",)


#: The rigid body's fields (moments about the pivot), ``mgl`` (N m), the centre's direction ``c1 c2 c3`` and the
#: products ``m_ij = (mgl/I_i) c_j`` (1/s²) the torque's components are made of (two multiply-adds each: the general
#: centre costs the rate four more than the centre on axis 3 did, and the same bits there).
Constants = namedtuple("Constants", (*RIGID_BODY, "mgl", "c1", "c2", "c3", "m12", "m13", "m21", "m23", "m31", "m32"))


def constants(moments, mgl, centre=(0.0, 0.0, 1.0)):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m², about the pivot), ``mgl`` (N m) and ``centre`` (the
    centre of mass's direction, body axes; normalised here)."""
    rigid = rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    c = np.asarray(centre, dtype=float)
    c1, c2, c3 = (float(x) for x in c / np.linalg.norm(c))
    mgl = float(mgl)
    m1, m2, m3 = mgl / i1, mgl / i2, mgl / i3
    return Constants(*rigid, mgl, c1, c2, c3, m1 * c2, m1 * c3, m2 * c1, m2 * c3, m3 * c1, m3 * c2)


@jit(inline=True)
def rate(t, w1, w2, w3, g1, g2, g3, c):
    """``(w', g')``: rad/s², then 1/s."""
    return (c.a1 * w2 * w3 + (c.m13 * g2 - c.m12 * g3),
            c.a2 * w3 * w1 + (c.m21 * g3 - c.m23 * g1),
            c.a3 * w1 * w2 + (c.m32 * g1 - c.m31 * g2),
            g2 * w3 - g3 * w2,
            g3 * w1 - g1 * w3,
            g1 * w2 - g2 * w1)


@jit(inline=True)
def tangent(t, w1, w2, w3, g1, g2, g3, v1, v2, v3, u1, u2, u3, c):
    # size: the state's six components, the tangent's six (v along w, u along g), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``g``)."""
    return (c.a1 * (v2 * w3 + w2 * v3) + (c.m13 * u2 - c.m12 * u3),
            c.a2 * (v3 * w1 + w3 * v1) + (c.m21 * u3 - c.m23 * u1),
            c.a3 * (v1 * w2 + w1 * v2) + (c.m32 * u1 - c.m31 * u2),
            (u2 * w3 - u3 * w2) + (g2 * v3 - g3 * v2),
            (u3 * w1 - u1 * w3) + (g3 * v1 - g1 * v3),
            (u1 * w2 - u2 * w1) + (g1 * v2 - g2 * v1))


@jit(inline=True)
def invariants(w1, w2, w3, g1, g2, g3, c):
    """``(energy ½ w·Iw + mgl g·c (J), L·g (N m s), |g|²)`` and their scales ``(½ w·Iw + mgl |g|, |I w| |g|,
    |g|²)``.

    The energy and ``L·g`` may vanish (a top hanging or lying flat, a spin across the vertical), so their scales
    are the largest magnitudes they can take for the given ``|I w|`` and ``|g|``; ``|g|²`` is its own scale.
    """
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    kinetic = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    up = g1 * g1 + g2 * g2 + g3 * g3
    g_norm = math.sqrt(up)
    height = g1 * c.c1 + g2 * c.c2 + g3 * c.c3
    return (kinetic + c.mgl * height, l1 * g1 + l2 * g2 + l3 * g3, up,
            kinetic + c.mgl * g_norm, math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) * g_norm, up)
