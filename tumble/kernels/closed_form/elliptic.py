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

Vectorised evaluation
---------------------
:func:`jacobi_sncndn` (and the kept scalar reference ``_torque_free_omega_reference``) follow steps 1-3
literally, with ``asin``/``sin``/``exp`` from libm: a few 1e6 evaluations per second and core. The
torque-free kernel :func:`torque_free_omega` computes the same functions in a form whose time loop is
straight-line code that LLVM vectorises across times (AVX2: 4 doubles; ``tests/test_elliptic_vectorised.py``
checks the assembly): everything that depends on ``k'`` only is computed once per sample, and the choices
that depend on the time (``|r| <= K/2`` or not, the signs) are selects. Per time:

* the reduction of step 1 with ``n = floor(s (1/2K) + 1/2)`` and the core at ``x = |r|`` or ``K - |r|``,
  returning ``sn x = P S/D, cn x = C/D, dn x = E/D`` so that the quotients of step 1 cost one reciprocal;
* ``k' >= KC_HYPERBOLIC``: four descending Gauss (Landen) transformations in rational form (DLMF
  22.7.1-3; ``k_1 = (1 - k')/(1 + k') <= 1/3``, then ``k_(l+1) ~ k_l^2/4``, so ``k_4 <= 1.2e-8``),
  carried projectively, from ``sin, cos`` of ``v = x/P <= pi/4`` (the polynomials of
  :func:`tumble.kernels.trig.sincos`) with the first-order terms in ``k_4^2`` (DLMF 22.10.4-6).
  ``dn = (1 - k_1 s^2)/(1 + k_1 s^2)`` has no cancellation as ``k_1 s^2 <= 1/3``; for ``k' = 1`` every
  ``k_l`` is 0 and ``dn`` is exactly 1;
* ``k' < KC_HYPERBOLIC``: the hyperbolic series regrouped as power series in ``q e^(+-y)`` with
  per-sample coefficients (see :func:`_omega_row_hyperbolic`), from one branch-free ``exp``/``expm1``
  pair (Cody-Waite reduction, Taylor polynomials, ``2^k`` built in the exponent bits).

