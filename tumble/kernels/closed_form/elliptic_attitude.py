"""The closed form's attitude, one sample and one time at a time (:func:`tumble.physics.exact.attitude`).

Written once for both devices: :func:`attitude_constants` sets up a sample (once) and :func:`attitude_at` gives its
body-to-space quaternion at one time from its angular velocity there; the CPU runs them over samples and then over
every (sample, time) pair in parallel (:func:`attitude_setup`, :func:`attitude_rows`), a CUDA thread over its
sample's times (:mod:`tumble.kernels.cuda.closed_form`), numba-cuda compiling these ``@jit`` functions for the device.

The formulas are those of :func:`tumble.physics.exact.attitude` (Landau & Lifshitz §35, §37): in the frame where
``L`` is along ``Z`` the rotation is ``R_z(φ) R_x(θ) R_z(ψ)`` in the body axes ``(a, b, p)`` (``p`` the axis whose
component goes as ``dn``); ``θ, ψ`` from the body-frame direction of ``L``, ``ψ`` carried continuously through the
amplitude ``am u``; the precession angle

``φ(t) = |L| t / I_p + |L| (I_p - I_q) / (I_q I_p ν) [Π(u) - Π(u0)]``,

``Π(u) = ∫_0^u du' / (1 - n sn² u')``, an elliptic integral of the third kind: ``2 j Π(n|m) + Π(n; am r | m)`` for
``u = 2K j + r``, ``|r| <= K``, with Carlson's
``Π(n; φ|m) = s R_F(c², d², 1) + (n/3) s³ R_J(c², d², 1, 1 - n s²)`` (DLMF 19.25.14; ``s, c, d = sn, cn, dn (r)``).
``R_F`` is :func:`tumble.kernels.closed_form.elliptic.carlson_rf`; ``R_J`` is Carlson's duplication algorithm
(:func:`carlson_rj`). On the separatrix (and for ``k' < 1e-100``, where ``sn = tanh`` to rounding on ``[-K, K]``)
the integral is elementary. Steady spins turn uniformly about their fixed axis.

Everything here is compiled without contraction (:func:`tumble.kernels.jit.jit`'s ``contract=False``): the CPU's
parallel loop would otherwise fuse other products when compiled than when loaded from numba's cache, and a cold
and a warm run disagree in the last bits. (On a GPU NVVM fuses multiply-adds all the same.)

Kernels take plain float64 arrays and scalars and write into arrays they are given.
"""

import math

import numpy as np

from .elliptic import (KIND_SEPARATRIX, KIND_STATIONARY, _LANDEN_MAX, _sech, _setup, _sncndn_core, _sncndn_shifted,
                       carlson_rf)
from ..jit import jit
from ..threads import in_parallel
from ..trig import _max

__all__ = ["CONSTANTS", "LANDEN", "attitude_at", "attitude_constants", "attitude_rows", "attitude_setup", "carlson_rj"]

#: Length of a Landen table of :func:`tumble.kernels.closed_form.elliptic._setup` (``a`` and ``c``, one each per sample).
LANDEN = _LANDEN_MAX

# The per-sample constants of attitude_constants, by index
(_KIND, _SEPARATRIX, _TINY, _K, _KC, _PHASE0, _NU, _IP, _IA, _IB, _CA, _CB, _CP, _SIZE, _COEF, _INTEGRAL0, _A, _N,
 _COMPLETE, _SIGN_Y, _X_POSITIVE, _SWAP, _F0, _F1, _F2, _F3, _S0, _S1, _S2, _S3, _SPIN, _AXIS0, _AXIS1, _AXIS2, _CK,
 _CH, _CQ, _NTERMS, _NLANDEN, _CKK) = range(40)
#: Length of a sample's constants (:func:`attitude_constants`).
CONSTANTS = 40

