"""Right-hand sides and invariants of the models, per sample, on scalars (numba, inlined into the steps).

The generated steps of :mod:`tumble.kernels.model_steps` call the rates below on one sample's scalars, so that
a loop over the samples of a block compiles to packed SIMD code with the state in registers, as the free body's
steps do (:mod:`tumble.kernels.fused`). ``c`` is the tuple :func:`model_constants` makes (read into a tuple of
scalars once per block: the compiler keeps them in registers).

Models (:mod:`tumble.physics.models`, whose numpy ``rhs`` these agree with to round-off; body frame):

* gyrostat (the free body is the gyrostat with ``h = 0``): ``I w' = (I w + h) × w``, i.e.
  ``w_i' = (I_j − I_k)/I_i w_j w_k + (h_j/I_i) w_k − (h_k/I_i) w_j`` for ``(i, j, k)`` cyclic;
* heavy top (Euler-Poisson): ``I w' = (I w) × w + mgl (g × e3)``, ``g' = g × w``, i.e.
  ``w1' = a1 w2 w3 + (mgl/I1) g2``, ``w2' = a2 w3 w1 − (mgl/I2) g1``, ``w3' = a3 w1 w2``;
* gravity gradient (attitude ``q`` relative to the orbit frame, scalar first; ``c2``, ``c3`` the orbit's pitch and
  nadir axes in the body frame, the rows of ``C(q)`` written as the physics layer writes them, ``1 − 2(…)`` on the
  diagonal): ``I w' = (I w) × w + 3 n² (c3 × I c3)``, i.e. ``w_i' = a_i (w_j w_k − 3 n² c3_j c3_k)``, and
  ``q' = ½ q ⊗ (0, w + n c2)``;
* damper (Kane's sphere): ``I w' = (I w) × w + c (s − w)``, ``s' = s × w − (c/J) (s − w)``.

The gravity gradient's quaternion is put back on the unit sphere after every step (:func:`gravity_gradient_unit`,
called by the generated block loop): its right-hand side keeps ``|q|`` only exactly, a Runge-Kutta step only to
its order, and the attitude rows ``c2``, ``c3`` are a rotation's only on the unit sphere.
"""

import math

import numpy as np

from .jit import jit

__all__ = ["N_CONSTANTS", "N_INVARIANTS", "damper_invariants", "damper_rate", "gravity_gradient_invariants",
           "gravity_gradient_rate", "gravity_gradient_unit", "gyrostat_invariants", "gyrostat_rate",
           "heavy_top_invariants", "heavy_top_rate", "model_constants"]

#: Length of the constants array of every model (one layout, so that one compiled driver serves them all).
N_CONSTANTS = 26

#: Invariants the kernels track per sample (the heavy top's three; the gyrostat's two, the third unused, 0).
N_INVARIANTS = 3


def model_constants(moments, rotor=(0.0, 0.0, 0.0), mgl=0.0, orbit_rate=0.0, damper_inertia=0.0, damping=0.0):
    """The constants of a model's kernels, float64 array of shape (:data:`N_CONSTANTS`,).

    Layout: ``0-2`` the moments ``I`` (kg m²); ``3-5`` ``a_i = (I_j − I_k)/I_i`` (cyclic); ``6-11``
    ``h2/I1, h3/I1, h3/I2, h1/I2, h1/I3, h2/I3`` (1/s); ``12-14`` the rotor ``h`` (N m s); ``15`` ``mgl`` (N m);
    ``16-17`` ``mgl/I1, mgl/I2`` (1/s²); ``18-20`` the orbit rate ``n`` (rad/s), ``n²`` and ``3 n²`` (1/s²);
    ``21-23`` ``c/I1, c/I2, c/I3`` and ``24`` ``c/J`` (1/s), ``25`` ``J`` (kg m²). A parameter a model does not
    have is 0 (a free body: all of them; a gyrostat has only ``h``, a heavy top only ``mgl``, ...). ``J`` = 0 (no
    damper) gives ``c/J`` = 0 (no damping either).
    """
    i1, i2, i3 = (float(x) for x in np.asarray(moments, dtype=float))
    h1, h2, h3 = (float(x) for x in np.asarray(rotor, dtype=float))
    mgl, n, j, c = float(mgl), float(orbit_rate), float(damper_inertia), float(damping)
    return np.array([i1, i2, i3, (i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3,
                     h2 / i1, h3 / i1, h3 / i2, h1 / i2, h1 / i3, h2 / i3,
                     h1, h2, h3, mgl, mgl / i1, mgl / i2,
                     n, n * n, 3 * (n * n), c / i1, c / i2, c / i3, c / j if j > 0 else 0.0, j])


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


@jit(inline=True)
def _orbit_rows(q0, q1, q2, q3):
    """Rows ``c2`` (orbit normal, negative) and ``c3`` (nadir) of the orbit frame in the body frame, from the attitude
    quaternion: ``(c21, c22, c23, c31, c32, c33)``."""
    return (2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q1 * q1 + q3 * q3), 2.0 * (q2 * q3 - q0 * q1),
            2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1), 1.0 - 2.0 * (q1 * q1 + q2 * q2))