One time per sample (the final state alone): :func:`torque_free_omega_at` fuses the invariants, the set-up and
one evaluation per sample and skips the initial argument (Carlson's ``R_F``) by Jacobi's addition theorem.

Measured against mpmath on a quarter period (``tests/test_elliptic_vectorised.py``): at most 3.7 eps
relative (the scalar path: 3.8 eps), and within a few ulps of the scalar path everywhere.

Kernels take plain float64 arrays and scalars and write into arrays they are given.
"""

import math

import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

from ..jit import jit, subroutine
from ..threads import in_parallel
from ..trig import _C1, _C2, _C3, _C4, _C5, _C6, _S1, _S2, _S3, _S4, _S5, _S6, _floor, _fma, _max, _min

__all__ = ["KC_HYPERBOLIC", "TINY_TRANSVERSE", "agm", "carlson_rf", "complete_integrals", "hyperbolic_nome", "jacobi_sncndn", "regimes",
           "torque_free_omega", "torque_free_omega_at", "torque_free_solve"]

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

#: A spin whose two smaller components are both below this fraction of the largest (and not both zero) is
#: too close to a principal axis for the invariants: their squares underflow. torque_free_solve
#: and torque_free_omega_at count such samples; :mod:`tumble.physics.exact` moves them where the squares are safe (its ``_lift_tiny``).
TINY_TRANSVERSE = 2.0**-500
# torque_free_omega_at's lanes take spins whose smallest non-zero component is above 2^-100 of the largest (their
# squares and products stay far from underflow); the rest go one by one through the scalar path.
TINY_TRANSVERSE_SAFE = 2.0**100

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
def hyperbolic_nome(kc, K):
    """``(h, q)`` of the hyperbolic series for complementary modulus ``kc < KC_HYPERBOLIC`` and ``K = K(k)``:
    ``h = AGM(1, k) = pi/(2K')`` and the complementary nome ``q = exp(-pi K/K') = exp(-2 K h)`` (0 where every
    term it scales is negligible). Computed once per sample by the set-up (:func:`complete_integrals`);
    :func:`torque_free_omega` reads them."""
    k = math.sqrt((1.0 - kc) * (1.0 + kc))
    h = agm(1.0, k)  # = pi / (2 K')
    beta = 2.0 * K * h  # = pi K / K'
    return h, (math.exp(-beta) if beta < _BETA_NEGLIGIBLE else 0.0)


@jit
def complete_integrals(kc):
    """``(K, h, q)`` for complementary modulus ``kc`` (elliptic motion): ``K = K(k) = pi / (2 AGM(1, k'))`` and
    :func:`hyperbolic_nome`'s ``(h, q)`` where ``kc < KC_HYPERBOLIC`` (else zeros)."""
    K = 0.5 * math.pi / agm(1.0, kc)
    h, q = hyperbolic_nome(kc, K) if kc < KC_HYPERBOLIC else (0.0, 0.0)
    return K, h, q


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
        if _max(abs(dx), abs(dy), abs(dz)) < _RF_TOL:
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


@jit(inline=True)
def _two_sum(a, b):
    """``a + b = s + e`` exactly (Knuth, TAOCP vol. 2 §4.2.2): no multiply, so fast-math ``contract`` cannot
    touch it, and ``reassoc`` is not among tumble's flags."""
    s = a + b
    bb = s - a
    return s, (a - (s - bb)) + (b - bb)


@jit(inline=True)
def _two_prod(a, b):
    """``a b = p + e`` exactly, by one fused multiply-add (whatever the fast-math flags)."""
    p = a * b
    return p, _fma(a, b, -p)


@jit(inline=True)
def _dd_term(inertia, diff_hi, diff_lo, w):
    """``inertia * (diff_hi + diff_lo) * w * w`` as a double-double."""
    hi, lo = _two_prod(w, w)
    p, e = _two_prod(hi, inertia)
    hi, lo = _two_sum(p, e + lo * inertia)
    p, e = _two_prod(hi, diff_hi)
    return _two_sum(p, e + (lo * diff_hi + hi * diff_lo))


@jit(inline=True)
def _invariants_row(m0, m1, m2, w0, w1, w2):
    """One sample of the invariants of :func:`torque_free_solve`: ``(a, b, c, even, moment_scale, spin_scale, I1, I2, I3,
    delta, tiny)`` for moments ``(m0, m1, m2)`` and spin ``(w0, w1, w2)``."""
    moments = (m0, m1, m2)
    w = (w0, w1, w2)
    a, b, c = 0, 1, 2  # a stable sort of three: strict comparisons never swap equal moments
    if moments[a] > moments[b]:
        a, b = b, a
    if moments[b] > moments[c]:
        b, c = c, b
    if moments[a] > moments[b]:
        a, b = b, a
    even = (a, b, c) == (0, 1, 2) or (a, b, c) == (1, 2, 0) or (a, b, c) == (2, 0, 1)
    ms = math.ldexp(1.0, math.frexp(moments[c])[1])
    ss = math.ldexp(1.0, math.frexp(_max(abs(w0), abs(w1), abs(w2)))[1])
    I1, I2, I3 = moments[a] / ms, moments[b] / ms, moments[c] / ms
    w1s, w3s = w[a] / ss, w[c] / ss
    d32h, d32l = _two_sum(I3, -I2)
    d21h, d21l = _two_sum(I2, -I1)
    ah, al = _dd_term(I3, d32h, d32l, w3s)
    bh, bl = _dd_term(I1, d21h, d21l, w1s)
    s, e = _two_sum(ah, -bh)
    dh, dl = _two_sum(s, e + (al - bl))
    x, y, z = abs(w0), abs(w1), abs(w2)
    second = _max(_min(x, y), _min(_max(x, y), z))  # the middle of the three
    return a, b, c, even, ms, ss, I1, I2, I3, dh + dl, 0.0 < second < TINY_TRANSVERSE * _max(x, y, z)


@jit(inline=True)
def _solve_sample(j, m0, m1, m2, w, I, perm, parity, scaled, kind, amp, cols, params, nome):
    # size: one sample's invariants and set-up, written at index j of every array torque_free_solve fills
    """One sample of :func:`torque_free_solve` (moments ``m``, spin ``w``, an array (3,)), written at index ``j`` of
    its arrays; returns 1 if the spin is too close to an axis for its invariants (:data:`TINY_TRANSVERSE`), else 0.
    The spin's components are read from its array, never passed as values: the compiler then fuses the same
    products as when the invariants and the set-up were two kernels, so the bits are theirs."""
    p0, p1, p2, even, ms, ss, I1, I2, I3, d, small = _invariants_row(m0, m1, m2, w[0], w[1], w[2])
    perm[j, 0], perm[j, 1], perm[j, 2] = p0, p1, p2
    parity[j] = 1.0 if even else -1.0
    scaled[2, j], scaled[3, j], scaled[4, j] = d, ms, ss
    I[j, 0], I[j, 1], I[j, 2] = I1, I2, I3
    kind_j, cols_j, amp_j, k_c, mi, nu_j, sn_r, cn_r, scaled[0, j], scaled[1, j] = _setup_row(
        I1, I2, I3, p0, p1, p2, parity[j], ss, w[p0], w[p1], w[p2], d)
    kind[j] = kind_j
    cols[j, 0], cols[j, 1], cols[j, 2] = cols_j
    amp[j, 0], amp[j, 1], amp[j, 2] = amp_j
    params[0, j], params[1, j], params[4, j] = k_c, mi, nu_j
    params[2, j], params[3, j], nome[0, j], nome[1, j] = _elliptic_integrals(kind_j, k_c, sn_r, cn_r)
    return 1 if small else 0


@jit(inline=True)
def _elliptic_integrals(kind, k_c, sn_r, cn_r):
    """``(K, initial argument, h, q)`` of a sample set up by :func:`_setup_row` (``sn_r, cn_r``: its ``x, y``)."""
    if kind == KIND_STATIONARY:
        return 0.5 * math.pi, 0.0, 0.0, 0.0
    if kind == KIND_SEPARATRIX:
        return math.inf, math.asinh(sn_r), 0.0, 0.0
    phase0 = sn_r * carlson_rf(cn_r * cn_r, cn_r * cn_r + (k_c * sn_r) ** 2, 1.0)
    K, h, q = complete_integrals(k_c)
    return K, phase0, h, q


def torque_free_solve(moments, w, I, perm, parity, scaled, kind, amp, cols, params, nome):
    """Per-sample parameters of the torque-free motion (Landau & Lifshitz §37) for :func:`torque_free_omega`, from
    bodies and spins given one per row: the invariants, then the set-up, in one pass (one kernel call).

    **Invariants.** With the moments sorted (a stable sort: ties keep their order) as ``I1 <= I2 <= I3`` and both
    moments and spin divided by powers of two (exact; ``|w| / spin_scale < 1``),
    ``L² - 2E I2 = I3 (I3 - I2) w3² - I1 (I2 - I1) w1²`` is formed in double-double arithmetic (Dekker's
    products by fused multiply-add, Knuth's sums), so that it keeps its sign and relative accuracy however close
    the spin is to the separatrix.

    **Set-up.** With ``p, q`` the axes whose components go as ``dn, cn`` (``p = 3, q = 1`` when ``L² > 2E I2``, else
    ``p = 1, q = 3``)::

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
    moments, w : ndarray, shape (n, 3)
        Principal moments (kg m², validated) and body-frame spins (rad/s), one sample per row, in the caller's
        axis order.
    I : ndarray, shape (n, 3)
        Receives the sorted moments divided by the moment scale.
    perm : ndarray of int64, shape (n, 3)
        Receives the sorting permutation (``perm[i, j]``: the axis holding sorted moment ``j``).
    parity : ndarray, shape (n,)
        Receives +1 for an even permutation, -1 for an odd one.
    scaled : ndarray, shape (5, n)
        Receives ``2E``, ``L²`` and ``L² - 2E I2`` of the scaled spin and moments, and the moment and spin scales.
    kind, amp, cols : ndarray, shapes (n,) int64, (n, 3), (n, 3) int64
        Receive the regime, the signed amplitudes and their output columns (see :func:`torque_free_omega`).
    params : ndarray, shape (5, n)
        Receives ``k'``, ``m``, ``K``, the initial argument and ``nu`` of each sample.
    nome : ndarray, shape (2, n)
        Receives :func:`hyperbolic_nome` of the samples with ``k' < KC_HYPERBOLIC`` (else zeros).

    Returns
    -------
    int
        The number of samples whose two smaller components are below :data:`TINY_TRANSVERSE` of the largest,
        not both zero: their ``L² - 2E I2`` has lost its accuracy to underflow (the caller lifts them and calls
        again).
    """
    return in_parallel(torque_free_solve_share, w.shape[0], moments, w, I, perm, parity, scaled, kind, amp, cols, params,
                       nome)


@jit
def torque_free_solve_share(moments, w, I, perm, parity, scaled, kind, amp, cols, params, nome, start, stop):
    # size: flat per-sample arrays in and out (numba); the invariants and the four regimes (elliptic, separatrix,
    # symmetric, stationary) set up in one pass per sample
    """The samples ``start:stop`` of :func:`torque_free_solve` (one share of
    :func:`tumble.kernels.threads.in_parallel`)."""
    tiny = 0
    for i in range(start, stop):
        tiny += _solve_sample(i, moments[i, 0], moments[i, 1], moments[i, 2], w[i], I, perm, parity, scaled, kind, amp,
                              cols, params, nome)
    return tiny


@jit(inline=True)
def _setup_row(I1, I2, I3, p0, p1, p2, parity, sc, wa, wb, wc, d):
    # size: one sample's sorted moments, permutation and spin in; flat scalars for the kernels that inline it
    """One sample of the set-up of :func:`torque_free_solve` (the formulas are in its docstring), without the elliptic integrals.

    ``wa, wb, wc`` are the spin's components on the axes ``p0, p1, p2`` (unscaled), ``d`` its ``L² - 2E I2``.
    Returns ``(kind, cols, amp, k', m, nu, x, y, 2E, L²)``: elliptic, ``x, y = sn r0, cn r0`` (normalised, so
    ``r0 = x R_F(y², y² + k'² x², 1)``); on the separatrix ``x = sinh u0``; stationary, zeros.
    """
    w1 = wa / sc
    w2 = wb / sc
    w3 = wc / sc
    e2 = I1 * w1 * w1 + I2 * w2 * w2 + I3 * w3 * w3
    L2 = (I1 * w1) ** 2 + (I2 * w2) ** 2 + (I3 * w3) ** 2
    # steady rotation: every term of w x (I w) vanishes exactly (zeros of the unscaled spin)
    z1 = wa == 0.0
    z2 = wb == 0.0
    z3 = wc == 0.0
    stationary = (I2 == I3 or z2 or z3) and (I3 == I1 or z3 or z1) and (I1 == I2 or z1 or z2)
    if stationary:
        return KIND_STATIONARY, (p0, p1, p2), (wa, wb, wc), 1.0, 0.0, 0.0, 0.0, 0.0, e2, L2
    cq, cp = p0, p2
    if d < 0.0:  # dn on the smallest-moment axis
        Ip, Iq, wp, wq = I1, I3, w1, w3
        cq, cp = p2, p0
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
        return (KIND_SEPARATRIX, (cq, p1, cp), (s_q * a_q * sc, a_mid * sc, s_p * a_p * sc), 0.0, 1.0,
                s_p * s_q * parity * nu_abs * sc, (w2 / a_mid) * (a_q / abs(wq)), 0.0, e2, L2)
    mi = dq2 * X / (dp2 * Y)
    k_c = 1.0 if mi == 0.0 else math.sqrt(dpq / (dp2 * Y)) * math.sqrt(abs(d))
    sigma = -1.0 if w2 < 0.0 else 1.0  # (-1)^n0
    ratio = a_p / abs(wp)
    sn_r = -sigma * (wq / a_q) * ratio
    cn_r = sigma * (w2 / a_mid) * ratio * k_c
    norm = math.hypot(sn_r, cn_r)
    # dn = 1 when m = 0 (a symmetric top): the symmetry-axis component is then exactly constant
    amp_p = wp * sc if mi == 0.0 else s_p * a_p * sc
    return (KIND_ELLIPTIC, (cq, p1, cp), (sigma * a_q * sc, sigma * a_mid * sc, amp_p), k_c, mi,
            s_p * parity * nu_abs * sc, sn_r / norm, cn_r / norm, e2, L2)


@jit
def _torque_free_omega_reference(kind, amp, cols, kc, phase0, nu, t, out, start, stop):
    """The scalar kernel :func:`torque_free_omega` replaced: one time grid, libm calls, per-sample arrays.

    Kept as the reference the vectorised kernel is tested and benchmarked against (same arguments but a
    single time grid ``t``, shape (T,), of times in s, and no ``K``, ``nome`` nor ``row``: ``kind``, ``amp``, ``cols``,
    ``kc``, ``phase0`` and ``nu`` as :func:`torque_free_omega` takes them); it evaluates ``sn, cn, dn`` with
    :func:`_sncndn_shifted` into ``out`` (n, T, 3), rad/s; the samples ``start:stop`` (one share of
    :func:`tumble.kernels.threads.in_parallel`).
    """
    a = np.empty(_LANDEN_MAX)
    c = np.empty(_LANDEN_MAX)
    for i in range(start, stop):
        cq, cm, cp = cols[i, 0], cols[i, 1], cols[i, 2]
        aq, am, ap = amp[i, 0], amp[i, 1], amp[i, 2]
        if kind[i] == KIND_ELLIPTIC:
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


# ------------------------------------------------------------------------------------------------------
# Vectorised kernel: straight-line code in the time loop (see "Vectorised evaluation" in the module
# docstring). Everything below that runs per time is branch-free: selects, no libm calls, one reciprocal.

#: Descending Gauss (Landen) levels used for ``k' >= KC_HYPERBOLIC``: the bottom modulus is then at most
#: 1.2e-8 (``k' = 0.5``), and the first-order correction in ``m = k_4^2 <= 1.4e-16`` leaves ``O(m^2)``.
LANDEN_LEVELS = 4  # unrolled by hand in _landen_constants and _omega_row_landen
# The hyperbolic series keep 7 terms for dn, cn (powers z^1 .. z^13) and 6 for sn (j = 1 .. 6): enough
# down to beta = pi K/K' = 4.02 (k' = 0.5), where the first omitted term is below e^-42 of the leading one.
#: From this ``beta = pi K/K'`` on (``k' <~ 1.3e-3``, a spin near the intermediate axis) two terms of each
#: hyperbolic series suffice (:func:`_omega_row_hyperbolic`'s ``short``).
BETA_SHORT_SERIES = 16.0
# Beyond this beta (k' < ~1e-17) every series correction is below e^-40 of the leading term: q is set to
# 0, which also keeps the products of tiny powers of q out of the (slow) subnormal range.
_BETA_NEGLIGIBLE = 80.0

# exp(x) = 2^k exp(r), r = x - k ln 2 (Cody & Waite 1980, ch. 6): ln 2 = _LN2_HI + _LN2_LO + O(2^-110).
_INV_LN2 = 1.4426950408889634
_LN2_HI = 0.6931471805599453  # RN(ln 2): x - k _LN2_HI is exact by one FMA (|k| < 2^11)
_LN2_LO = 2.3190468138462996e-17  # RN(ln 2 - _LN2_HI)
# expm1(r) = r + r^2 (1/2! + r/3! + ... + r^11/13!) on |r| <= ln2/2 (+ rounding of k): the first omitted
# term r^14/14! is below 1.2e-17 |r| there (Taylor; a minimax fit would save a term or two).
_E2, _E3, _E4, _E5 = 0.5, 0.16666666666666666, 0.041666666666666664, 0.008333333333333333
_E6, _E7, _E8, _E9 = 0.001388888888888889, 0.0001984126984126984, 2.48015873015873e-05, 2.7557319223985893e-06
_E10, _E11, _E12, _E13 = 2.755731922398589e-07, 2.505210838544172e-08, 2.08767569878681e-09, 1.6059043836821613e-10
_E14 = 1.1470745597729725e-11
# Adding 1.5 * 2^52 to an integral double k (|k| < 2^51) leaves k in the low mantissa bits.
_INT_SHIFTER = 6755399441055744.0
# The exponent field of an IEEE-754 double.
_EXPONENT_BITS = 0x7FF0000000000000
# Arguments below this give exp = 0 (and expm1 = -1) in double precision.
_EXP_XMIN = -1000.0


@intrinsic
def _float64_bits(typingctx, x):
    """The IEEE-754 bits of a float64 as int64 (an LLVM ``bitcast``: free, and vectorisable)."""
    if not isinstance(x, types.Float):
        return None

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[0], signature.args[0], types.float64)
        return builder.bitcast(value, ir.IntType(64))

    return types.int64(x), codegen


@intrinsic
def _bits_float64(typingctx, i):
    """The float64 whose IEEE-754 bits are the int64 ``i`` (an LLVM ``bitcast``)."""
    if not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        value = context.cast(builder, args[0], signature.args[0], types.int64)
        return builder.bitcast(value, ir.DoubleType())

    return types.float64(i), codegen


@jit(inline=True)
def _pow2(k):
    """``2^k`` for an integral double ``-1022 <= k <= 1023``, built in the exponent field (no conversion
    to an integer type, which AVX2 cannot vectorise for int64)."""
    return _bits_float64((_float64_bits(k + _INT_SHIFTER) + 1023) << 52)


@jit(inline=True)
def _exp_expm1(x):
    """``(exp x, exp x - 1)`` for ``x <= 0``, both to about 1 ulp relative, branch-free.

    Cody-Waite reduction ``x = k ln 2 + r`` (``|r| <~ ln2/2``, ``r`` exact by one FMA), Taylor polynomial
    for ``p = expm1 r``, then ``exp x = 2^k (1 + p)`` and ``expm1 x = (2^k - 1) + 2^k p`` (``2^k - 1`` is
    exact for ``k >= -53``; for ``k = 0``, i.e. ``|x| <~ 0.35``, ``expm1 x = p`` keeps full relative
    accuracy near 0). ``2^k`` is formed as ``2^k1 2^k2`` so that it may be subnormal; below ``_EXP_XMIN``
    the results are 0 and -1. NaN in gives NaN out.
    """
    x = _EXP_XMIN if x < _EXP_XMIN else x  # noqa: FURB136 (max() need not keep a NaN)
    k = _floor(x * _INV_LN2 + 0.5)
    r = _fma(-k, _LN2_HI, x)  # exact
    r = _fma(-k, _LN2_LO, r)
    poly = _E9 + r * (_E10 + r * (_E11 + r * (_E12 + r * _E13)))
    poly = _E2 + r * (_E3 + r * (_E4 + r * (_E5 + r * (_E6 + r * (_E7 + r * (_E8 + r * poly))))))
    p = _fma(r * r, poly, r)
    k1 = _floor(0.5 * k)
    scale = _pow2(k1) * _pow2(k - k1)  # exact while 2^k is normal
    return _fma(scale, p, scale), _fma(scale, p, scale - 1.0)


@jit(inline=True)
def _quarter_period_reduction(s, K, two_k, inv_two_k):
    """``s = u - K = 2 K n + r``: returns ``(x, near, par, sg)`` with ``x = |r|`` (``near``, ``|r| <= K/2``)
    or ``K - |r|``, ``par = (-1)^n``, ``sg = sign r`` (module docstring, step 1); selects only."""
    n = _floor(s * inv_two_k + 0.5)
    r = s - two_k * n
    par = 1.0 - 2.0 * (n - 2.0 * _floor(0.5 * n))
    ar = abs(r)
    sg = 1.0 if r >= 0.0 else -1.0
    near = ar <= 0.5 * K
    far_x = K - ar
    far_x = 0.0 if far_x < 0.0 else far_x  # noqa: FURB136 (a NaN must stay NaN)
    x = ar if near else far_x
    return x, near, par, sg


@jit(inline=True)
def _unreduce(S, C, E, D, P, kc, near, par, sg):
    """``sn, cn, dn`` of ``u`` from ``sn x = P S/D, cn x = C/D, dn x = E/D`` (module docstring, step 1):
    ``near``: ``(cd, -k' sd, k' nd)(x)``, else ``(sn, -cn, dn)(x)``, signs by ``par, sg``; one reciprocal."""
    PS = P * S
    den = E if near else D
    a = C if near else PS
    b = kc * PS if near else C
    c = kc * D if near else E
    inv = 1.0 / den
    return par * (a * inv), -(par * sg) * (b * inv), c * inv


@jit(inline=True)
def _column_weights(cq, cm, cp, aq, am, ap):
    """The amplitudes as a 3x3 matrix, flat: ``W[3c + f]`` multiplies function ``f`` (0: the ``cq``
    component, 1: ``cm``, 2: ``cp``) in output column ``c``; one non-zero per row and column."""
    return (aq if cq == 0 else 0.0, am if cm == 0 else 0.0, ap if cp == 0 else 0.0,
            aq if cq == 1 else 0.0, am if cm == 1 else 0.0, ap if cp == 1 else 0.0,
            aq if cq == 2 else 0.0, am if cm == 2 else 0.0, ap if cp == 2 else 0.0)


@jit(inline=True)
def _store(out, j, W, fq, fm, fp):
    """``out[3j + c] = sum_f W[3c + f] f``: the amplitude times the one function that goes to column ``c``,
    exactly (the other two products are zeros). Written as arithmetic with a stride known to be 3 so that
    the stores vectorise: selects on the columns (or indexing by them) keep LLVM from vectorising the loop.
    (A non-finite value spreads to the sample's other columns at that time.)"""
    out[3 * j] = W[0] * fq + W[1] * fm + W[2] * fp
    out[3 * j + 1] = W[3] * fq + W[4] * fm + W[5] * fp
    out[3 * j + 2] = W[6] * fq + W[7] * fm + W[8] * fp


@subroutine
def _landen_constants(kc):
    """Per-modulus constants of the descending Gauss transformation (DLMF 22.7.1-3) from ``k' >= 1/2``.

    Returns ``(kap, quarter_m, P)``: ``kap[l - 1] = k_l (prod_{i > l} (1 + k_i))^2`` for the levels
    ``l = 1 .. LANDEN_LEVELS``, ``quarter_m = k_L^2 / 4`` for the bottom correction and
    ``P = prod_l (1 + k_l)``. ``k_1 = (1 - k')/(1 + k')`` (exact difference), then without cancellation
    ``k_{l+1} = k_l^2/(1 + k_l')^2`` and ``k_{l+1}' = 2 sqrt(k_l')/(1 + k_l')``.
    """
    k1 = (1.0 - kc) / (1.0 + kc)
    c1 = 2.0 * math.sqrt(kc) / (1.0 + kc)
    k2 = k1 * k1 / ((1.0 + c1) * (1.0 + c1))
    c2 = 2.0 * math.sqrt(c1) / (1.0 + c1)
    k3 = k2 * k2 / ((1.0 + c2) * (1.0 + c2))
    c3 = 2.0 * math.sqrt(c2) / (1.0 + c2)
    k4 = k3 * k3 / ((1.0 + c3) * (1.0 + c3))
    f4 = 1.0 + k4
    f3 = (1.0 + k3) * f4
    f2 = (1.0 + k2) * f3
    kap = (k1 * f2 * f2, k2 * f3 * f3, k3 * f4 * f4, k4)
    return kap, 0.25 * k4 * k4, (1.0 + k1) * f2


@subroutine
def _series_constants(q):
    """Coefficients of the hyperbolic series regrouped as power series in ``z = q e^(+-y)`` (see
    :func:`_omega_row_hyperbolic`): ``(-1)^i/(1 -+ q^(2i+1))`` for dn and cn, ``(-1)^(j-1)/(1 + q^(2j))``
    for sn."""
    q2 = q * q
    q4 = q2 * q2
    q6 = q4 * q2
    q8 = q4 * q4
    q10 = q8 * q2
    q12 = q8 * q4
    odd = (q, q * q2, q * q4, q * q6, q * q8, q * q10, q * q12)
    dcoef = (1.0 / (1.0 - odd[0]), -1.0 / (1.0 - odd[1]), 1.0 / (1.0 - odd[2]), -1.0 / (1.0 - odd[3]),
             1.0 / (1.0 - odd[4]), -1.0 / (1.0 - odd[5]), 1.0 / (1.0 - odd[6]))
    ccoef = (1.0 / (1.0 + odd[0]), -1.0 / (1.0 + odd[1]), 1.0 / (1.0 + odd[2]), -1.0 / (1.0 + odd[3]),
             1.0 / (1.0 + odd[4]), -1.0 / (1.0 + odd[5]), 1.0 / (1.0 + odd[6]))
    scoef = (1.0 / (1.0 + q2), -1.0 / (1.0 + q4), 1.0 / (1.0 + q6), -1.0 / (1.0 + q8), 1.0 / (1.0 + q10),
             -1.0 / (1.0 + q12))
    return dcoef, ccoef, scoef


@jit(inline=True)
def _horner7(w, c):
    return c[0] + w * (c[1] + w * (c[2] + w * (c[3] + w * (c[4] + w * (c[5] + w * c[6])))))


@jit(inline=True)
def _sin_cos_octant(v):
    """``sin v, cos v`` for ``|v| <= pi/4`` (a little beyond is fine): the polynomials of
    :func:`tumble.kernels.trig.sincos` (fdlibm ``k_sin``, FreeBSD ``k_cos``) without its argument
    reduction, which the Landen core does not need (``0 <= v <= K/(2P) = pi/4 (1 + O(k_5))``)."""
    z = v * v
    ps = _S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))
    sin_v = v + (z * v) * (_S1 + z * ps)
    w = z * z
    pc = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    one_hz = 1.0 - hz
    return sin_v, one_hz + (((1.0 - one_hz) - hz) + z * pc)


