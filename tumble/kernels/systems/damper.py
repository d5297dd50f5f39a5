"""A rigid body with Kane's spherical damper: a sphere of moment ``J`` inside the body, coupled by viscosity ``c``.

``I w' = (I w) × w + c (s − w)``, ``J (s' + w × s) = −c (s − w)`` (body frame; ``I`` excludes the sphere): state
``w1 w2 w3`` and the sphere's angular velocity ``s1 s2 s3`` (rad/s); parameters ``damper_inertia`` ``J`` (kg m²) and
``damping`` ``c`` (N m s). ``|I w + J s|`` is kept, the energy decays (the drift observer tracks ``|L|²`` only).

Per-sample scalar code, as :mod:`tumble.kernels.systems.gyrostat`.
"""

import math
from collections import namedtuple

from ..jit import jit
from ._rigid import RIGID_BODY, rigid_body

__all__ = ["KINDS", "Constants", "constants", "invariants", "rate", "tangent"]

#: The model kinds of ``registry.MODELS`` this module is the system of (its row).
KINDS = ("damper",)


#: The rigid body's fields (``I`` excludes the sphere), ``c/I_i`` and ``c/J`` (1/s), and ``J`` (kg m²).
Constants = namedtuple("Constants", (*RIGID_BODY, "c_i1", "c_i2", "c_i3", "c_j", "j"))


def constants(moments, damper_inertia, damping):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²), ``J`` (kg m²) and ``c`` (N m s); ``J = 0`` (no
    damper) gives ``c/J = 0`` (no damping either)."""
    rigid = rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    j, c = float(damper_inertia), float(damping)
    return Constants(*rigid, c / i1, c / i2, c / i3, c / j if j > 0 else 0.0, j)


@jit(inline=True)
def rate(t, w1, w2, w3, s1, s2, s3, c):
    """``(w', s')``, rad/s²."""
    d1, d2, d3 = s1 - w1, s2 - w2, s3 - w3
    return (c.a1 * w2 * w3 + c.c_i1 * d1,
            c.a2 * w3 * w1 + c.c_i2 * d2,
            c.a3 * w1 * w2 + c.c_i3 * d3,
            (s2 * w3 - s3 * w2) - c.c_j * d1,
            (s3 * w1 - s1 * w3) - c.c_j * d2,
            (s1 * w2 - s2 * w1) - c.c_j * d3)


@jit(inline=True)
def tangent(t, w1, w2, w3, s1, s2, s3, v1, v2, v3, u1, u2, u3, c):
    # size: the state's six components, the tangent's six (v along w, u along s), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``s``)."""
    e1, e2, e3 = u1 - v1, u2 - v2, u3 - v3
    return (c.a1 * (v2 * w3 + w2 * v3) + c.c_i1 * e1,
            c.a2 * (v3 * w1 + w3 * v1) + c.c_i2 * e2,
            c.a3 * (v1 * w2 + w1 * v2) + c.c_i3 * e3,
            ((u2 * w3 - u3 * w2) + (s2 * v3 - s3 * v2)) - c.c_j * e1,
            ((u3 * w1 - u1 * w3) + (s3 * v1 - s1 * v3)) - c.c_j * e2,
            ((u1 * w2 - u2 * w1) + (s1 * v2 - s2 * v1)) - c.c_j * e3)


@jit(inline=True)
def invariants(w1, w2, w3, s1, s2, s3, c):
    """``(|I w + J s|² ((N m s)²), 0, 0)`` and their scales ``((|I w| + J |s|)², 1, 1)``: ``|L|²`` may vanish."""
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    t1, t2, t3 = l1 + c.j * s1, l2 + c.j * s2, l3 + c.j * s3
    scale = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) + c.j * math.sqrt(s1 * s1 + s2 * s2 + s3 * s3)
    return t1 * t1 + t2 * t2 + t3 * t3, 0.0, 0.0, scale * scale, 1.0, 1.0
