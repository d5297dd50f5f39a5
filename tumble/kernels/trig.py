"""Branch-free ``sincos`` and ``atan2`` that vectorise inside a caller's numba loop.

Without Intel SVML, ``math.sin``/``math.cos`` in a numba loop are scalar libm calls, and one such call
keeps LLVM from vectorising the whole loop. :func:`sincos` is straight-line floating-point code (plus
selects), inlined at the numba IR level, so a loop such as ::

    for i in range(theta.shape[0]):
        s, c = sincos(theta[i])
        x[i], y[i] = c * x[i] + s * y[i], c * y[i] - s * x[i]

compiles to packed AVX2/AVX-512 code (``tests/test_trig.py`` checks the assembly).

Method
------
1. **Quadrant.** ``q = floor(x 2/pi + 1/2)``, ``r = x - q pi/2``, so ``|r|`` exceeds ``pi/4`` only by
   the rounding of ``x 2/pi`` (at most ``2e-4`` at ``XMAX``).
2. **Cody-Waite reduction in three pieces** (Cody & Waite 1980, ch. 8; the scheme of fdlibm's
   ``e_rem_pio2.c``), ``pi/2 = P1 + P2 + P3 + O(2^-132)``:

   * ``P1 = RN(pi/2)`` (53 bits): ``x - q P1`` is formed by one fused multiply-add and is *exact* (the
     exact difference is a multiple of ``2^-52`` below 2 in magnitude, or for ``|x| < 1`` of ``2^-53``
     below 1). fdlibm instead splits ``pi/2`` into 33-bit pieces (``pio2_1 = 1.57079632673412561417``,
     ...) so that ``q pio2_1`` is exact without an FMA, which only holds for ``|q| < 2^20``
     (``|x| < 1.6e6``); the FMA lifts that limit.
   * ``P2`` (23 bits): ``q P2`` is exact for ``|q| < 2^30`` (``|x| < 1.69e9``), and beyond that its
     rounding error is recovered by one more FMA (TwoProd); the sum with the exact first remainder is
     carried as a double-double by Knuth's TwoSum.
   * ``P3`` (53 bits) is folded into the low part, and a last TwoSum gives ``r = y0 + y1``,
     ``|y1| <= ulp(y0)/2``.

   The remainder is thus accurate to about ``|q| 2^-132`` absolute, enough for ``r`` to keep full
   relative accuracy even where ``x`` is within a few ulps of a multiple of ``pi/2``.
3. **Kernels on [-pi/4, pi/4]**: fdlibm's ``k_sin.c`` (``S1..S6``, degree 13, ``|sin x/x - p| < 2^-58``)
   and ``k_cos.c`` (``C1..C6``, degree 14, ``|cos x - p| < 2^-58``) minimax polynomials, both fed with the
   tail ``y1``. The cosine uses the branch-free form of FreeBSD's ``k_cos.c`` (Bruce Evans):
   ``w = 1 - z/2``, ``cos = w + (((1 - w) - z/2) + (z R(z) - y0 y1))``, which recovers the rounding error
   of ``1 - z/2`` exactly and so needs none of fdlibm's original ``|x| > 0.3`` branch.
4. **Quadrant fix-up** by selects on ``m = q mod 4`` computed in floating point (no float-to-integer
   conversion, which AVX2 cannot vectorise): swap for odd ``m``; negate ``sin`` for ``m in {2, 3}`` and
   ``cos`` for ``m in {1, 2}``.

Range and special values
------------------------
* ``|x| <= XMAX = 2^40`` (1.1e12): every step above is exact or compensated. Measured against mpmath:
  below 0.75 ulp for sin and cos on random angles, and below 0.5 ulp at the doubles closest to multiples
  of ``pi/2`` (``tests/test_trig.py``). Near ``XMAX``, ``q`` may be off by one where ``x 2/pi`` is close to
  a half-integer; ``|r|`` then exceeds ``pi/4`` by up to ``2e-4``, still inside the polynomials' accurate
  range.
* ``|x| > XMAX``, ``+-inf`` and NaN give NaN for both. Past ``2^40`` the error of ``x 2/pi`` pushes ``r``
  out of ``[-pi/4, pi/4]`` and the result would drift (``~1e-14`` at ``1e15``); a double there is spaced
  ``2^-12`` or more apart, so NaN is the honest answer and keeps blow-up detection working.
* ``sin`` is odd and ``cos`` even bit for bit, except where the rounded ``x 2/pi + 1/2`` is an integer (then
  the two sides pick neighbouring quadrants and may differ by one ulp). The sign of a zero result is not kept
  (fast-math ``nsz``).
* Needs a hardware FMA for speed (Intel and AMD CPUs with AVX2, every AArch64 CPU); elsewhere LLVM's
  ``llvm.fma`` falls back to the (correct, slow, scalar) libm ``fma``.

Speed: a rotation loop over 10^6 angles runs 7-8x faster than the same loop with ``math.sin`` and
``math.cos`` (AVX2, 4 doubles a vector; ``benchmarks`` is the place to re-measure).
"""

import operator

