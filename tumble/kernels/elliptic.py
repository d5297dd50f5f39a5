"""Jacobi elliptic functions that keep relative accuracy up to the parameter ``m = 1``.

numba kernels for the exact torque-free solution (:mod:`tumble.physics.exact`). Everything here takes the
*complementary modulus* ``kc = k' = sqrt(1 - m)`` instead of ``m``: near the separatrix of the free rigid
body ``k'`` is proportional to the distance from the separatrix, and ``1 - m`` rounded to a double would
already have lost it.

Method
------
1. **Argument reduction about the quarter period** (DLMF Table 22.4.3, quarter-period shifts). The argument is carried
   as ``s = u - K``; with ``s = 2 K n + r``, ``|r| <= K``,

   * ``|r| <= K/2``:  ``sn u = (-1)^n cd r``, ``cn u = (-1)^(n+1) k' sd r``, ``dn u = k' nd r``;
   * ``|r| >  K/2``:  with ``x = K - |r|``, ``sn u = (-1)^n sn x``, ``cn u = -(-1)^n sign(r) cn x``,
     ``dn u = dn x``,

   so that ``sn, cn, dn`` are only ever evaluated on ``0 <= x <= K/2``, where ``cn x`` and ``dn x`` are at
   least ``sqrt(k'/(1+k'))`` and every quotient above is formed from quantities that are accurate
   *relative to themselves*. In particular the tiny values ``cn u, dn u ~ k'`` near ``u = K`` (a spin
   close to the intermediate axis) come out with full relative accuracy.
2. **Core on 0 <= x <= K/2**

   * ``k' < KC_HYPERBOLIC``: hyperbolic (sech/tanh) series, which are the Fourier series DLMF 22.11.1-3
     carried through Jacobi's imaginary transformation (DLMF 22.6(iv)), i.e. with the roles of ``K`` and
     ``K'`` exchanged (equivalently, the partial-fraction sums of DLMF 22.12 summed in the other order;
     checked term by term against mpmath), with ``h = pi/(2K') = AGM(1, k)`` and ``beta = pi K/K'``::

        dn x = h       sum_n        sech(h x - n beta)
        cn x = (h/k)   sum_n (-1)^n sech(h x - n beta)
        sn x = (h/k) [tanh(h x) + sum_{n>=1} (-1)^n (tanh(h x + n beta) + tanh(h x - n beta))]

     The terms fall off like ``q = exp(-beta)``, the nome of the complementary modulus (``~ k'^2/16``);
     every sum is dominated by its ``n = 0`` term, so there is no cancellation, and at ``k' -> 0`` the
     series reduce to ``tanh, sech, sech``. With ``exp(-y)`` computed once, the terms follow by
     multiplication by ``q``: two exponentials per evaluation.
   * otherwise: the descending Landen transformation / arithmetic-geometric mean (Abramowitz & Stegun
     16.4; King, "Evaluating Jacobi elliptic functions", 2007), started from ``(1, k')`` so that ``k'``
     enters exactly, with ``c_{n+1} = c_n^2 / (4 a_{n+1})`` (no cancellation) and
     ``dn = sqrt(cn^2 + k'^2 sn^2)``.

3. **Complete integrals** by the AGM: ``K = pi / (2 AGM(1, k'))``, ``K' = pi / (2 AGM(1, k))``;
   the incomplete integral (for initial arguments) by Carlson's ``R_F`` (DLMF 19.25.5).

Measured against mpmath (``tests/test_elliptic.py``): relative error of ``sn, cn, dn`` below
``4 eps (1 + |u|)`` for ``k'`` from 1 down to 1e-15, plus ``4 eps |u|`` times the slope near their zeros.

Kernels take plain float64 arrays and scalars and write into arrays they are given.
"""

import math

import numba
import numpy as np

from .jit import jit

__all__ = ["KC_HYPERBOLIC", "agm", "carlson_rf", "jacobi_sncndn", "torque_free_omega", "torque_free_setup"]