@jit(inline=True)
def _gauss_level(s_b, f, g, d, e, kap):
    """One descending Gauss transformation in projective form, ``(S, C, E, D) <- (S D, C E, D^2 - kap S^2,
    D^2 + kap S^2)``, on the deviations ``S = s_b (1 + f)``, ``C = c_b (1 + g)``, ``E = 1 + e``,
    ``D = 1 + d``: each rounding is then relative to a deviation (at most ~1/3) rather than to 1."""
    S = s_b + s_b * f
    t = kap * (S * S)
    dd = d * (2.0 + d)
    return f + d + f * d, g + e + g * e, dd + t, dd - t


@subroutine
def _omega_row_landen(ph, nu, t, K, kc, kap, quarter_m, P, out, W):
    """One elliptic sample with ``k' >= KC_HYPERBOLIC`` at the times ``t`` into ``out`` (3T,).

    Core on ``[0, K/2]``: ``LANDEN_LEVELS`` descending Gauss transformations in rational form (DLMF 22.7.1-3),
    ``sn(x|k) = (1 + k1) s/(1 + k1 s^2)``, ``cn = c d/(1 + k1 s^2)``, ``dn = (1 - k1 s^2)/(1 + k1 s^2)`` with
    ``s, c, d`` at ``x/(1 + k1)`` and modulus ``k1``, carried projectively as ``sn = P S/D, cn = C/D,
    dn = E/D`` (no division per level; see :func:`_gauss_level`); at the bottom ``sin v, cos v``
    (:func:`_sin_cos_octant`) with the first-order terms in ``m = k_L^2`` (DLMF 22.10.4-6, here below 1.4e-16).
    """
    two_k = 2.0 * K
    inv_two_k = 1.0 / two_k
    inv_p = 1.0 / P
    for j in range(t.shape[0]):
        sn, cn, dn = _landen_at(ph + nu * t[j], K, two_k, inv_two_k, inv_p, kc, kap, quarter_m, P)
        _store(out, j, W, cn, sn, dn)