import numpy as np
from numba.core import cgutils, types
from numba.core.typing import signature
from numba.cpython.builtins import do_minmax
from numba.extending import intrinsic

from .jit import jit

__all__ = ["XMAX", "atan2", "sincos"]

# 2/pi rounded to double (fdlibm e_rem_pio2.c ``invpio2``).
_INV_PIO2 = 6.36619772367581382433e-01  # 0x3FE45F30 6DC9C883

# pi/2 = _PIO2_1 + _PIO2_2 + _PIO2_3 + 1.6e-40 (computed with mpmath at 300 bits).
_PIO2_1 = 1.5707963267948966  # 0x1.921fb54442d18p+0, RN(pi/2), 53 bits
_PIO2_2 = 6.123234262925839e-17  # 0x1.1a6264p-54, 23 bits: q * _PIO2_2 exact for |q| < 2^30
_PIO2_3 = -2.6718907338610155e-24  # -0x1.9d747f23e32edp-79, RN of the rest

# fdlibm k_sin.c: |sin(x)/x - (1 + S1 x^2 + ... + S6 x^12)| <= 2^-58 on [-pi/4, pi/4].
_S1 = -1.66666666666666324348e-01  # 0xBFC55555, 0x55555549
_S2 = 8.33333333332248946124e-03  # 0x3F811111, 0x1110F8A6
_S3 = -1.98412698298579493134e-04  # 0xBF2A01A0, 0x19C161D5
_S4 = 2.75573137070700676789e-06  # 0x3EC71DE3, 0x57B1FE7D
_S5 = -2.50507602534068634195e-08  # 0xBE5AE5E6, 0x8A2B9CEB
_S6 = 1.58969099521155010221e-10  # 0x3DE5D93A, 0x5ACFD57C

# fdlibm k_cos.c: |cos(x) - (1 - x^2/2 + C1 x^4 + ... + C6 x^14)| <= 2^-58 on [-pi/4, pi/4].
_C1 = 4.16666666666666019037e-02  # 0x3FA55555, 0x5555554C
_C2 = -1.38888888888741095749e-03  # 0xBF56C16C, 0x16C15177
_C3 = 2.48015872894767294178e-05  # 0x3EFA01A0, 0x19CB1590
_C4 = -2.75573143513906633035e-07  # 0xBE927E4F, 0x809C52AD
_C5 = 2.08757232129817482790e-09  # 0x3E21EE9E, 0xBDB4B1C4
_C6 = -1.13596475577881948265e-11  # 0xBDA8FAE9, 0xBE8838D4