#: Below this complementary modulus the hyperbolic series is used (11 terms a side just below 0.5, 3 at
#: k' = 1e-3, 2 at 1e-8); above it the Landen/AGM recursion (<= 6 steps), whose ``cn`` on
#: ``[0, K/2]`` is then >= 0.57 and so keeps relative accuracy.
KC_HYPERBOLIC = 0.5

# Stop the series when a term is below this fraction of the leading one.
_SERIES_TOL = 1e-17
# Landen recursion stops when c_n / a_n < this.
_AGM_TOL = 1e-17
_AGM_MAXITER = 64
# Landen table size (descending Landen from k' >= KC_HYPERBOLIC needs at most 6 steps).
_LANDEN_MAX = 16

# Kinds of motion, per sample, understood by torque_free_omega.
KIND_STATIONARY = 0
KIND_ELLIPTIC = 1
KIND_SEPARATRIX = 2


@jit
def agm(a, b):
    """Arithmetic-geometric mean of two non-negative floats (``AGM(1, k')`` gives ``K``).

    Stops once ``|a - b| <= 1e-8 a``: the next mean ``(a + b)/2`` is then within ``(a - b)^2 / (16 a)``,
    i.e. 1e-17 relative, of the limit (quadratic convergence), and no tolerance near one ulp is needed.
    """
    for _ in range(_AGM_MAXITER):
        if abs(a - b) <= 1e-8 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return 0.5 * (a + b)


# Carlson's R_F by duplication (Carlson, Numer. Algorithms 10 (1995) 13; Numerical Recipes §6.11): the
# series is cut after E2^2 and E2 E3; with |deviation| < _RF_TOL its remainder is below ~1e-19.
_RF_TOL = 1e-3


@jit
def carlson_rf(x, y, z):
    """Carlson's symmetric integral ``R_F(x, y, z)`` for ``x, y, z >= 0``, at most one of them zero."""
    for _ in range(200):
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * (sy + sz) + sy * sz
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        ave = (x + y + z) / 3.0
        dx = (ave - x) / ave
        dy = (ave - y) / ave
        dz = (ave - z) / ave
        if max(abs(dx), abs(dy), abs(dz)) < _RF_TOL:
            break
    e2 = dx * dy - dz * dz
    e3 = dx * dy * dz
    return (1.0 + (e2 / 24.0 - 0.1 - 3.0 * e3 / 44.0) * e2 + e3 / 14.0) / math.sqrt(ave)


@jit
def _sech(z):
    e = math.exp(-abs(z))
    return 2.0 * e / (1.0 + e * e)


@jit
def _landen_table(kc, a, c):
    """Fill ``a[0..n]``, ``c[0..n]`` of the descending Landen/AGM sequence from ``(1, kc)``; return n."""
    a[0] = 1.0
    b = kc
    c[0] = math.sqrt((1.0 - kc) * (1.0 + kc))
    n = 0
    while c[n] > _AGM_TOL * a[n] and n < _LANDEN_MAX - 1:
        a[n + 1] = 0.5 * (a[n] + b)
        c[n + 1] = c[n] * c[n] / (4.0 * a[n + 1])
        b = math.sqrt(a[n] * b)
        n += 1
    return n