# Carlson's R_J (Carlson, Numer. Algorithms 10 (1995) 13, §2): the duplication stops once 4^-m Q < |A_m|,
# Q = (r/4)^(-1/6) max|A_0 - x_i|; the series to E5 is then in error by less than r (relative).
_RJ_TOLERANCE = 1e-17
_RJ_Q = (_RJ_TOLERANCE / 4.0) ** (-1.0 / 6.0)
# Below this complementary modulus the integral takes the separatrix form (Carlson's arguments cn², dn² underflow).
_KC_TANH = 1e-100


@jit(contract=False)
def _rc_one(e):
    """Carlson's ``R_C(1, 1 + e)`` for ``e > -1``: ``atan(sqrt e)/sqrt e``, ``atanh(sqrt(-e))/sqrt(-e)``, 1 at 0."""
    if e > 0.0:
        s = math.sqrt(e)
        return math.atan(s) / s
    if e < 0.0:
        s = math.sqrt(-e)
        return math.atanh(s) / s
    return 1.0


@jit(contract=False)
def carlson_rj(x, y, z, p):
    """Carlson's symmetric integral ``R_J(x, y, z, p)`` for ``x, y, z >= 0`` (at most one zero) and ``p > 0``, by
    duplication and the series to fifth order (Carlson 1995, §2; the algorithm of ``scipy.special.elliprj`` and
    Boost), to about one ulp."""
    a0 = (x + y + z + p + p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    big = _RJ_Q * _max(abs(a0 - x), abs(a0 - y), abs(a0 - z), abs(a0 - p))
    a = a0
    xm, ym, zm, pm = x, y, z, p
    fourm = 1.0  # 4^-m
    total = 0.0
    for _ in range(100):
        if fourm * big < abs(a):
            break
        sx, sy, sz, sp = math.sqrt(xm), math.sqrt(ym), math.sqrt(zm), math.sqrt(pm)
        lam = sx * sy + sx * sz + sy * sz
        d = (sp + sx) * (sp + sy) * (sp + sz)
        total += fourm / d * _rc_one(fourm * fourm * fourm * delta / (d * d))
        a = 0.25 * (a + lam)
        xm, ym, zm, pm = 0.25 * (xm + lam), 0.25 * (ym + lam), 0.25 * (zm + lam), 0.25 * (pm + lam)
        fourm *= 0.25
    X = (a0 - x) * fourm / a
    Y = (a0 - y) * fourm / a
    Z = (a0 - z) * fourm / a
    P = -0.5 * (X + Y + Z)
    xyz = X * Y * Z
    P2 = P * P
    e2 = X * Y + X * Z + Y * Z - 3.0 * P2
    e3 = xyz + 2.0 * e2 * P + 4.0 * P2 * P
    e4 = (2.0 * xyz + e2 * P + 3.0 * P2 * P) * P
    e5 = xyz * P2
    series = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0 - 9.0 * e2 * e3 / 52.0
              + 3.0 * e5 / 26.0)
    return fourm / (a * math.sqrt(a)) * series + 6.0 * total


@jit(contract=False)
def _sncndn(u, kc, K, k, h, q, nterms, a, c, nlanden):
    """``sn, cn, dn`` of ``u`` for complementary modulus ``kc`` (set up by :func:`tumble.kernels.closed_form.elliptic._setup`),
    one element of :func:`tumble.kernels.closed_form.elliptic.jacobi_sncndn` (``kc = 0``: ``tanh, sech, sech``)."""
    if kc == 0.0:
        sech = _sech(u)
        return math.tanh(u), sech, sech
    if abs(u) <= 0.5 * K:
        sn, cn, dn = _sncndn_core(abs(u), kc, k, h, q, nterms, a, c, nlanden)
        return (-sn if u < 0.0 else sn), cn, dn
    return _sncndn_shifted(u - K, kc, K, k, h, q, nterms, a, c, nlanden)


@jit(contract=False)
def _tangent(v, a):
    """``∫_0^v du / (1 + a² tanh² u)``: the integral on the separatrix (``sn = tanh``)."""
    return (v + a * math.atan(a * math.tanh(v))) / (1.0 + a * a)