@jit(inline=True)
def _landen_at(s, K, two_k, inv_two_k, inv_p, kc, kap, quarter_m, P):
    """``sn, cn, dn`` of ``u = K + s`` by :func:`_omega_row_landen`'s core (``two_k = 2K``, ``inv_p = 1/P``)."""
    k1, k2, k3, k4 = kap
    x, near, par, sg = _quarter_period_reduction(s, K, two_k, inv_two_k)
    v = x * inv_p
    sv, cv = _sin_cos_octant(v)
    w = quarter_m * (v - sv * cv)
    s_b = sv - w * cv
    c_b = cv + w * sv
    # levels 4 .. 1 on the deviations S = s_b (1 + f), C = c_b (1 + g), E = 1 + e, D = 1 + d
    f, g, d, e = _gauss_level(s_b, 0.0, 0.0, 0.0, -2.0 * quarter_m * sv * sv, k4)
    f, g, d, e = _gauss_level(s_b, f, g, d, e, k3)
    f, g, d, e = _gauss_level(s_b, f, g, d, e, k2)
    f, g, d, e = _gauss_level(s_b, f, g, d, e, k1)
    S = s_b + s_b * f
    C = c_b + c_b * g
    E = 1.0 + e
    D = 1.0 + d
    return _unreduce(S, C, E, D, P, kc, near, par, sg)