@jit
def _sncndn_core(x, kc, k, h, q, nterms, a, c, nlanden):
    """sn, cn, dn at ``0 <= x <~ K/2`` with relative accuracy; see the module docstring.

    Hyperbolic branch: with ``e = exp(-y)``, ``y = h x`` and ``q = exp(-beta)``, the n-th terms are
    ``sech(n beta -+ y) = 2 z/(1 + z^2)`` with ``z = q^n e^(+-y)``, and
    ``tanh(y + n beta) + tanh(y - n beta) = (1 - tanh(n beta - y)) - (1 - tanh(n beta + y))
    = sinh(2y) sech(n beta - y) sech(n beta + y)``; only two exponentials per call.
    """
    if kc < KC_HYPERBOLIC:
        y = h * x
        em = math.exp(-y)
        em2 = em * em
        om = -math.expm1(-2.0 * y)  # 1 - e^{-2y}, accurate for small y
        dsum = 2.0 * em / (1.0 + em2)  # sech y
        csum = dsum
        ssum = om / (1.0 + em2)  # tanh y
        if q > 0.0:
            ep = 1.0 / em
            sinh2y = 2.0 * ssum / (dsum * dsum)  # 2 tanh y cosh^2 y
            small = y < 1.0
            pn = 1.0
            sgn = -1.0
            for _ in range(nterms):
                pn *= q
                zp = pn * ep
                zm = pn * em
                zp2 = zp * zp
                zm2 = zm * zm
                s1 = 2.0 * zp / (1.0 + zp2)
                s2 = 2.0 * zm / (1.0 + zm2)
                dsum += s1 + s2
                csum += sgn * (s1 + s2)
                if small:
                    ssum += sgn * sinh2y * s1 * s2
                else:
                    ssum += sgn * (2.0 * zp2 / (1.0 + zp2) - 2.0 * zm2 / (1.0 + zm2))
                sgn = -sgn
        return (h / k) * ssum, (h / k) * csum, h * dsum
    phi = a[nlanden] * x
    for _ in range(nlanden):
        phi *= 2.0
    for n in range(nlanden, 0, -1):
        phi = 0.5 * (phi + math.asin(c[n] / a[n] * math.sin(phi)))
    sn = math.sin(phi)
    cn = math.cos(phi)
    if nlanden == 0:  # m < 1e-34: dn = 1 to double precision (and exactly 1 for a symmetric top)
        return sn, cn, 1.0
    dn = math.sqrt(cn * cn + kc * kc * sn * sn)
    return sn, cn, dn


@jit
def _setup(kc, a, c):
    """Per-modulus constants: (K, k, h, q, nterms, nlanden); ``q = exp(-pi K/K')``."""
    k = math.sqrt((1.0 - kc) * (1.0 + kc))
    K = 0.5 * math.pi / agm(1.0, kc)
    h = agm(1.0, k)  # = pi / (2 K')
    beta = 2.0 * K * h  # = pi K / K'
    q = math.exp(-beta)
    nterms = 0
    nlanden = 0
    if kc < KC_HYPERBOLIC:
        # n-th term / leading term <= exp(-(n - 1/2) beta) on 0 <= x <= K/2
        nterms = int(math.ceil(-math.log(_SERIES_TOL) / beta + 0.5))
    else:
        nlanden = _landen_table(kc, a, c)
    return K, k, h, q, nterms, nlanden


@jit
def _sncndn_shifted(s, kc, K, k, h, q, nterms, a, c, nlanden):
    """sn, cn, dn of ``u = K + s`` (any real s), reduced about the quarter period."""
    n = math.floor(s / (2.0 * K) + 0.5)
    r = s - 2.0 * K * n
    par = 1.0 - 2.0 * (n - 2.0 * math.floor(0.5 * n))  # (-1)^n
    ar = abs(r)
    sg = 1.0 if r >= 0.0 else -1.0
    if ar <= 0.5 * K:
        sx, cx, dx = _sncndn_core(ar, kc, k, h, q, nterms, a, c, nlanden)
        return par * cx / dx, -par * sg * kc * sx / dx, kc / dx
    x = K - ar
    if x < 0.0:
        x = 0.0
    sx, cx, dx = _sncndn_core(x, kc, k, h, q, nterms, a, c, nlanden)
    return par * sx, -par * sg * cx, dx