@jit(contract=False)
def _pi_integral(u, cst, landen_a, landen_c):
    """``(Π(u), am u)`` of a sample (module docstring), ``u`` its elliptic argument (separatrix: that of tanh)."""
    separatrix = cst[_SEPARATRIX] != 0.0
    K, n_char, a_char = cst[_K], cst[_N], cst[_A]
    if separatrix:
        j = 0.0
        r = u
        zero = np.int64(0)  # (not the literal 0: a second compiled variant of the sn cn dn chain)
        s, c, d = _sncndn(r, 0.0, 0.0, 0.0, 0.0, 0.0, zero, landen_a, landen_c, zero)
    else:
        j = math.floor(u / (2.0 * K) + 0.5)
        r = u - 2.0 * K * j
        s, c, d = _sncndn(r, cst[_KC], cst[_CKK], cst[_CK], cst[_CH], cst[_CQ], int(cst[_NTERMS]), landen_a,
                          landen_c, int(cst[_NLANDEN]))
    amplitude = j * math.pi + math.atan2(s, c)
    if separatrix:
        return _tangent(u, a_char), amplitude
    if cst[_TINY] != 0.0:
        incomplete = _tangent(r, a_char)
    else:
        c2, d2 = c * c, d * d
        incomplete = s * carlson_rf(c2, d2, 1.0) + (n_char / 3.0) * (s * s * s) * carlson_rj(c2, d2, 1.0,
                                                                                                1.0 - n_char * s * s)
    return 2.0 * j * cst[_COMPLETE] + incomplete, amplitude


