"""Right-hand sides and invariants of the models, per sample, on scalars (numba, inlined into the steps).

The generated steps of :mod:`tumble.kernels.model_steps` call the rates below on one sample's scalars, so that
a loop over the samples of a block compiles to packed SIMD code with the state in registers, as the free body's
steps do (:mod:`tumble.kernels.fused`). ``c`` is the tuple :func:`model_constants` makes (read into a tuple of
scalars once per block: the compiler keeps them in registers).

Models (:mod:`tumble.physics.models`, whose numpy ``rhs`` these agree with to round-off; body frame):

* gyrostat (the free body is the gyrostat with ``h = 0``): ``I w' = (I w + h) × w``, i.e.
  ``w_i' = (I_j − I_k)/I_i w_j w_k + (h_j/I_i) w_k − (h_k/I_i) w_j`` for ``(i, j, k)`` cyclic;
* heavy top (Euler-Poisson): ``I w' = (I w) × w + mgl (g × e3)``, ``g' = g × w``, i.e.
  ``w1' = a1 w2 w3 + (mgl/I1) g2``, ``w2' = a2 w3 w1 − (mgl/I2) g1``, ``w3' = a3 w1 w2``.
"""

import math

import numpy as np

from .jit import jit

__all__ = ["N_CONSTANTS", "N_INVARIANTS", "gyrostat_invariants", "gyrostat_rate", "heavy_top_invariants",
           "heavy_top_rate", "model_constants"]

#: Length of the constants array of every model (one layout, so that one compiled driver serves them all).
N_CONSTANTS = 18

#: Invariants the kernels track per sample (the heavy top's three; the gyrostat's two, the third unused, 0).
N_INVARIANTS = 3


def model_constants(moments, rotor=(0.0, 0.0, 0.0), mgl=0.0):
    """The constants of a model's kernels, float64 array of shape (:data:`N_CONSTANTS`,).

    Layout: ``0-2`` the moments ``I`` (kg m²); ``3-5`` ``a_i = (I_j − I_k)/I_i`` (cyclic); ``6-11``
    ``h2/I1, h3/I1, h3/I2, h1/I2, h1/I3, h2/I3`` (1/s); ``12-14`` the rotor ``h`` (N m s); ``15`` ``mgl`` (N m);
    ``16-17`` ``mgl/I1, mgl/I2`` (1/s²). A free body has ``h = 0`` and ``mgl = 0``; a gyrostat ``mgl = 0``; a
    heavy top ``h = 0``.
    """
    i1, i2, i3 = (float(x) for x in np.asarray(moments, dtype=float))
    h1, h2, h3 = (float(x) for x in np.asarray(rotor, dtype=float))
    mgl = float(mgl)
    return np.array([i1, i2, i3, (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3,
                     h2 / i1, h3 / i1, h3 / i2, h1 / i2, h1 / i3, h2 / i3,
                     h1, h2, h3, mgl, mgl / i1, mgl / i2])


@jit(inline=True)
def gyrostat_rate(w1, w2, w3, c):
    """``w'`` (rad/s²) of the gyrostat (free body: ``h = 0``) at ``w`` (rad/s)."""
    return (c[3] * w2 * w3 + (c[6] * w3 - c[7] * w2),
            c[4] * w3 * w1 + (c[8] * w1 - c[9] * w3),
            c[5] * w1 * w2 + (c[10] * w2 - c[11] * w1))


@jit(inline=True)
def heavy_top_rate(w1, w2, w3, g1, g2, g3, c):
    """``(w', g')`` of the heavy top: rad/s², then 1/s."""
    return (c[3] * w2 * w3 + c[16] * g2,
            c[4] * w3 * w1 - c[17] * g1,
            c[5] * w1 * w2,
            g2 * w3 - g3 * w2,
            g3 * w1 - g1 * w3,
            g1 * w2 - g2 * w1)


@jit(inline=True)
def gyrostat_invariants(w1, w2, w3, c):
    """``(energy ½ w·Iw (J), |I w + h|² ((N m s)²), 0)`` and their scales ``(½ w·Iw, (|I w| + |h|)², 1)``.

    A drift is ``|x − x0| / scale0``: the energy is >= 0 and its own scale; ``|I w + h|²`` may vanish (``I w =
    −h``), so its scale is the largest value it can take for the given ``|I w|`` and ``|h|``.
    """
    l1, l2, l3 = c[0] * w1, c[1] * w2, c[2] * w3
    t1, t2, t3 = l1 + c[12], l2 + c[13], l3 + c[14]
    e = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    m = t1 * t1 + t2 * t2 + t3 * t3
    s = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) + math.sqrt(c[12] * c[12] + c[13] * c[13] + c[14] * c[14])
    return e, m, 0.0, e, s * s, 1.0


@jit(inline=True)
def heavy_top_invariants(w1, w2, w3, g1, g2, g3, c):
    """``(energy ½ w·Iw + mgl g3 (J), L·g (N m s), |g|²)`` and their scales ``(½ w·Iw + mgl |g|, |I w| |g|,
    |g|²)``.

    The energy and ``L·g`` may vanish (a top hanging or lying flat, a spin across the vertical), so their scales
    are the largest magnitudes they can take for the given ``|I w|`` and ``|g|``; ``|g|²`` is its own scale.
    """
    l1, l2, l3 = c[0] * w1, c[1] * w2, c[2] * w3
    kinetic = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    up = g1 * g1 + g2 * g2 + g3 * g3
    g_norm = math.sqrt(up)
    return (kinetic + c[15] * g3, l1 * g1 + l2 * g2 + l3 * g3, up,
            kinetic + c[15] * g_norm, math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) * g_norm, up)