@jit(inline=True)
def _exp_both(x):
    """``(exp x, exp x - 1, exp -x)`` for ``-708 <= x <= 0`` (``2^k`` normal), each to about 1 ulp, branch-free.

    As :func:`_exp_expm1`, but with ``exp(+-r) = cosh r +- r (sinh r / r)`` from one even and one odd
    Taylor polynomial in ``r^2`` (the first omitted terms are ``r^14/14!`` and ``r^14/15!``, below 5e-18),
    so ``exp -x = 2^-k exp -r`` costs no division; ``expm1 x = 2^k ((cosh r - 1) + r sinh r / r) + (2^k - 1)``.
    """
    k = _floor(x * _INV_LN2 + 0.5)
    r = _fma(-k, _LN2_HI, x)  # exact
    r = _fma(-k, _LN2_LO, r)
    z = r * r
    cosh_m1 = z * (_E2 + z * (_E4 + z * (_E6 + z * (_E8 + z * (_E10 + z * (_E12 + z * _E14))))))
    rsinh = r * (1.0 + z * (_E3 + z * (_E5 + z * (_E7 + z * (_E9 + z * (_E11 + z * _E13))))))
    scale = _pow2(k)
    em1 = cosh_m1 + rsinh  # exp r - 1
    return _fma(scale, em1, scale), _fma(scale, em1, scale - 1.0), _pow2(-k) * (1.0 + (cosh_m1 - rsinh))


@jit(inline=True)
def _hyperbolic_core(x, h, hk, q):
    """Leading terms of the hyperbolic series at ``y = h x``: returns ``(em, om, den, zp, zm)`` with
    ``em = e^-y``, ``om = 1 - e^-2y``, ``den = 1 + e^-2y`` (``sech y = 2 em/den``, ``tanh y = om/den``),
    ``zp = q e^y``, ``zm = q e^-y``."""
    em, em_m1, ep = _exp_both(-(h * x))
    return em, -em_m1 * (1.0 + em), 1.0 + em * em, q * ep, q * em


@jit(inline=True)
def _hyperbolic_unreduce(em, om, den, zp, zm, dser, cser, hsum, h, hk, kc, near, par, sg):
    """``sn, cn, dn`` from the series sums (see :func:`_omega_row_hyperbolic`), all over the common
    denominator ``den``: ``sn x = hk (om - 2 (a - b) den hsum)/den``, ``cn x = hk (2 em - 2 cser den)/den``,
    ``dn x = h (2 em + 2 dser den)/den``, with ``(a - b) den = zp^2 om den^2``."""
    S = hk * (om - 2.0 * ((zp * zp) * om * (den * den)) * hsum)
    C = hk * (2.0 * em - 2.0 * cser * den)
    E = h * (2.0 * em + 2.0 * dser * den)
    return _unreduce(S, C, E, den, 1.0, kc, near, par, sg)


@subroutine
def _omega_row_hyperbolic(ph, nu, t, K, kc, h, hk, q, dcoef, ccoef, scoef, out, W, short):
    """One elliptic sample with ``k' < KC_HYPERBOLIC`` at the times ``t`` into ``out`` (3T,).

    The sech/tanh series of the module docstring with each term expanded geometrically in
    ``z_n = q^n e^(+-y)`` (all ``< e^(-3 beta/4)``) and summed over ``n`` first, which turns them into
    power series in ``zp = q e^y`` and ``zm = q e^-y`` with per-modulus coefficients (no division per
    term)::

        dn x / h       = sech y + 2 sum_i (-1)^i (zp^(2i+1) + zm^(2i+1)) / (1 - q^(2i+1))
        cn x k / h     = sech y - 2 sum_i (-1)^i (zp^(2i+1) + zm^(2i+1)) / (1 + q^(2i+1))
        sn x k / h     = tanh y - 2 sum_j (-1)^(j-1) (a^j - b^j) / (1 + q^(2j)),   a = zp^2, b = zm^2,

    with ``a^j - b^j = (a - b) sum_i a^(j-1-i) b^i``, ``a - b = a (1 - e^-4y)`` (no cancellation at small
    ``y``). Every correction is below ``e^(-beta/2) <= 0.14`` of the leading term, so no sum cancels.
    Kept: ``i <= 6`` and ``j <= 6``, enough for ``beta >= 4.02`` (``k' <= 0.5``: the first omitted term is
    below ``e^-42`` of the leading one). One ``exp`` pair (:func:`_exp_both`) and one reciprocal per time.

    ``short`` (for ``beta >= BETA_SHORT_SERIES``, ``k' <~ 1.3e-3``) keeps ``i <= 1`` and ``j <= 2``
    (:func:`_hyperbolic_short_at`): the first omitted terms are below ``e^-56`` and ``e^-72`` of the leading one.
    The choice is made once per sample, outside the loop over the times, each loop vectorised on its own.
    """
    two_k = 2.0 * K
    inv_two_k = 1.0 / two_k
    if short:
        for j in range(t.shape[0]):
            sn, cn, dn = _hyperbolic_short_at(ph + nu * t[j], K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef)
            _store(out, j, W, cn, sn, dn)
    else:
        for j in range(t.shape[0]):
            sn, cn, dn = _hyperbolic_at(ph + nu * t[j], K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef)
            _store(out, j, W, cn, sn, dn)


@jit(inline=True)
def _hyperbolic_at(s, K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef):
    """``sn, cn, dn`` of ``u = K + s`` by :func:`_omega_row_hyperbolic`'s series."""
    g1, g2, g3, g4, g5, g6 = scoef
    x, near, par, sg = _quarter_period_reduction(s, K, two_k, inv_two_k)
    em, om, den, zp, zm = _hyperbolic_core(x, h, hk, q)
    a = zp * zp
    b = zm * zm
    dser = zp * _horner7(a, dcoef) + zm * _horner7(b, dcoef)
    cser = zp * _horner7(a, ccoef) + zm * _horner7(b, ccoef)
    p5 = g5 + a * g6  # P_i(a) = g_(i+1) + a P_(i+1)(a)
    p4 = g4 + a * p5
    p3 = g3 + a * p4
    p2 = g2 + a * p3
    p1 = g1 + a * p2
    hsum = p1 + b * (p2 + b * (p3 + b * (p4 + b * (p5 + b * g6))))
    return _hyperbolic_unreduce(em, om, den, zp, zm, dser, cser, hsum, h, hk, kc, near, par, sg)


@jit(inline=True)
def _hyperbolic_short_at(s, K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef):
    """``sn, cn, dn`` of ``u = K + s`` by the short series of :func:`_omega_row_hyperbolic` (``short``)."""
    d0, d1 = dcoef[0], dcoef[1]
    c0, c1 = ccoef[0], ccoef[1]
    g1, g2 = scoef[0], scoef[1]
    x, near, par, sg = _quarter_period_reduction(s, K, two_k, inv_two_k)
    em, om, den, zp, zm = _hyperbolic_core(x, h, hk, q)
    a = zp * zp
    b = zm * zm
    dser = zp * (d0 + a * d1) + zm * (d0 + b * d1)
    cser = zp * (c0 + a * c1) + zm * (c0 + b * c1)
    hsum = g1 + (a + b) * g2
    return _hyperbolic_unreduce(em, om, den, zp, zm, dser, cser, hsum, h, hk, kc, near, par, sg)


@subroutine
def _omega_row_separatrix(ph, nu, t, out, W):
    """One separatrix sample: ``(sech, tanh, sech)(u0 + nu t)`` into ``out`` (3T,), branch-free:
    ``tanh|v| = (1 - e^-2|v|)/(1 + e^-2|v|)``, ``sech v = 2 e^-|v|/(1 + e^-2|v|)``."""
    for j in range(t.shape[0]):
        sech, tanh = _sech_tanh(ph + nu * t[j])
        _store(out, j, W, sech, tanh, sech)


@jit(inline=True)
def _sech_tanh(v):
    """``sech v, tanh v`` (see :func:`_omega_row_separatrix`)."""
    em, em_m1 = _exp_expm1(-abs(v))
    inv_den = 1.0 / (1.0 + em * em)
    tanh = -em_m1 * (1.0 + em) * inv_den
    return 2.0 * em * inv_den, tanh if v >= 0.0 else -tanh