@jit(inline=True)
def gravity_gradient_rate(w1, w2, w3, q0, q1, q2, q3, c):
    """``(w', q')`` of the gravity-gradient satellite: rad/s², then 1/s (the physics layer's rows ``c2``, ``c3``)."""
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + c[18] * c21, w2 + c[18] * c22, w3 + c[18] * c23  # w_r = w + n c2, relative to the orbit
    return (c[3] * (w2 * w3 - c[20] * (c32 * c33)),
            c[4] * (w3 * w1 - c[20] * (c33 * c31)),
            c[5] * (w1 * w2 - c[20] * (c31 * c32)),
            0.5 * (-q1 * v1 - q2 * v2 - q3 * v3),
            0.5 * (q0 * v1 - q3 * v2 + q2 * v3),
            0.5 * (q3 * v1 + q0 * v2 - q1 * v3),
            0.5 * (-q2 * v1 + q1 * v2 + q0 * v3))


@jit(inline=True)
def gravity_gradient_unit(w1, w2, w3, q0, q1, q2, q3):
    """The state with its quaternion divided by its norm (after each step; ``w`` unchanged)."""
    norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return w1, w2, w3, q0 / norm, q1 / norm, q2 / norm, q3 / norm


@jit(inline=True)
def damper_rate(w1, w2, w3, s1, s2, s3, c):
    """``(w', s')`` of the body with Kane's damper, rad/s²."""
    d1, d2, d3 = s1 - w1, s2 - w2, s3 - w3
    return (c[3] * w2 * w3 + c[21] * d1,
            c[4] * w3 * w1 + c[22] * d2,
            c[5] * w1 * w2 + c[23] * d3,
            (s2 * w3 - s3 * w2) - c[24] * d1,
            (s3 * w1 - s1 * w3) - c[24] * d2,
            (s1 * w2 - s2 * w1) - c[24] * d3)


@jit(inline=True)
def gravity_gradient_invariants(w1, w2, w3, q0, q1, q2, q3, c):
    """``(Jacobi integral (J), |q|², 0)`` and their scales ``(T_r + V_g + V_c, |q|², 1)``.

    The Jacobi integral ``T_r + V_g − V_c`` (``T_r = ½ w_r·I w_r``, ``V_g = (3/2) n² c3·I c3``, ``V_c = ½ n²
    c2·I c2``) may vanish, so its scale is the sum of the three terms' magnitudes; ``|q|²`` is its own scale.
    """
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + c[18] * c21, w2 + c[18] * c22, w3 + c[18] * c23
    kinetic = 0.5 * (c[0] * v1 * v1 + c[1] * v2 * v2 + c[2] * v3 * v3)
    gravity = 1.5 * c[19] * (c[0] * c31 * c31 + c[1] * c32 * c32 + c[2] * c33 * c33)
    centrifugal = 0.5 * c[19] * (c[0] * c21 * c21 + c[1] * c22 * c22 + c[2] * c23 * c23)
    unit = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    return kinetic + gravity - centrifugal, unit, 0.0, kinetic + gravity + centrifugal, unit, 1.0


@jit(inline=True)
def damper_invariants(w1, w2, w3, s1, s2, s3, c):
    """``(|I w + J s|² ((N m s)²), 0, 0)`` and their scales ``((|I w| + J |s|)², 1, 1)``: ``|L|²`` may vanish.

    The energy is not an invariant (it decays): the drift observer does not track it."""
    l1, l2, l3 = c[0] * w1, c[1] * w2, c[2] * w3
    t1, t2, t3 = l1 + c[25] * s1, l2 + c[25] * s2, l3 + c[25] * s3
    scale = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) + c[25] * math.sqrt(s1 * s1 + s2 * s2 + s3 * s3)
    return t1 * t1 + t2 * t2 + t3 * t3, 0.0, 0.0, scale * scale, 1.0, 1.0
