"""The gyrostat (and the free body, its ``h = 0``): a rigid body with a rotor of constant relative angular momentum.

``I w' = (I w + h) × w`` in the body frame (Wittenburg, *Dynamics of Multibody Systems*, §3.6), i.e. for ``(i, j, k)``
cyclic ``w_i' = (I_j − I_k)/I_i w_j w_k + (h_j/I_i) w_k − (h_k/I_i) w_j``. State ``w1 w2 w3`` (rad/s); parameter
``rotor`` ``h`` (N m s, body frame). Kept: the energy ``½ w·I w`` and ``|I w + h|²``.

Per-sample scalar code (numba, inlined into the generated steps of :mod:`tumble.kernels.model_steps`, so that a loop
over a block's samples vectorises); :class:`Constants` is what the steps read, built once per run by
:func:`constants`.
"""

import math
from collections import namedtuple

import numpy as np

from ..jit import jit
from ._rigid import RIGID_BODY, rigid_body

__all__ = ["KINDS", "Constants", "constants", "invariants", "rate", "tangent"]

#: The model kinds of ``registry.MODELS`` this module is the system of (the free body is the gyrostat with no rotor).
KINDS = ("free", "gyrostat")


#: The rigid body's fields (:data:`~tumble.kernels.systems._rigid.RIGID_BODY`), ``h_j/I_i`` (1/s) and the rotor
#: ``h`` (N m s).
Constants = namedtuple("Constants", (*RIGID_BODY, "h2_i1", "h3_i1", "h3_i2", "h1_i2", "h1_i3", "h2_i3", "h1", "h2",
                                     "h3"))


def constants(moments, rotor=(0.0, 0.0, 0.0)):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²) and ``rotor`` (N m s)."""
    rigid = rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    h1, h2, h3 = (float(x) for x in np.asarray(rotor, dtype=float))
    return Constants(*rigid, h2 / i1, h3 / i1, h3 / i2, h1 / i2, h1 / i3, h2 / i3, h1, h2, h3)


@jit(inline=True)
def rate(t, w1, w2, w3, c):
    """``w'`` (rad/s²) at ``w`` (rad/s)."""
    return (c.a1 * w2 * w3 + (c.h2_i1 * w3 - c.h3_i1 * w2),
            c.a2 * w3 * w1 + (c.h3_i2 * w1 - c.h1_i2 * w3),
            c.a3 * w1 * w2 + (c.h1_i3 * w2 - c.h2_i3 * w1))


@jit(inline=True)
def tangent(t, w1, w2, w3, v1, v2, v3, c):
    """The tangent flow ``J(w) v``: the derivative of :func:`rate` at ``w`` along ``v``."""
    return (c.a1 * (v2 * w3 + w2 * v3) + (c.h2_i1 * v3 - c.h3_i1 * v2),
            c.a2 * (v3 * w1 + w3 * v1) + (c.h3_i2 * v1 - c.h1_i2 * v3),
            c.a3 * (v1 * w2 + w1 * v2) + (c.h1_i3 * v2 - c.h2_i3 * v1))


@jit(inline=True)
def invariants(w1, w2, w3, c):
    """``(energy ½ w·Iw (J), |I w + h|² ((N m s)²), 0)`` and their scales ``(½ w·Iw, (|I w| + |h|)², 1)``.

    A drift is ``|x − x0| / scale0``: the energy is >= 0 and its own scale; ``|I w + h|²`` may vanish (``I w =
    −h``), so its scale is the largest value it can take for the given ``|I w|`` and ``|h|``.
    """
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    t1, t2, t3 = l1 + c.h1, l2 + c.h2, l3 + c.h3
    e = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    m = t1 * t1 + t2 * t2 + t3 * t3
    s = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) + math.sqrt(c.h1 * c.h1 + c.h2 * c.h2 + c.h3 * c.h3)
    return e, m, 0.0, e, s * s, 1.0