@jit(inline=True)
def _omega_row(kind, k_c, K, h, q, phase0, nu, t, o, W):
    """One sample of :func:`torque_free_omega` at the times ``t``, into its flattened row ``o`` (``W``: its
    :func:`_column_weights`), whatever its regime (the device's kernels; the CPU runs one kernel per regime)."""
    if kind == KIND_ELLIPTIC:
        if k_c >= KC_HYPERBOLIC:
            _landen_row(k_c, K, phase0, nu, t, o, W)
        else:
            _hyperbolic_row(k_c, K, h, q, phase0, nu, t, o, W)
    elif kind == KIND_SEPARATRIX:
        _omega_row_separatrix(phase0, nu, t, o, W)
    else:
        for j in range(t.shape[0]):
            _store(o, j, W, 1.0, 1.0, 1.0)


@jit(inline=True)
def _landen_row(k_c, K, phase0, nu, t, o, W):
    """An elliptic sample with ``k' >= KC_HYPERBOLIC``: its constants, then :func:`_omega_row_landen`."""
    kap, quarter_m, P = _landen_constants(k_c)
    _omega_row_landen(phase0, nu, t, K, k_c, kap, quarter_m, P, o, W)


@jit(inline=True)
def _hyperbolic_row(k_c, K, h, q, phase0, nu, t, o, W):
    """An elliptic sample with ``k' < KC_HYPERBOLIC``: its constants, then :func:`_omega_row_hyperbolic`."""
    k = math.sqrt((1.0 - k_c) * (1.0 + k_c))
    beta = 2.0 * K * h  # = pi K / K'
    dcoef, ccoef, scoef = _series_constants(q)
    _omega_row_hyperbolic(phase0, nu, t, K, k_c, h, h / k, q, dcoef, ccoef, scoef, o, W, beta >= BETA_SHORT_SERIES)


@jit(inline=True)
def _count_non_finite(o):
    """1 if the row ``o`` holds a value that is not finite, else 0 (a packed integer OR over a row still in cache)."""
    bad = 0
    for j in range(o.shape[0]):
        bad |= 0 if abs(o[j]) < math.inf else 1
    return bad


def torque_free_omega(kind, amp, cols, kc, K, nome, phase0, nu, times, row, out):
    """Body-frame angular velocity of the free rigid body, sample by sample (Landau & Lifshitz §37).

    Samples run in parallel, one kernel per regime met (:func:`regimes`: the Landen and hyperbolic cores, the
    separatrix; a stationary sample's constant components are written here): a first call compiles the rows of the
    regimes its samples meet, no other. Each sample's time loop is straight-line code that LLVM vectorises across
    times (module docstring, "Vectorised evaluation"). The value at one (sample, time) does not depend on the other
    samples, rows or times of the call.

    Parameters
    ----------
    kind : ndarray of int64, shape (n,)
        ``KIND_STATIONARY`` (constant), ``KIND_ELLIPTIC`` or ``KIND_SEPARATRIX``.
    amp : ndarray, shape (n, 3)
        Signed amplitudes, rad/s, of the components proportional to ``(cn, sn, dn)`` (elliptic),
        ``(sech, tanh, sech)`` (separatrix), or the constant components (stationary).
    cols : ndarray of int64, shape (n, 3)
        Output column of each of those three components (a permutation of 0, 1, 2).
    kc : ndarray, shape (n,)
        Complementary modulus ``k'`` (elliptic samples).
    K : ndarray, shape (n,)
        ``K(k)`` (elliptic samples), as :func:`torque_free_solve` computes it.
    nome : ndarray, shape (2, n)
        ``(h, q)`` of :func:`hyperbolic_nome` (elliptic samples with ``k' < KC_HYPERBOLIC``).
    phase0 : ndarray, shape (n,)
        Initial argument: ``u0 - K`` (elliptic) or ``u0`` (separatrix).
    nu : ndarray, shape (n,)
        Rate of the argument, rad/s: ``u = u0 + nu t``.
    times : ndarray, shape (R, T), C-contiguous
        Time grids, s; several samples may share a row.
    row : ndarray of int64, shape (n,)
        Sample ``i`` is evaluated at the times ``times[row[i], :]``.
    out : ndarray, shape (n, T, 3)
        Receives the angular velocity, rad/s.

    Returns
    -------
    int
        The number of samples with a non-finite value (0 unless something is wrong).
    """
    landen, hyperbolic, separatrix, stationary = regimes(kind, kc)
    non_finite = 0
    if landen.shape[0]:
        non_finite += in_parallel(omega_landen_share, landen.shape[0], landen, amp, cols, kc, K, phase0, nu, times,
                                  row, out)
    if hyperbolic.shape[0]:
        non_finite += in_parallel(omega_hyperbolic_share, hyperbolic.shape[0], hyperbolic, amp, cols, kc, K, nome,
                                  phase0, nu, times, row, out)
    if separatrix.shape[0]:
        non_finite += in_parallel(omega_separatrix_share, separatrix.shape[0], separatrix, amp, cols, phase0, nu,
                                  times, row, out)
    if stationary.shape[0]:  # the constant components, each in its column: _store's sum with the functions all 1
        values = np.zeros((stationary.shape[0], 3))
        values[np.arange(stationary.shape[0])[:, None], cols[stationary]] = amp[stationary]
        values += 0.0  # as the kernels' sums of the amplitude and two zero products (-0.0 -> 0.0)
        out[stationary] = values[:, None, :]
        non_finite += int(np.count_nonzero(~np.isfinite(values).all(axis=1)))
    return non_finite


#: The regimes of :func:`torque_free_omega`, each evaluated by a kernel of its own (:func:`regimes`' order).
REGIMES = ("landen", "hyperbolic", "separatrix")


_NO_SAMPLE = np.empty(0, dtype=np.int64)
_FIRST_SAMPLE = np.zeros(1, dtype=np.int64)


def regimes(kind, kc):
    """The samples of each regime: ``(landen, hyperbolic, separatrix, stationary)`` index arrays (int64), elliptic
    samples by ``k'`` (:data:`KC_HYPERBOLIC`), as :func:`_omega_row` chooses (a ``k'`` that is NaN: hyperbolic). All
    samples of one elliptic regime, the common case, cost two comparisons (a few microseconds a call)."""
    none = _NO_SAMPLE
    if kind.shape[0] == 1:  # one spin: read as scalars
        k = kind[0]
        regime = (0 if kc[0] >= KC_HYPERBOLIC else 1) if k == KIND_ELLIPTIC else 2 if k == KIND_SEPARATRIX else 3
        return tuple(_FIRST_SAMPLE if r == regime else none for r in range(4))
    elliptic = kind == KIND_ELLIPTIC
    landen = elliptic & (kc >= KC_HYPERBOLIC)
    if landen.all():
        return np.arange(kind.shape[0]), none, none, none
    hyperbolic = elliptic ^ landen
    if hyperbolic.all():
        return none, np.arange(kind.shape[0]), none, none
    separatrix = kind == KIND_SEPARATRIX
    return (np.flatnonzero(landen), np.flatnonzero(hyperbolic), np.flatnonzero(separatrix),
            np.flatnonzero(~(elliptic | separatrix)))


@jit
def omega_landen_share(index, amp, cols, kc, K, phase0, nu, times, row, out, start, stop):
    """The samples ``index[start:stop]`` of :func:`torque_free_omega` in the Landen regime (one share of
    :func:`tumble.kernels.threads.in_parallel`): the count of samples with a non-finite value."""
    rows = out.reshape(out.shape[0], 3 * out.shape[1])  # (n, T, 3) -> (n, 3T), a view
    non_finite = 0
    for n in range(start, stop):
        i = index[n]
        W = _column_weights(cols[i, 0], cols[i, 1], cols[i, 2], amp[i, 0], amp[i, 1], amp[i, 2])
        _landen_row(kc[i], K[i], phase0[i], nu[i], times[row[i]], rows[i], W)
        non_finite += _count_non_finite(rows[i])
    return non_finite