@jit
def jacobi_sncndn(u, kc, out):
    """Jacobi ``sn, cn, dn`` of ``u`` for parameter ``m = 1 - kc**2``, with relative accuracy up to m = 1.

    Parameters
    ----------
    u : ndarray, shape (n,)
        Arguments (dimensionless).
    kc : ndarray, shape (n,)
        Complementary moduli ``k' = sqrt(1 - m)``, ``0 <= k' <= 1`` (``k' = 0``: ``tanh, sech, sech``).
    out : ndarray, shape (n, 3)
        Receives ``sn, cn, dn``.

    Notes
    -----
    Relative accuracy holds for all three functions away from the zeros of ``sn`` and ``cn``; there the
    error is absolute, ``~ eps * |u|``, as the argument itself carries that much. Arguments beyond
    ``K/2`` are reduced as ``u - K``, so near ``u = K`` (where ``cn, dn ~ k'``) the offset ``u - K`` is
    only as accurate as ``u``; :func:`torque_free_omega` carries that offset directly instead.
    """
    a = np.empty(_LANDEN_MAX)
    c = np.empty(_LANDEN_MAX)
    last = -1.0
    K = k = h = q = 0.0
    nterms = nlanden = 0
    for i in range(u.shape[0]):
        if kc[i] == 0.0:  # m = 1: K = inf
            out[i, 0] = math.tanh(u[i])
            out[i, 1] = _sech(u[i])
            out[i, 2] = out[i, 1]
            continue
        if kc[i] != last:
            K, k, h, q, nterms, nlanden = _setup(kc[i], a, c)
            last = kc[i]
        if abs(u[i]) <= 0.5 * K:  # keep relative accuracy of sn near u = 0
            sn, cn, dn = _sncndn_core(abs(u[i]), kc[i], k, h, q, nterms, a, c, nlanden)
            if u[i] < 0.0:
                sn = -sn
        else:
            sn, cn, dn = _sncndn_shifted(u[i] - K, kc[i], K, k, h, q, nterms, a, c, nlanden)
        out[i, 0] = sn
        out[i, 1] = cn
        out[i, 2] = dn