#: Largest ``|x|`` accepted; beyond it (and for inf/NaN) :func:`sincos` returns NaN.
XMAX = 2.0**40


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` with one rounding (``llvm.fma.f64``), whatever the fast-math flags say."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        args = [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)]
        return builder.fma(*args)

    return sig, codegen


@intrinsic
def _floor(typingctx, x):
    """``floor(x)`` as a float (``llvm.floor.f64``): what ``np.floor`` compiles to on the CPU (the same bits, and it
    vectorises), and it compiles for a CUDA device too, where numba-cuda has no ``np.floor`` (``math.floor`` would
    return an integer, a float-to-integer conversion that AVX2 cannot vectorise)."""
    if not isinstance(x, types.Float):
        return None
    sig = types.float64(types.float64)

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[0], signature.args[0], types.float64)
        floor = builder.module.declare_intrinsic("llvm.floor", [value.type])
        return builder.call(floor, [value])

    return sig, codegen


def _extremum(cmpop):
    """An intrinsic of two or more numbers that lowers as numba's own ``max`` (``cmpop`` ``>``) or ``min`` (``<``) does,
    fold by fold ``acc = v if v cmpop acc else acc`` (numba's ``do_minmax``: the same instructions, so the same bits),
    without compiling the builtin's overload: numba compiles that as a function of its own per signature, ten of
    them 0.2 s of the closed form's first call."""

    @intrinsic
    def extremum(typingctx, *values):
        if len(values) < 2 or not all(isinstance(t, types.Number) for t in values):
            return None

        def codegen(context, builder, sig, args):
            return do_minmax(context, builder, list(sig.args[0]), cgutils.unpack_tuple(builder, args[0]), cmpop)

        return signature(typingctx.unify_types(*values), types.StarArgTuple.from_types(values)), codegen

    return extremum


#: ``max(a, b, ...)`` and ``min(a, b, ...)`` of numbers, as numba's builtins compute them (:func:`_extremum`).
_max = _extremum(operator.gt)
_min = _extremum(operator.lt)


@jit(inline=True)
def _two_sum(a, b):
    """``(s, e)`` with ``s = RN(a + b)`` and ``s + e = a + b`` exactly (Knuth, TAOCP vol. 2, 4.2.2)."""
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)
    return s, e


@jit(inline=True)
def sincos(x):
    """Sine and cosine of one angle, branch-free, for use inside vectorised numba loops.

    Parameters
    ----------
    x : float
        Angle, rad. Below 1 ulp (measured) for ``|x| <= XMAX = 2^40`` (1.1e12).

    Returns
    -------
    s, c : float
        ``sin x`` and ``cos x``; both NaN if ``x`` is NaN, infinite or ``|x| > XMAX``.

    Notes
    -----
    Cody-Waite reduction by ``pi/2`` in three pieces with an FMA-exact first step, then fdlibm's
    ``k_sin``/``k_cos`` polynomials on the double-double remainder (module docstring).
    """
    # 1. quadrant
    q = _floor(x * _INV_PIO2 + 0.5)
    # 2. r = x - q pi/2 as y0 + y1
    r1 = _fma(-q, _PIO2_1, x)  # exact
    p2 = q * _PIO2_2  # exact for |q| < 2^30; beyond, its rounding error is recovered:
    p2_err = _fma(q, _PIO2_2, -p2)  # q P2 = p2 + p2_err exactly
    h, t = _two_sum(r1, -p2)
    y0, y1 = _two_sum(h, (t - p2_err) - q * _PIO2_3)
    # 3. kernels (fdlibm k_sin.c, FreeBSD k_cos.c)
    z = y0 * y0
    v = z * y0
    ps = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
    sin_r = y0 - ((z * (0.5 * y1 - v * ps) - y1) - v * _S1)
    w = z * z
    pc = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    one_hz = 1.0 - hz
    cos_r = one_hz + (((1.0 - one_hz) - hz) + (z * pc - y0 * y1))
    # 4. quadrant fix-up: m = q mod 4 in {0, 1, 2, 3}
    m = q - 4.0 * _floor(0.25 * q)
    odd = (m == 1.0) | (m == 3.0)
    a = cos_r if odd else sin_r
    b = sin_r if odd else cos_r
    s = -a if m >= 2.0 else a
    c = -b if (m == 1.0) | (m == 2.0) else b
    ok = abs(x) <= XMAX  # False for NaN
    return (s if ok else np.nan), (c if ok else np.nan)


# Cephes atan.c (S. L. Moshier): atan(t) = t + t z P(z)/Q(z), z = t², on |t| <= 0.66; relative error below
# 2.2e-16 (rms 0.5 ulp) there.
_AT_P0 = -8.750608600031904122785e-01
_AT_P1 = -1.615753718733365076637e01
_AT_P2 = -7.500855792314704667340e01
_AT_P3 = -1.228866684490136173410e02
_AT_P4 = -6.485021904942025371773e01
_AT_Q0 = 2.485846490142306297962e01  # Q is monic: z^5 + Q0 z^4 + ... + Q4
_AT_Q1 = 1.650270098316988542046e02
_AT_Q2 = 4.328810604912902668951e02
_AT_Q3 = 4.853903996359136964868e02
_AT_Q4 = 1.945506571482613964425e02
_PIO4 = 0.7853981633974483  # RN(pi/4)
_PI = 3.141592653589793  # RN(pi)
_PI_LO = 1.2246467991473532e-16  # pi - RN(pi)


@jit(inline=True)
def atan2(y, x):
    """Angle of the point ``(x, y)``, branch-free, for use inside vectorised numba loops.

    Parameters
    ----------
    y, x : float
        Coordinates (any scale: only their ratio is used).

    Returns
    -------
    float
        ``atan2(y, x)`` in ``[-pi, pi]``, within 2 ulp of libm's (``tests/test_trig.py``). NaN if either
        argument is NaN; ``(0, 0)`` gives 0 and two infinities give NaN (libm gives multiples of ``pi/4``:
        neither is a direction a perturbation can have).

    Notes
    -----
    ``t = min/max`` of ``|x|, |y|`` in ``[0, 1]``; above 0.66 the identity
    ``atan t = pi/4 + atan((t - 1)/(t + 1))`` formed as ``(min - max)/(min + max)`` (one division either way)
    brings the argument into ``|t| <= 0.66``, where Cephes' rational approximation holds; then the octant is
    restored by ``pi/2 - a`` (``|y| > |x|``), ``pi - a`` (``x < 0``) and the sign of ``y``, each carrying the
    low part of the constant.
    """
    ax = abs(x)
    ay = abs(y)
    big = _max(ax, ay)
    small = _min(ax, ay)
    upper = small > 0.66 * big
    t = (small - big if upper else small) / (small + big if upper else big)
    z = t * t
    p = (((_AT_P0 * z + _AT_P1) * z + _AT_P2) * z + _AT_P3) * z + _AT_P4
    q = ((((z + _AT_Q0) * z + _AT_Q1) * z + _AT_Q2) * z + _AT_Q3) * z + _AT_Q4
    a = t + t * (z * p / q)
    a = (_PIO4 + (a + 0.5 * _PIO2_2)) if upper else a  # atan of small/big, in [0, pi/4]
    a = (_PIO2_1 - a) + _PIO2_2 if ay > ax else a  # in [0, pi/2]
    a = (_PI - a) + _PI_LO if x < 0.0 else a  # in [0, pi]
    a = 0.0 if big == 0.0 else a
    a = a if (x == x) & (y == y) else np.nan  # max/min would drop a NaN
    return -a if y < 0.0 else a