@jit
def omega_hyperbolic_share(index, amp, cols, kc, K, nome, phase0, nu, times, row, out, start, stop):
    """As :func:`omega_landen_share`, the samples in the hyperbolic regime (elliptic, ``k' < KC_HYPERBOLIC``)."""
    rows = out.reshape(out.shape[0], 3 * out.shape[1])
    non_finite = 0
    for n in range(start, stop):
        i = index[n]
        W = _column_weights(cols[i, 0], cols[i, 1], cols[i, 2], amp[i, 0], amp[i, 1], amp[i, 2])
        _hyperbolic_row(kc[i], K[i], nome[0, i], nome[1, i], phase0[i], nu[i], times[row[i]], rows[i], W)
        non_finite += _count_non_finite(rows[i])
    return non_finite


@jit
def omega_separatrix_share(index, amp, cols, phase0, nu, times, row, out, start, stop):
    """As :func:`omega_landen_share`, the samples on the separatrix."""
    rows = out.reshape(out.shape[0], 3 * out.shape[1])
    non_finite = 0
    for n in range(start, stop):
        i = index[n]
        W = _column_weights(cols[i, 0], cols[i, 1], cols[i, 2], amp[i, 0], amp[i, 1], amp[i, 2])
        _omega_row_separatrix(phase0[i], nu[i], times[row[i]], rows[i], W)
        non_finite += _count_non_finite(rows[i])
    return non_finite


@jit
def _sncndn_once(s, kc, K, h, q):
    """``sn, cn, dn`` of ``u = K + s`` for one argument, by the core of :func:`torque_free_omega` for ``k'``."""
    two_k = 2.0 * K
    inv_two_k = 1.0 / two_k
    if kc >= KC_HYPERBOLIC:
        kap, quarter_m, P = _landen_constants(kc)
        return _landen_at(s, K, two_k, inv_two_k, 1.0 / P, kc, kap, quarter_m, P)
    hk = h / math.sqrt((1.0 - kc) * (1.0 + kc))
    dcoef, ccoef, scoef = _series_constants(q)
    if 2.0 * K * h >= BETA_SHORT_SERIES:
        return _hyperbolic_short_at(s, K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef)
    return _hyperbolic_at(s, K, two_k, inv_two_k, kc, h, hk, q, dcoef, ccoef, scoef)


@jit(inline=True)
def _omega_at_sample(m0, m1, m2, w0, w1, w2, t):
    """One sample of :func:`torque_free_omega_at` by scalar code (every regime): ``(w(t) as three floats, tiny)``."""
    a, b, c, even, _, ss, I1, I2, I3, d, small = _invariants_row(m0, m1, m2, w0, w1, w2)
    w = (w0, w1, w2)
    kind, cols, amp, k_c, mi, nu, x, y, _, _ = _setup_row(I1, I2, I3, a, b, c, 1.0 if even else -1.0, ss,
                                                          w[a], w[b], w[c], d)
    fq = fm = fp = 1.0  # stationary
    if kind == KIND_SEPARATRIX:
        fq, fm = _sech_tanh(math.asinh(x) + nu * t)
        fp = fq
    elif kind == KIND_ELLIPTIC:
        K, h, q = complete_integrals(k_c)
        sn, cn, dn = _sncndn_once(nu * t - K, k_c, K, h, q)
        fq, fm, fp = _addition(x, y, k_c, mi, sn, cn, dn)
    vq, vm, vp = amp[0] * fq, amp[1] * fm, amp[2] * fp  # into the columns cols (a permutation), without a list
    return (vq if cols[0] == 0 else (vm if cols[1] == 0 else vp),
            vq if cols[0] == 1 else (vm if cols[1] == 1 else vp),
            vq if cols[0] == 2 else (vm if cols[1] == 2 else vp), small)


@jit(inline=True)
def _addition(x, y, k_c, mi, sn, cn, dn):
    """``cn, sn, dn`` of ``u0 + v`` from ``sn r0 = x``, ``cn r0 = y`` (``u0 = K + r0``) and ``sn, cn, dn`` of ``v``
    (:func:`torque_free_omega_at`); ``dn = 1`` exactly for ``m = 0``."""
    D = math.sqrt(y * y + (k_c * x) ** 2)
    inv = 1.0 / ((y * dn) ** 2 + (k_c * x) ** 2)
    fm = (y * D * (cn * dn) - k_c * k_c * (x * sn)) * inv
    fq = -k_c * (x * D * cn + y * (sn * dn)) * inv
    fp = k_c * (D * dn + mi * (x * y) * (sn * cn)) * inv
    return fq, fm, 1.0 if mi == 0.0 else fp


# Samples a chunk of torque_free_omega_at holds in its scratch arrays (each stage a loop over them, in SIMD lanes).
_CHUNK = 256
# Rows of the chunk's scratch array.
_AQ, _AM, _AP, _KC, _M, _NU, _X, _Y, _NEG, _SPECIAL, _K, _Q, _SN, _CN, _DN, _A, _B, _WA, _WB, _WC = range(20)


def torque_free_omega_at(moments, w, t, out):
    """Angular velocity of the free rigid body at one time ``t``, straight from the initial spins: the invariants,
    the set-up and one evaluation of :func:`torque_free_omega`, fused, with samples in SIMD lanes and without the
    initial argument.

    Jacobi's addition theorem (DLMF 22.8.1-3) moves the motion from ``u0 = K + r0`` to ``u0 + nu t``, with
    ``sn, cn, dn`` of ``u0`` taken from the spin itself (``sn u0 = cd r0``, ``cn u0 = -k' sd r0``,
    ``dn u0 = k' nd r0``, with ``sn r0 = x``, ``cn r0 = y`` of :func:`_setup_row` and ``D = dn r0``); only
    ``sn, cn, dn`` of ``nu t`` are evaluated. Multiplied through by ``D²``, every denominator is a sum of
    squares, ``y² dn² + k'² x²``, and ``k'`` factors out of ``cn, dn`` (kept relative near the unstable axis)::

        sn = (y D cn dn - k'² x sn) / den,   cn = -k' (x D cn + y sn dn) / den,
        dn =  k' (D dn + k² x y sn cn) / den          (sn, cn, dn of nu t)

    So Carlson's ``R_F`` (the initial argument) is never computed. Samples go in chunks of ``_CHUNK``; in each,
    every stage (set-up, the two AGMs with a common iteration count, the nome, ``sn, cn, dn``, the addition) is a
    branch-free loop over the chunk's samples that LLVM vectorises: square roots and divisions, latency-bound one
    sample at a time, fill the SIMD lanes instead. The rare samples that need other code (steady spins, the
    separatrix, spins whose scales or ratios leave the safe range) are redone one by one
    (:func:`_omega_at_sample`). The error is a few ulps of ``|w|``; near the unstable axis the small components
    keep their relative accuracy (tested against mpmath).

    Parameters
    ----------
    moments : ndarray, shape (3,)
        Principal moments (kg m², validated) of the one body.
    w : ndarray, shape (n, 3)
        Initial body-frame spins, rad/s.
    t : float
        The time, s.
    out : ndarray, shape (n, 3)
        Receives the angular velocity at ``t``, rad/s.

    Returns
    -------
    (int, int)
        The samples too close to a principal axis for the invariants (``TINY_TRANSVERSE``: the caller must take
        the general path for them) and the samples with a non-finite value.
    """
    return in_parallel(torque_free_omega_at_share, w.shape[0], moments, w, t, out, granule=_CHUNK)


@jit
def torque_free_omega_at_share(moments, w, t, out, start, stop):
    """The samples ``start:stop`` of :func:`torque_free_omega_at` (one share of
    :func:`tumble.kernels.threads.in_parallel`): ``(tiny, non_finite)`` counts."""
    tiny = 0
    non_finite = 0
    for lo in range(start, stop, _CHUNK):
        tiny_chunk, non_finite_chunk = _omega_at_chunk(moments, w, t, out, lo, _min(_CHUNK, stop - lo))
        tiny += tiny_chunk
        non_finite += non_finite_chunk
    return tiny, non_finite