@jit
def torque_free_setup(I, perm, parity, w, spin_scale, delta, kind, amp, cols, kc, m, K, phase0, nu, e2, L2):
    """Per-sample parameters of the torque-free motion (Landau & Lifshitz §37) for torque_free_omega.

    With the sorted moments ``I1 <= I2 <= I3`` and ``p, q`` the axes whose components go as ``dn, cn``
    (``p = 3, q = 1`` when ``L² > 2E I2``, else ``p = 1, q = 3``)::

        A_q² = |2E Ip - L²| / (Iq |Ip - Iq|),   A_mid² = |2E Ip - L²| / (I2 |Ip - I2|),
        A_p² = |L² - 2E Iq| / (Ip |Ip - Iq|),   m = |Iq - I2| |2E Ip - L²| / (|Ip - I2| |L² - 2E Iq|),
        k'² = |Ip - Iq| |L² - 2E I2| / (|Ip - I2| |L² - 2E Iq|),   |nu|² = |Ip - I2| |L² - 2E Iq| / (I1 I2 I3),

    each difference of invariants formed as a sum of terms of one sign, ``L² - 2E I2`` given. The initial
    argument is carried as ``r0 = u0 - K - 2K n0`` (``n0 = 0`` if ``w_mid >= 0`` else 1, folded into the
    signs of the ``cn, sn`` amplitudes), from ``sn r0 = -(w_q/A_q)(A_p/|w_p|)``,
    ``cn r0 = (|w_mid|/A_mid)(A_p k'/|w_p|)``: ``r0 = sn R_F(cn², dn², 1)``. On the separatrix
    ``sinh u0 = (w_mid/A_mid)(A_q/|w_q|)``. ``nu`` takes the sign of ``w_p`` (times ``w_q`` on the
    separatrix) and of the sorting permutation.

    Parameters
    ----------
    I : ndarray, shape (n, 3)
        Sorted principal moments of each sample's body (any common scale), ``I[i, 0] <= I[i, 1] <= I[i, 2]``.
    perm : ndarray of int64, shape (n, 3)
        ``perm[i, j]``: the caller's axis holding sorted moment ``j`` of sample ``i``'s body.
    parity : ndarray, shape (n,)
        +1 where ``perm[i]`` is an even permutation, else -1.
    w : ndarray, shape (n, 3)
        Initial angular velocities in the caller's axis order, rad/s.
    spin_scale : ndarray, shape (n,)
        Powers of two with ``|w| / spin_scale < 1``; the invariants are formed from ``w / spin_scale``.
    delta : ndarray, shape (n,)
        ``L² - 2E I2`` of the scaled spins, correctly rounded.
    kind, amp, cols, kc, m, K, phase0, nu : ndarray
        Receive the inputs of :func:`torque_free_omega`, ``m`` and ``K`` (shapes (n,), (n, 3), (n, 3),
        (n,) ...).
    e2, L2 : ndarray, shape (n,)
        Receive ``2E`` and ``L²`` of the scaled spins.
    """
    for i in range(w.shape[0]):
        I1, I2, I3 = I[i, 0], I[i, 1], I[i, 2]
        p0, p1, p2 = perm[i, 0], perm[i, 1], perm[i, 2]
        sc = spin_scale[i]
        w1 = w[i, p0] / sc
        w2 = w[i, p1] / sc
        w3 = w[i, p2] / sc
        e2[i] = I1 * w1 * w1 + I2 * w2 * w2 + I3 * w3 * w3
        L2[i] = (I1 * w1) ** 2 + (I2 * w2) ** 2 + (I3 * w3) ** 2
        d = delta[i]
        # steady rotation: every term of w x (I w) vanishes exactly (zeros of the unscaled spin)
        z1 = w[i, p0] == 0.0
        z2 = w[i, p1] == 0.0
        z3 = w[i, p2] == 0.0
        stationary = (I2 == I3 or z2 or z3) and (I3 == I1 or z3 or z1) and (I1 == I2 or z1 or z2)
        cols[i, 0] = p0
        cols[i, 1] = p1
        cols[i, 2] = p2
        if stationary:
            kind[i] = KIND_STATIONARY
            amp[i, 0] = w[i, p0]
            amp[i, 1] = w[i, p1]
            amp[i, 2] = w[i, p2]
            kc[i] = 1.0
            m[i] = 0.0
            K[i] = 0.5 * math.pi
            phase0[i] = 0.0
            nu[i] = 0.0
            continue
        if d < 0.0:  # dn on the smallest-moment axis
            Ip, Iq, wp, wq = I1, I3, w1, w3
            cols[i, 0] = p2
            cols[i, 2] = p0
        else:
            Ip, Iq, wp, wq = I3, I1, w3, w1
        dpq = I3 - I1
        dp2 = abs(Ip - I2)
        dq2 = abs(Iq - I2)
        X = I2 * dp2 * w2 * w2 + Iq * dpq * wq * wq  # |2E Ip - L²|
        Y = I2 * dq2 * w2 * w2 + Ip * dpq * wp * wp  # |L² - 2E Iq|
        a_q = math.sqrt(X / (Iq * dpq))
        a_mid = math.sqrt(X / (I2 * dp2))
        a_p = math.sqrt(Y / (Ip * dpq))
        nu_abs = math.sqrt(dp2 * Y / (I1 * I2 * I3))
        s_p = -1.0 if wp < 0.0 else 1.0
        if d == 0.0:  # the separatrix: tanh, sech, sech
            s_q = -1.0 if wq < 0.0 else 1.0
            kind[i] = KIND_SEPARATRIX
            kc[i] = 0.0
            m[i] = 1.0
            K[i] = math.inf
            phase0[i] = math.asinh((w2 / a_mid) * (a_q / abs(wq)))
            nu[i] = s_p * s_q * parity[i] * nu_abs * sc
            amp[i, 0] = s_q * a_q * sc
            amp[i, 1] = a_mid * sc
            amp[i, 2] = s_p * a_p * sc
            continue
        kind[i] = KIND_ELLIPTIC
        mi = dq2 * X / (dp2 * Y)
        k_c = 1.0 if mi == 0.0 else math.sqrt(dpq / (dp2 * Y)) * math.sqrt(abs(d))
        sigma = -1.0 if w2 < 0.0 else 1.0  # (-1)^n0
        ratio = a_p / abs(wp)
        sn_r = -sigma * (wq / a_q) * ratio
        cn_r = sigma * (w2 / a_mid) * ratio * k_c
        norm = math.hypot(sn_r, cn_r)
        sn_r /= norm
        cn_r /= norm
        phase0[i] = sn_r * carlson_rf(cn_r * cn_r, cn_r * cn_r + (k_c * sn_r) ** 2, 1.0)
        kc[i] = k_c
        m[i] = mi
        K[i] = 0.5 * math.pi / agm(1.0, k_c)
        nu[i] = s_p * parity[i] * nu_abs * sc
        amp[i, 0] = sigma * a_q * sc
        amp[i, 1] = sigma * a_mid * sc
        # dn = 1 when m = 0 (a symmetric top): the symmetry-axis component is then exactly constant
        amp[i, 2] = wp * sc if mi == 0.0 else s_p * a_p * sc