@jit(inline=True, contract=False)
def _product(a0, a1, a2, a3, b0, b1, b2, b3):
    """Hamilton product ``a ⊗ b`` (:func:`tumble.physics.rotations.product`)."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@jit(inline=True, contract=False)
def _pick(v0, v1, v2, k):
    return v0 if k == 0 else (v1 if k == 1 else v2)


@jit(contract=False)
def _round_half_even(x):
    r = math.floor(x + 0.5)
    if r - x == 0.5 and r - 2.0 * math.floor(0.5 * r) != 0.0:  # a tie rounded up to an odd number
        r -= 1.0
    return r


@jit(contract=False)
def _local(cst, landen_a, landen_c, t, w0, w1, w2):
    """``R_z(φ) R_x(θ) R_z(ψ)`` times the frame of the axes ``(a, b, p)`` at time ``t``, for the angular velocity
    ``(w0, w1, w2)`` there: the rotation before it is taken relative to the start."""
    ca, cb, cp = int(cst[_CA]), int(cst[_CB]), int(cst[_CP])
    la = cst[_IA] * _pick(w0, w1, w2, ca)
    lb = cst[_IB] * _pick(w0, w1, w2, cb)
    lp = cst[_IP] * _pick(w0, w1, w2, cp)
    theta = math.atan2(math.hypot(la, lb), lp)
    u = (cst[_K] + cst[_PHASE0]) + cst[_NU] * t  # separatrix: K is 0 here
    integral, am = _pi_integral(u, cst, landen_a, landen_c)
    phi = cst[_SIZE] * t / cst[_IP] + cst[_COEF] * (integral - cst[_INTEGRAL0])
    reference = cst[_SIGN_Y] * am if cst[_X_POSITIVE] != 0.0 else math.pi - cst[_SIGN_Y] * am
    if cst[_SWAP] != 0.0:
        reference = 0.5 * math.pi - reference
    z = math.atan2(la, lb) - reference
    psi = reference + (z - 2.0 * math.pi * _round_half_even(z / (2.0 * math.pi)))
    hp, ht, hs = 0.5 * phi, 0.5 * theta, 0.5 * psi
    q = _product(math.cos(hp), 0.0, 0.0, math.sin(hp), math.cos(ht), math.sin(ht), 0.0, 0.0)
    q = _product(q[0], q[1], q[2], q[3], math.cos(hs), 0.0, 0.0, math.sin(hs))
    return _product(q[0], q[1], q[2], q[3], cst[_F0], cst[_F1], cst[_F2], cst[_F3])


@jit(contract=False)
def attitude_constants(m0, m1, m2, w0, w1, w2, kind, amp_q, amp_m, cq, cm, cp, kc, K, phase0, nu, s0, s1, s2, cst,
                       landen_a, landen_c):
    # size: one sample's set-up as the closed form gives it (flat scalars, DESIGN.md), into the arrays it is given
    """Set up one sample of :func:`attitude_at` into ``cst`` (:data:`CONSTANTS`,) and its Landen tables ``landen_a``,
    ``landen_c`` (:data:`LANDEN`,): the moments ``m``, the initial spin ``w`` (rad/s), the closed form's set-up of the
    spin (``kind``, the amplitudes of the ``cn`` and ``sn`` terms, the columns ``cq, cm, cp`` of the ``cn, sn, dn``
    terms, ``k'``, ``K``, the initial phase, ``ν``: :func:`tumble.physics.exact.solve_rows`) and its angular velocity
    ``s`` at ``t = 0`` as the closed form evaluates it."""
    cst[_KIND] = kind
    if kind == KIND_STATIONARY:
        spin = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        n0, n1, n2 = (w0, w1, w2) if spin > 0.0 else (1.0, 0.0, 0.0)
        norm = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        cst[_SPIN], cst[_AXIS0], cst[_AXIS1], cst[_AXIS2] = spin, n0 / norm, n1 / norm, n2 / norm
        return
    moments = (m0, m1, m2)
    Iq, Im, Ip = moments[cq], moments[cm], moments[cp]
    separatrix = kind == KIND_SEPARATRIX
    ca, cb = (cp + 1) % 3, (cp + 2) % 3
    cst[_SEPARATRIX] = 1.0 if separatrix else 0.0
    cst[_TINY] = 1.0 if not separatrix and kc < _KC_TANH else 0.0
    cst[_K] = 0.0 if separatrix else K
    cst[_KC], cst[_PHASE0], cst[_NU] = (0.0 if separatrix else kc), phase0, nu
    cst[_IP], cst[_IA], cst[_IB] = Ip, moments[ca], moments[cb]
    cst[_CA], cst[_CB], cst[_CP] = ca, cb, cp
    size = math.sqrt((m0 * w0) ** 2 + (m1 * w1) ** 2 + (m2 * w2) ** 2)  # |L|
    cst[_SIZE] = size
    cst[_COEF] = size * (Ip - Iq) / (Iq * Ip * nu)
    n_char = -Ip * (Im - Iq) / (Iq * (Ip - Im))
    cst[_N], cst[_A] = n_char, math.sqrt(-n_char)
    for index in (_CKK, _CK, _CH, _CQ, _NTERMS, _NLANDEN, _COMPLETE):
        cst[index] = 0.0
    if not separatrix:  # the constants of jacobi_sncndn's kc, its own K included (the same formula as the set-up's)
        cst[_CKK], cst[_CK], cst[_CH], cst[_CQ], cst[_NTERMS], cst[_NLANDEN] = _setup(kc, landen_a, landen_c)
        if cst[_TINY] != 0.0:
            cst[_COMPLETE] = _tangent(K, cst[_A])
        else:
            k2 = kc * kc
            cst[_COMPLETE] = carlson_rf(0.0, k2, 1.0) + (n_char / 3.0) * carlson_rj(0.0, k2, 1.0, 1.0 - n_char)
    X, Y = Iq * amp_q, Im * amp_m
    cst[_SIGN_Y] = 1.0 if Y > 0.0 else (-1.0 if Y < 0.0 else (0.0 if Y == 0.0 else math.nan))
    cst[_X_POSITIVE] = 1.0 if X > 0.0 else 0.0
    cst[_SWAP] = 1.0 if ca != cm else 0.0
    # the frame of the axes (a, b, p): a proper rotation taking body coordinates to (a, b, p)
    if cp == 0:
        cst[_F0], cst[_F1], cst[_F2], cst[_F3] = 0.5, -0.5, -0.5, -0.5
    elif cp == 1:
        cst[_F0], cst[_F1], cst[_F2], cst[_F3] = 0.5, 0.5, 0.5, 0.5
    else:
        cst[_F0], cst[_F1], cst[_F2], cst[_F3] = 1.0, 0.0, 0.0, 0.0
    cst[_INTEGRAL0] = _pi_integral(cst[_K] + phase0, cst, landen_a, landen_c)[0]
    start = _local(cst, landen_a, landen_c, 0.0, s0, s1, s2)
    cst[_S0], cst[_S1], cst[_S2], cst[_S3] = start


@jit(contract=False)
def attitude_at(cst, landen_a, landen_c, t, w0, w1, w2):
    """The body-to-space quaternion (scalar first, ``q(0) = 1``) at time ``t`` of a sample set up by
    :func:`attitude_constants`, from its angular velocity ``(w0, w1, w2)`` at ``t`` (rad/s, as the closed form
    evaluates it): four floats."""
    if cst[_KIND] == KIND_STATIONARY:
        half = 0.5 * (cst[_SPIN] * t)
        s = math.sin(half)
        return math.cos(half), s * cst[_AXIS0], s * cst[_AXIS1], s * cst[_AXIS2]
    q = _local(cst, landen_a, landen_c, t, w0, w1, w2)
    return _product(cst[_S0], -cst[_S1], -cst[_S2], -cst[_S3], q[0], q[1], q[2], q[3])


@jit(contract=False)
def attitude_setup(moments, w, kind, amp, cols, kc, K, phase0, nu, start, cst, landen_a, landen_c):
    # size: the closed form's per-sample set-up arrays (flat, as its kernels take them), and the three it fills
    """:func:`attitude_constants` of every sample (one loop: a few microseconds a sample, against the times' work;
    a parallel loop here is not worth its threads): ``moments`` and ``w`` (n, 3), the set-up arrays of
    :func:`tumble.physics.exact.solve_rows` (``kind`` (n,), ``amp`` and ``cols`` (n, 3), ``kc``, ``K``, ``phase0``,
    ``nu`` (n,)), ``start`` (n, 3) the angular velocity at ``t = 0``; fills ``cst`` (n, CONSTANTS) and ``landen_a``,
    ``landen_c`` (n, LANDEN)."""
    for i in range(w.shape[0]):
        attitude_constants(moments[i, 0], moments[i, 1], moments[i, 2], w[i, 0], w[i, 1], w[i, 2], kind[i],
                           amp[i, 0], amp[i, 1], cols[i, 0], cols[i, 1], cols[i, 2], kc[i], K[i], phase0[i], nu[i],
                           start[i, 0], start[i, 1], start[i, 2], cst[i], landen_a[i], landen_c[i])


def attitude_rows(cst, landen_a, landen_c, times, omega, out):
    """:func:`attitude_at` of every sample at every time, in parallel over (sample, time) pairs (a long trajectory of
    one sample uses every core): ``times`` (T,), ``omega`` (n, T, 3) the angular velocity there; ``out`` (n, T, 4)
    receives the quaternions."""
    in_parallel(attitude_rows_share, omega.shape[0] * omega.shape[1], cst, landen_a, landen_c, times, omega, out)


@jit(contract=False)
def attitude_rows_share(cst, landen_a, landen_c, times, omega, out, start, stop):
    """The (sample, time) pairs ``start:stop`` of :func:`attitude_rows`, sample-major (one share of
    :func:`tumble.kernels.threads.in_parallel`)."""
    t_count = omega.shape[1]
    for k in range(start, stop):
        i = k // t_count
        j = k - i * t_count
        out[i, j, 0], out[i, j, 1], out[i, j, 2], out[i, j, 3] = attitude_at(
            cst[i], landen_a[i], landen_c[i], times[j], omega[i, j, 0], omega[i, j, 1], omega[i, j, 2])