@jit
def _omega_at_chunk(moments, w, t, out, lo, m):
    # size: the stages of a chunk are loops over its samples (SIMD lanes), each written out in one place so that
    # LLVM vectorises it; the constants of the one body are hoisted
    """Samples ``lo .. lo + m`` of :func:`torque_free_omega_at`: ``(tiny, non-finite)`` counts."""
    a, b, c, even, _, _, I1, I2, I3, _, _ = _invariants_row(moments[0], moments[1], moments[2], 1.0, 1.0, 1.0)
    parity = 1.0 if even else -1.0
    d32h, d32l = _two_sum(I3, -I2)
    d21h, d21l = _two_sum(I2, -I1)
    dpq = I3 - I1
    d32 = I3 - I2
    d21 = I2 - I1
    tiny = 0
    non_finite = 0
    z = np.empty((20, m))
    n_hyperbolic = 0
    n_landen = 0
    for j in range(m):  # the spins' components in sorted order, as rows
        z[_WA, j], z[_WB, j], z[_WC, j] = w[lo + j, a], w[lo + j, b], w[lo + j, c]
    for j in range(m):  # set-up (_invariants_row, _setup_row), branch-free
        wa, wb, wc = z[_WA, j], z[_WB, j], z[_WC, j]
        big = _max(abs(wa), abs(wb), abs(wc))
        ss = 2.0 * _bits_float64(_float64_bits(big) & _EXPONENT_BITS)  # math.frexp's power of two for normal big
        special = (ss == 0.0) | (ss == math.inf)
        ss = 1.0 if special else ss
        w1, w2, w3 = wa / ss, wb / ss, wc / ss
        ah, al = _dd_term(I3, d32h, d32l, w3)
        bh, bl = _dd_term(I1, d21h, d21l, w1)
        s_, e_ = _two_sum(ah, -bh)
        dh, dl = _two_sum(s_, e_ + (al - bl))
        d = dh + dl
        neg = d < 0.0
        Ip = I1 if neg else I3
        Iq = I3 if neg else I1
        wp = w1 if neg else w3
        wq = w3 if neg else w1
        dp2 = d21 if neg else d32
        dq2 = d32 if neg else d21
        X = I2 * dp2 * w2 * w2 + Iq * dpq * wq * wq
        Y = I2 * dq2 * w2 * w2 + Ip * dpq * wp * wp
        a_q = math.sqrt(X / (Iq * dpq))
        a_mid = math.sqrt(X / (I2 * dp2))
        a_p = math.sqrt(Y / (Ip * dpq))
        nu_abs = math.sqrt(dp2 * Y / (I1 * I2 * I3))
        s_p = -1.0 if wp < 0.0 else 1.0
        mi = dq2 * X / (dp2 * Y)
        k_c = math.sqrt(dpq / (dp2 * Y)) * math.sqrt(abs(d))
        k_c = 1.0 if mi == 0.0 else k_c
        sigma = -1.0 if w2 < 0.0 else 1.0
        ratio = a_p / abs(wp)
        sn_r = -sigma * (wq / a_q) * ratio
        cn_r = sigma * (w2 / a_mid) * ratio * k_c
        norm2 = sn_r * sn_r + cn_r * cn_r
        inv_norm = 1.0 / math.sqrt(norm2)
        # zeros of the spin (steady spins, symmetric tops' axes), the separatrix, and ratios whose squares
        # would leave the safe range (math.hypot's work) go to the scalar path
        special = special | (wa == 0.0) | (wb == 0.0) | (wc == 0.0) | (d == 0.0) | (I1 == I2) | (I2 == I3)
        special = special | ~(norm2 > 1e-300) | ~(norm2 < 1e300) | ~(big < TINY_TRANSVERSE_SAFE * _min(
            abs(wa), abs(wb), abs(wc)))
        z[_AQ, j] = sigma * a_q * ss
        z[_AM, j] = sigma * a_mid * ss
        z[_AP, j] = wp * ss if mi == 0.0 else s_p * a_p * ss
        z[_KC, j] = k_c
        z[_M, j] = mi
        z[_NU, j] = s_p * parity * nu_abs * ss
        z[_X, j] = sn_r * inv_norm
        z[_Y, j] = cn_r * inv_norm
        z[_NEG, j] = 1.0 if neg else 0.0
        z[_SPECIAL, j] = 1.0 if special else 0.0
        z[_A, j] = 1.0
        z[_B, j] = 0.5 if special else k_c  # a harmless modulus for the lanes redone below
        hyperbolic = (k_c < KC_HYPERBOLIC) & ~special
        n_hyperbolic += 1 if hyperbolic else 0
        n_landen += 0 if hyperbolic or special else 1
    _agm_lanes(z[_A], z[_B])  # K = pi / (2 AGM(1, k'))
    for j in range(m):
        z[_K, j] = 0.5 * math.pi / z[_A, j]
        k_c = z[_KC, j]
        k_c = 0.25 if k_c >= KC_HYPERBOLIC or z[_SPECIAL, j] != 0.0 else k_c
        z[_A, j] = 1.0
        z[_B, j] = math.sqrt((1.0 - k_c) * (1.0 + k_c))
    if n_hyperbolic:
        _agm_lanes(z[_A], z[_B])  # h = AGM(1, k) = pi / (2 K')
        for j in range(m):
            h = z[_A, j]
            beta = 2.0 * z[_K, j] * h
            q, _ = _exp_expm1(-beta)
            z[_Q, j] = q if beta < _BETA_NEGLIGIBLE else 0.0
            k_c = z[_KC, j]
            K = z[_K, j]
            dcoef, ccoef, scoef = _series_constants_inline(z[_Q, j])
            hk = h / math.sqrt((1.0 - k_c) * (1.0 + k_c))
            sn, cn, dn = _hyperbolic_at(z[_NU, j] * t - K, K, 2.0 * K, 0.5 / K, k_c, h, hk, z[_Q, j], dcoef, ccoef,
                                        scoef)
            z[_SN, j], z[_CN, j], z[_DN, j] = sn, cn, dn
    if n_landen:
        for j in range(m):
            landen = z[_KC, j] >= KC_HYPERBOLIC
            k_c = z[_KC, j] if landen else 0.75  # a harmless modulus for the other lanes (their values are kept)
            K = z[_K, j]
            kap, quarter_m, P = _landen_constants_inline(k_c)
            sn, cn, dn = _landen_at(z[_NU, j] * t - K, K, 2.0 * K, 0.5 / K, 1.0 / P, k_c, kap, quarter_m, P)
            z[_SN, j] = sn if landen else z[_SN, j]
            z[_CN, j] = cn if landen else z[_CN, j]
            z[_DN, j] = dn if landen else z[_DN, j]
    for j in range(m):
        fq, fm, fp = _addition(z[_X, j], z[_Y, j], z[_KC, j], z[_M, j], z[_SN, j], z[_CN, j], z[_DN, j])
        vq = z[_AQ, j] * fq
        vp = z[_AP, j] * fp
        neg = z[_NEG, j] != 0.0
        z[_WA, j] = vp if neg else vq
        z[_WB, j] = z[_AM, j] * fm
        z[_WC, j] = vq if neg else vp
    for j in range(m):
        out[lo + j, a], out[lo + j, b], out[lo + j, c] = z[_WA, j], z[_WB, j], z[_WC, j]
    for j in range(m):
        if z[_SPECIAL, j] != 0.0:
            i = lo + j
            out[i, 0], out[i, 1], out[i, 2], small = _omega_at_sample(moments[0], moments[1], moments[2],
                                                                      w[i, 0], w[i, 1], w[i, 2], t)
            tiny += 1 if small else 0
    for j in range(m):
        i = lo + j
        non_finite += 0 if abs(out[i, 0]) + abs(out[i, 1]) + abs(out[i, 2]) < math.inf else 1
    return tiny, non_finite


# The lanes' copies of the per-modulus constants (inlined, so that the loops over lanes vectorise).
_series_constants_inline = jit(inline=True)(_series_constants)
_landen_constants_inline = jit(inline=True)(_landen_constants)


@jit(inline=True)
def _agm_lanes(a, b):
    """``a <- AGM(a, b)`` lane by lane: :func:`agm`'s steps and test, a lane held once it meets the test, so that
    its bits are :func:`agm`'s whatever the other lanes of the chunk (the loop runs until the slowest one is done)."""
    for _ in range(_AGM_MAXITER):
        unconverged = 0
        for j in range(a.shape[0]):
            go = abs(a[j] - b[j]) > 1e-8 * a[j]
            unconverged += 1 if go else 0
            mean, root = 0.5 * (a[j] + b[j]), math.sqrt(a[j] * b[j])
            a[j] = mean if go else a[j]
            b[j] = root if go else b[j]
        if unconverged == 0:
            break
    for j in range(a.shape[0]):
        a[j] = 0.5 * (a[j] + b[j])