@jit(parallel=True)
def torque_free_omega(kind, amp, cols, kc, phase0, nu, t, out):
    """Body-frame angular velocity of the free rigid body, sample by sample (Landau & Lifshitz §37).

    Parameters
    ----------
    kind : ndarray of int64, shape (n,)
        ``KIND_STATIONARY`` (constant), ``KIND_ELLIPTIC`` or ``KIND_SEPARATRIX``.
    amp : ndarray, shape (n, 3)
        Signed amplitudes, rad/s, of the components proportional to ``(cn, sn, dn)`` (elliptic),
        ``(sech, tanh, sech)`` (separatrix), or the constant components (stationary).
    cols : ndarray of int64, shape (n, 3)
        Output column of each of those three components.
    kc : ndarray, shape (n,)
        Complementary modulus ``k'`` (elliptic samples).
    phase0 : ndarray, shape (n,)
        Initial argument: ``u0 - K`` (elliptic) or ``u0`` (separatrix).
    nu : ndarray, shape (n,)
        Rate of the argument, rad/s: ``u = u0 + nu t``.
    t : ndarray, shape (T,)
        Times, s.
    out : ndarray, shape (n, T, 3)
        Receives the angular velocity, rad/s.
    """
    for i in numba.prange(kind.shape[0]):
        cq, cm, cp = cols[i, 0], cols[i, 1], cols[i, 2]
        aq, am, ap = amp[i, 0], amp[i, 1], amp[i, 2]
        if kind[i] == KIND_ELLIPTIC:
            a = np.empty(_LANDEN_MAX)  # per sample: samples run in parallel
            c = np.empty(_LANDEN_MAX)
            K, k, h, q, nterms, nlanden = _setup(kc[i], a, c)
            for j in range(t.shape[0]):
                s = phase0[i] + nu[i] * t[j]
                sn, cn, dn = _sncndn_shifted(s, kc[i], K, k, h, q, nterms, a, c, nlanden)
                out[i, j, cq] = aq * cn
                out[i, j, cm] = am * sn
                out[i, j, cp] = ap * dn
        elif kind[i] == KIND_SEPARATRIX:
            for j in range(t.shape[0]):
                v = phase0[i] + nu[i] * t[j]
                sech = _sech(v)
                out[i, j, cq] = aq * sech
                out[i, j, cm] = am * math.tanh(v)
                out[i, j, cp] = ap * sech
        else:
            for j in range(t.shape[0]):
                out[i, j, cq] = aq
                out[i, j, cm] = am
                out[i, j, cp] = ap
