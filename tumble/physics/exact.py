"""The exact torque-free motion of a rigid body in the body frame (Landau & Lifshitz, Mechanics §37).

With the moments sorted, ``I1 <= I2 <= I3`` (``I2`` the *intermediate* moment), kinetic energy
``E = ½ Σ Ii wi²`` and ``L² = Σ Ii² wi²``, the body-frame angular velocity is a Jacobi-elliptic motion in
the argument ``u = u0 + nu t``:

* ``L² > 2 E I2`` (spin nearer the axis of the *largest* moment)::

      w1 = A1 cn u,   w2 = A2 sn u,   w3 = ±A3 dn u,
      A1² = (2E I3 - L²) / (I1 (I3 - I1)),  A2² = (2E I3 - L²) / (I2 (I3 - I2)),
      A3² = (L² - 2E I1) / (I3 (I3 - I1)),
      m = k² = (I2 - I1)(2E I3 - L²) / ((I3 - I2)(L² - 2E I1)),
      |nu|² = (I3 - I2)(L² - 2E I1) / (I1 I2 I3);

* ``L² < 2 E I2``: the same with the roles of axes 1 and 3 exchanged (``dn`` on the smallest axis);
* ``L² = 2 E I2``, the separatrix: ``m = 1``, ``sn, cn, dn -> tanh, sech, sech``; the motion takes an
  infinite time to leave (and to reach) the intermediate axis;
* the symmetric top (two equal moments) is ``m = 0``: the transverse components rotate at
  ``Omega = w3 (I3 - I1) / I1`` about the symmetry axis;
* stationary spins (about a principal axis, any spin of a sphere, zero spin) stay constant.

Accuracy near the separatrix
----------------------------
The elliptic parameter approaches 1 as the spin approaches the separatrix, and everything that matters
there is a *small difference*: ``k'² = 1 - m``, ``L² - 2E I2``, and the components ``cn u, dn u ~ k'`` of a
spin near the intermediate axis. None of them is formed by subtraction here:

* ``L² - 2E I2 = I3 (I3 - I2) w3² - I1 (I2 - I1) w1²`` is evaluated in double-double arithmetic (error-free
  products by fused multiply-add and Knuth's two-sum, :func:`tumble.kernels.closed_form.elliptic.torque_free_solve`), so it is correctly rounded even on heavy cancellation;
  ``2E I3 - L²`` and ``L² - 2E I1`` are sums of terms of one sign;
* the complementary modulus comes directly from those, ``k'² = (I3 - I1)(L² - 2E I2) / ((I3 - I2)(L² -
  2E I1))``, never as ``sqrt(1 - m)``;
* the argument is carried as its offset from the quarter period ``K`` (where the spin is closest to the
  intermediate axis), and the initial offset comes from the initial components through Carlson's
  ``R_F``: ``u - K = sn·R_F(cn², dn², 1)`` at the reduced argument (DLMF 19.25.5), with
  ``sn, cn, dn`` there read off the components *relative to themselves*;
* ``sn, cn, dn`` are evaluated by :mod:`tumble.kernels.closed_form.elliptic`, which keeps relative accuracy up to
  ``m = 1`` (quarter-period reduction, hyperbolic series for small ``k'``, Landen/AGM otherwise).

Measured against mpmath at 50 digits (``tests/test_exact.py``; 8 random bodies and spins per row, both
regimes, 300 times over ten flips of the intermediate-axis component), for spins ``eps`` away from the
intermediate axis:

======  ==============  =========================  ==============
eps     ``|dw|/|w|``    per component (see below)  at t = 0
======  ==============  =========================  ==============
1       9.6e-15         1.0e-13                    8e-16
1e-3    5.8e-14         4.6e-13                    5e-16
1e-6    9.4e-14         8.0e-13                    8e-16
1e-8    1.2e-13         5.7e-13                    5e-16
1e-10   7.0e-14         7.3e-13                    4e-16
1e-12   1.9e-13         1.9e-12                    4e-16
======  ==============  =========================  ==============

"Per component" is ``|dw_i| / max(|w_i|, 0.1 |dw_i/du|)``: relative to the component itself, the tiny
transverse ones included, except within 0.1 (in the elliptic argument ``u``) of a zero crossing, where
the error is the argument's own absolute error times the slope. That argument error, a few ulp of
``|u|`` (``|u|`` reaches ``20 K ~ 600`` after ten flips at ``eps = 1e-12``), comes from ``K`` and
``nu`` rounded to doubles and is the floor of any double-precision evaluation.

Sorting the moments is a permutation of the axes; an odd permutation is a reflection, which reverses the
sense of ``w x (I w)``, so ``nu`` changes sign with the parity of the sorting permutation.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from ..kernels import device_closed_form
from ..kernels import elliptic as _ell
from ..kernels import elliptic_attitude as _ell_attitude
from ..kernels import fits as _fits
from ..kernels import side_by_side as _side_by_side
from .bodies import finite_array, one_body, spin_vectors

__all__ = ["EllipticParameters", "attitude", "attitude_on_device", "attitude_rows", "omega", "omega_on_device",
           "omega_rows_on_device", "period", "parameters", "first_flip_time", "flip_spacing", "phase_fit_rows_on_device",
           "rotation_per_period"]

REGIME_LARGEST = 1  # L² > 2E I_mid: w along the largest-moment axis never changes sign (dn there)
REGIME_SEPARATRIX = 0  # L² = 2E I_mid
REGIME_SMALLEST = -1  # L² < 2E I_mid: w along the smallest-moment axis never changes sign


class EllipticParameters(NamedTuple):
    """Parameters of the exact solution; every field is an array shaped like ``w0[..., 0]`` unless noted.

    Attributes
    ----------
    m : ndarray
        Elliptic parameter ``k²`` (dimensionless; 1 on the separatrix, 0 for a symmetric top).
    kc : ndarray
        Complementary modulus ``k' = sqrt(1 - m)``, computed without cancellation.
    K : ndarray
        Quarter period ``K(m)`` (inf on the separatrix, pi/2 for a stationary spin).
    nu : ndarray
        Rate of the elliptic argument, rad/s: ``u = u0 + nu t``. Its sign carries the sense of the motion.
        0 for a stationary spin.
    u0 : ndarray
        Initial argument, in ``(-2K, 2K]`` (real line on the separatrix; 0 for a stationary spin), so that
        ``w_mid = A_mid sn(u)``, ``w_cn = A_cn cn(u)``, ``w_dn = ± A_dn dn(u)`` (on the separatrix
        ``w_mid = A_mid tanh u``, ``w_cn = ± A_cn sech u``).
    regime : ndarray of int8
        Sign of ``L² - 2 E I_mid``: ``+1`` (the largest-moment component keeps its sign), ``-1`` (the
        smallest-moment component keeps its sign), ``0`` (the separatrix; also a steady spin about the
        intermediate axis, any spin of a sphere, zero spin). See ``stationary`` for steady spins.
    stationary : ndarray of bool
        True where the spin is a steady rotation (along a principal axis, about any axis of a sphere,
        in the equal-moment plane of a symmetric top, or zero).
    energy : ndarray
        Kinetic energy ``E = ½ Σ Ii wi²``, J.
    L2 : ndarray
        ``|L|² = Σ (Ii wi)²``, (kg m² rad/s)².
    delta : ndarray
        ``L² - 2 E I_mid``, (kg m² rad/s)², correctly rounded; its sign gives the regime.
    amplitude : ndarray, shape (..., 3)
        Largest ``|w_i|`` over the motion, rad/s, in the caller's axis order.
    mid_axis : int
        0-based index (caller's order) of the intermediate-moment axis; ties broken by axis order.
    dn_axis : ndarray of int
        0-based index (caller's order) of the axis whose component is ``∝ dn`` (never changes sign);
        the largest-moment axis on the separatrix and for stationary spins.

    See Also
    --------
    tumble.exact.parameters : What returns it.

    Examples
    --------
    >>> import tumble
    >>> p = tumble.exact.parameters((1.0, 2.0, 3.0), [0.01, 1.0, 0.0])
    >>> isinstance(p, tumble.exact.EllipticParameters), round(float(p.K), 4), round(float(p.energy), 6)
    (True, 5.9916, 1.00005)
    """

    m: np.ndarray
    kc: np.ndarray
    K: np.ndarray
    nu: np.ndarray
    u0: np.ndarray
    regime: np.ndarray
    stationary: np.ndarray
    energy: np.ndarray
    L2: np.ndarray
    delta: np.ndarray
    amplitude: np.ndarray
    mid_axis: int
    dn_axis: np.ndarray


# ---------------------------------------------------------------------------------------------------
class _Solution(NamedTuple):
    """The closed form's per-sample set-up (flattened samples). The kernels read the first fields; the physical
    invariants are derived from the scaled ones only when asked (the properties), so an evaluation pays for
    none of them."""

    shape: tuple
    kind: np.ndarray  # (n,) int64
    amp: np.ndarray  # (n, 3) signed amplitudes of (cn, sn, dn) / (sech, tanh, sech) / constant parts
    cols: np.ndarray  # (n, 3) int64 output columns, caller's order
    kc: np.ndarray
    m: np.ndarray
    K: np.ndarray
    nome: np.ndarray  # (2, n): h = pi/(2K') and q = exp(-pi K/K') where k' < KC_HYPERBOLIC, else 0
    phase0: np.ndarray  # u0 - K (elliptic), u0 (separatrix)
    nu: np.ndarray
    mid_axis: object  # int (one body) or (n,) int64 (one body per sample)
    scaled: np.ndarray  # (5, n): 2E, |L|², L² - 2E I2 of the scaled body and spin; moment and spin scales

    @property
    def regime(self):
        """(n,) int8: sign of ``L² - 2E I_mid`` (``REGIME_*``)."""
        return np.sign(self.scaled[2]).astype(np.int8)

    @property
    def stationary(self):
        return self.kind == _ell.KIND_STATIONARY

    def _unscaled(self, value, moment_power):
        moment_scale, spin_scale = self.scaled[3], self.scaled[4]
        with np.errstate(over="ignore", under="ignore"):  # invariants in SI units may overflow; spins do not
            for _ in range(moment_power):
                value = value * moment_scale
            return value * spin_scale * spin_scale

    @property
    def energy(self):
        """(n,) kinetic energy, J."""
        return self._unscaled(0.5 * self.scaled[0], 1)

    @property
    def L2(self):
        """(n,) ``|L|²``, (kg m² rad/s)²."""
        return self._unscaled(self.scaled[1], 2)

    @property
    def delta(self):
        """(n,) ``L² - 2E I_mid``."""
        return self._unscaled(self.scaled[2], 2)


def _check_t(t):
    tt = finite_array(t, "t")
    if tt.ndim > 1:
        raise ValueError(f"t must be a scalar or have shape (T,) (times, s), got shape {tt.shape}")
    if tt.size == 0:
        raise ValueError("t holds no times (shape (0,))")
    return tt


def _solve(body, w0):
    """Everything the closed form needs, per sample (flattened), for one body."""
    moments = one_body(body)
    w = spin_vectors(w0)
    shape = w.shape[:-1]
    w = np.ascontiguousarray(w.reshape(-1, 3))
    rows = np.empty(w.shape)
    rows[:] = moments
    i1, i2, i3 = moments.tolist()
    mid_axis = sorted(range(3), key=(i1, i2, i3).__getitem__)[1]  # as a stable argsort
    return _setup(rows, w, shape, mid_axis)


def solve_rows(moments, w):
    """The closed form's per-sample set-up for spins ``w`` (n, 3) of bodies ``moments`` (n, 3), one body per row
    (validated by the caller): what :func:`omega_rows` evaluates, computed once per sample.

    Returns a private ``_Solution`` (fields per sample; ``shape = (n,)``, ``mid_axis`` per sample).
    """
    # C-ordered and writeable, always: a read-only array (a broadcast body of one row is one, and contiguous) would
    # compile another variant of the set-up kernel, 4.5 s on the first run
    moments = np.require(moments, dtype=float, requirements=("C", "W"))
    w = np.require(w, dtype=float, requirements=("C", "W"))
    return _setup(moments, w, (w.shape[0],), None)


def _setup(moments, w, shape, mid_axis):
    n = w.shape[0]
    # Euler's equations are homogeneous: w(t) -> c w(c t) and I -> c I map solutions to solutions. The kernel
    # works with moments and spins divided by powers of two (exact), so that no invariant under- or overflows,
    # and forms L² - 2E I2 in double-double arithmetic.
    I_sorted, perm = np.empty((n, 3)), np.empty((n, 3), dtype=np.int64)
    parity = np.empty(n)
    scaled = np.empty((5, n))  # 2E, L², delta (scaled); moment scale, spin scale
    kind = np.empty(n, dtype=np.int64)
    amp = np.empty((n, 3))
    cols = np.empty((n, 3), dtype=np.int64)
    params = np.empty((5, n))  # k', m, K, initial argument, nu
    nome = np.empty((2, n))
    given, lifted = w, None
    if _ell.torque_free_solve(moments, w, I_sorted, perm, parity, scaled, kind, amp, cols, params, nome):
        w, lifted = _lift_tiny(w)  # spins within 2^-500 of an axis (rare)
        _ell.torque_free_solve(moments, w, I_sorted, perm, parity, scaled, kind, amp, cols, params, nome)
    kc, m, K, phase0, nu = params
    if lifted is not None:
        _lower_tiny(lifted, I_sorted, perm, given, kind, amp, cols, kc, K, nome, phase0)
    return _Solution(shape=shape, kind=kind, amp=amp, cols=cols, kc=kc, m=m, K=K, nome=nome, phase0=phase0, nu=nu,
                     mid_axis=perm[:, 1] if mid_axis is None else mid_axis, scaled=scaled)


# Where _lift_tiny moves a spin's two small components: their squares are then far from underflow, and the
# terms of relative order (lifted component)^2 that the rescaling below neglects far below rounding.
_LIFT = 2.0**-200


def _lift_tiny(w):
    """Spins within ``TINY_TRANSVERSE`` of a principal axis, their two small components multiplied by one power
    of two (``factor``) so that the invariants of the lifted spin keep their accuracy (:func:`_lower_tiny`
    undoes it on the set-up). Returns the lifted spins and ``(rows, dominant axis, factor)``."""
    a = np.abs(w)
    dominant = a.argmax(axis=1)
    second = np.sort(a, axis=1)[:, 1]
    rows = np.flatnonzero((second > 0) & (second < _ell.TINY_TRANSVERSE * a.max(axis=1)))
    factor = np.ldexp(1.0, np.frexp(_LIFT * a.max(axis=1)[rows] / second[rows])[1])
    lifted = w.copy()
    transverse = np.arange(3)[None, :] != dominant[rows, None]
    lifted[rows] = np.where(transverse, w[rows] * factor[:, None], w[rows])
    return lifted, (rows, dominant[rows], factor)


def _lower_tiny(lifted, I_sorted, perm, w, kind, amp, cols, kc, K, nome, phase0):
    # size: the closed form's per-sample set-up arrays, corrected in place for the rare spins it lifted
    """The closed form of spins within ``TINY_TRANSVERSE`` of an axis from that of the lifted spins.

    Such a spin's two small components ``ε`` are so small that their squares underflow in ``L² - 2E I2``. To
    relative order ``ε²`` (below rounding) they follow the linearised motion about the axis ``a``, linear in
    them, so the lifted spin (components ``f ε``) gives the true one by scaling:

    * about a stable or degenerate axis the small components stay small: the amplitudes of their output
      columns are divided by ``f`` (a steady spin keeps its own components);
    * about the intermediate axis (``I1 < I2 < I3`` strictly) they grow and the spin flips: the orbit of the
      lifted spin passes ``f`` times farther from the unstable axis. Everything but the modulus is the same to
      ``O(f ε)²`` (amplitudes, rate, the initial argument, whose ``sn r0, cn r0`` are ratios of the small
      components), while ``k'`` is proportional to them: ``k' -> k'/f``, ``K`` recomputed (``K ≈ ln(4/k')``,
      so the time spent near the unstable axis grows by ``ln(f)/ν``); on the separatrix the argument
      ``asinh(c/ε) ≈ ln(2c/ε)`` moves by ``ln f``.
    """
    rows, dominant, factor = lifted
    strict = (I_sorted[rows, 0] < I_sorted[rows, 1]) & (I_sorted[rows, 1] < I_sorted[rows, 2])
    unstable = strict & (perm[rows, 1] == dominant) & (kind[rows] != _ell.KIND_STATIONARY)
    for j, i in enumerate(rows):
        if kind[i] == _ell.KIND_STATIONARY:
            amp[i] = w[i, cols[i]]
        elif not unstable[j]:
            amp[i] = np.where(cols[i] != dominant[j], amp[i] / factor[j], amp[i])
        elif kind[i] == _ell.KIND_SEPARATRIX:
            phase0[i] += math.copysign(math.log(factor[j]), phase0[i])
        else:
            kc[i] /= factor[j]
            K[i], nome[0, i], nome[1, i] = _ell.complete_integrals(kc[i])


def omega_rows(sol, times, row):
    """Angular velocity (n, T, 3), rad/s, of the samples of :func:`solve_rows`, sample ``i`` at ``times[row[i]]``
    (``times`` of shape (R, T): one time grid per scene of a batch). The bits of a sample do not depend on the
    batch it is evaluated in."""
    times = np.ascontiguousarray(times, dtype=float)
    out = np.empty((sol.kind.shape[0], times.shape[1], 3))
    non_finite = _ell.torque_free_omega(sol.kind, sol.amp, sol.cols, sol.kc, sol.K, sol.nome, sol.phase0, sol.nu, times,
                                        np.ascontiguousarray(row, dtype=np.int64), out)
    if non_finite:  # the one check at the layer boundary (counted by the kernel)
        raise FloatingPointError("exact.omega produced non-finite values; please report this spin")
    return out


def omega_at(moments, w, t):
    """Angular velocity (n, 3), rad/s, at one time ``t`` (s) of spins ``w`` (n, 3) of one body ``moments`` (3,), all
    validated by the caller: the lean path of :func:`omega` for a single time.

    One fused kernel (:func:`tumble.kernels.closed_form.elliptic.torque_free_omega_at`: no initial argument, Jacobi's
    addition theorem instead); agrees with :func:`omega` to a few ulps of ``|w|``. A call with a spin within
    ``TINY_TRANSVERSE`` of an axis takes the time grid's path (:func:`omega_apart`), for all its spins.
    """
    moments = np.ascontiguousarray(moments, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    out = np.empty(w.shape)
    tiny, non_finite = _ell.torque_free_omega_at(moments, w, float(t), out)
    if tiny:
        return omega_apart(moments, w, np.array([float(t)]))[:, 0]
    if non_finite:
        raise FloatingPointError("exact.omega produced non-finite values; please report this spin")
    return out


#: The regimes of the evaluation (:data:`tumble.kernels.closed_form.elliptic.REGIMES`) a scene's samples meet, by
#: linear theory's kind: spins perturbed about the intermediate axis lie near the separatrix (the hyperbolic core),
#: those about the largest or the smallest axis far from it (Landen's). A guess: a regime it leaves out compiles in the
#: run, later, and changes no result.
_KIND_REGIMES = {"exponential": ("hyperbolic",), "periodic": ("landen",)}


@functools.cache
def compile_kernels_side_by_side(kind, attitude=False, regimes=None):
    """Compile the closed form's kernels, and those of the estimators that scenes of ``kind`` (``"exponential"``,
    ``"periodic"`` or ``"neutral"``; ``"grid"``: the closed form on a time grid, as :func:`omega` and ``tumble check``
    run it) run on its samples, side by side where numba's cache lacks them
    (:func:`tumble.kernels.side_by_side.compile_side_by_side`: on two cores :func:`omega`'s first call on a grid after
    an install takes about half as long); the evaluation's rows of ``regimes`` (a call's own spins:
    :func:`regimes_to_compile`; None: those :data:`_KIND_REGIMES` expects of ``kind``, every one for the others); with
    ``attitude``, the attitude's kernels too (:func:`attitude`, a study drawing one spin's attitude, as
    ``dzhanibekov_flip``); checked once per process and arguments."""
    if regimes is None:
        regimes = _KIND_REGIMES.get(kind, _ell.REGIMES)
    rows = tuple(_side_by_side.ROWS[r] for r in regimes)
    return tuple(_side_by_side.compile_side_by_side(_side_by_side.CLOSED_FORM[kind] + rows
                                                    + (_side_by_side.ATTITUDE if attitude else ())))


def regimes_to_compile(moments, w):
    """:func:`regimes_met` while the set-up has not run in this process (a first call: what to compile ahead), else
    none (its 50 us would be paid by every call; a regime met later compiles in its run)."""
    return () if _ell.torque_free_solve_share.overloads else regimes_met(moments, w)


def regimes_met(moments, w):
    """The regimes of the evaluation (:data:`tumble.kernels.closed_form.elliptic.REGIMES`) that spins ``w`` (n, 3) of
    the body ``moments`` (3,) meet, estimated in plain floating point before the set-up runs (what
    :func:`compile_kernels_side_by_side` compiles ahead): ``k'^2`` of :func:`~tumble.kernels.closed_form.elliptic.
    torque_free_solve`'s set-up from ``L^2 - 2E I2`` without its double-double care, so both sides of a boundary
    where the estimate is near one (a symmetric body, or a spin on an axis, meets every regime)."""
    order = np.argsort(moments, kind="stable")
    I = np.asarray(moments, dtype=float)[order]
    ws = np.asarray(w, dtype=float).reshape(-1, 3)[:, order]
    e2 = (I * ws**2).sum(axis=1)
    L2 = ((I * ws) ** 2).sum(axis=1)
    d = L2 - e2 * I[1]
    with np.errstate(all="ignore"):
        Ip, Iq = np.where(d >= 0.0, I[2], I[0]), np.where(d >= 0.0, I[0], I[2])
        kc2 = np.abs(Ip - Iq) * np.abs(d) / (np.abs(Ip - I[1]) * np.abs(L2 - e2 * Iq))
    unsure = ~np.isfinite(kc2)
    near = _ell.KC_HYPERBOLIC**2
    met = (("landen", bool(np.any(unsure | (kc2 >= 0.8 * near)))),
           ("hyperbolic", bool(np.any(unsure | (kc2 < 1.25 * near)))),
           ("separatrix", bool(np.any(unsure | (np.abs(d) <= 1e-9 * L2)))))
    return tuple(name for name, meets in met if meets)


def flip_spacings(sol):
    """Flip spacing ``2K/|nu|`` (s; inf where none) of each sample of a :func:`solve_rows` solution."""
    with np.errstate(divide="ignore"):
        return np.where(sol.kind == _ell.KIND_ELLIPTIC, 2.0 * sol.K / np.abs(sol.nu), np.inf)


def first_flips(sol):
    """First flip time (s; inf where none) of each sample of a :func:`solve_rows` solution."""
    elliptic = sol.kind == _ell.KIND_ELLIPTIC
    separatrix = sol.kind == _ell.KIND_SEPARATRIX
    out = np.full(sol.kind.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        sgn = np.sign(sol.nu)
        K = sol.K
        gap = K - sgn * sol.phase0  # phase still to go to the next zero of sn, in [0, 2K]
        gap = np.where(gap > 0, gap, gap + 2.0 * K)
        out = np.where(elliptic, gap / np.abs(sol.nu), out)
        tsep = -sol.phase0 / sol.nu
        out = np.where(separatrix & (tsep > 0), tsep, out)
    return out


def omega(body, w0, t):
    r"""Body-frame angular velocity of the torque-free rigid body, in closed form.

    Landau & Lifshitz, *Mechanics*, §37 (Jacobi elliptic functions); see the module docstring for the
    formulas, the regimes and how accuracy is kept near the separatrix.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body: a :class:`tumble.Body` or its principal moments, kg m², in any order.
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s, components along the body's axes in the order of
        ``body``'s moments.
    t : array_like, shape (T,) or scalar
        Times, s (any sign, any order).

    Returns
    -------
    ndarray, shape (..., T, 3)
        Angular velocity at each time, rad/s; shape ``(..., 3)`` when ``t`` is a scalar.

    Raises
    ------
    ValueError
        If the moments are invalid, ``w0`` is not ``(..., 3)`` or not finite, or ``t`` is not a finite
        scalar or 1-d array.

    See Also
    --------
    tumble.exact.period : The period of this motion.
    tumble.exact.attitude : The orientation in space, in closed form.
    tumble.integrate : ``method="exact"``: this solution as a Dataset.
    tumble.check : Another simulator's trajectory against this solution.

    Notes
    -----
    With the moments sorted, :math:`I_1 \le I_2 \le I_3`, the kinetic energy :math:`E` and
    :math:`L^2 = \sum_i I_i^2 \omega_i^2`, a spin with :math:`L^2 > 2 E I_2` (nearer the axis of the largest
    moment) moves as [1]_

    .. math::

        \omega_1 = A_1 \operatorname{cn} u, \qquad \omega_2 = A_2 \operatorname{sn} u, \qquad
        \omega_3 = \pm A_3 \operatorname{dn} u, \qquad u = u_0 + \nu t,

    .. math::

        m = k^2 = \frac{(I_2 - I_1)(2 E I_3 - L^2)}{(I_3 - I_2)(L^2 - 2 E I_1)}, \qquad
        \nu^2 = \frac{(I_3 - I_2)(L^2 - 2 E I_1)}{I_1 I_2 I_3},

    with :math:`A_1^2 = (2 E I_3 - L^2) / (I_1 (I_3 - I_1))`, :math:`A_2^2 = (2 E I_3 - L^2) / (I_2 (I_3 - I_2))`
    and :math:`A_3^2 = (L^2 - 2 E I_1) / (I_3 (I_3 - I_1))`; for :math:`L^2 < 2 E I_2` axes 1 and 3 exchange their
    roles. The module docstring gives the separatrix, the symmetric top and how accuracy is kept near
    :math:`m = 1`.

    One time (a scalar ``t`` or an array of one) takes the fused one-time kernel (:func:`omega_at`; for 2000 spins
    about 9x faster than the grid's set-up), which agrees with a time grid holding ``t`` to a few ulps of ``|w|``,
    not bit for bit. A grid of two or more times is set up once per spin, then evaluated (:func:`omega_apart`: the
    kernels the scenes call, so the same bits as theirs).

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    A spin 0.01 rad/s off the intermediate axis flips and returns after one period:

    >>> import numpy as np, tumble
    >>> body, w0 = tumble.Body(1.0, 2.0, 3.0), [0.01, 1.0, 0.0]
    >>> tumble.exact.omega(body, w0, np.linspace(0.0, 10.0, 5)).shape
    (5, 3)
    >>> T = tumble.exact.period(body, w0)
    >>> bool(np.allclose(tumble.exact.omega(body, w0, float(T)), w0, atol=1e-9))
    True
    """
    tt = _check_t(t)
    if tt.size == 1:
        w = spin_vectors(w0)
        at = omega_at(one_body(body), w.reshape(-1, 3), float(tt.reshape(())))
        return at.reshape(w.shape if tt.ndim == 0 else w.shape[:-1] + (1, 3))
    return _omega_grid(body, w0, tt)


def omega_apart(moments, w, times):
    """Angular velocity (n, T, 3) of spins ``w`` (n, 3) of one body ``moments`` (3,) at ``times`` (T,), all validated:
    the set-up (:func:`solve_rows`, which lifts spins within ``TINY_TRANSVERSE`` of an axis), then the evaluation
    (:func:`omega_rows`), the kernels a scene's samples use; :func:`omega` on a grid."""
    sol = solve_rows(np.broadcast_to(moments, w.shape), w)
    return omega_rows(sol, times.reshape(1, -1), np.zeros(w.shape[0], dtype=np.int64))


def omega_rows_on_device(moments, w, times, row):
    """:func:`omega_rows` on the CUDA device, set-up included, for the samples of many scenes in one launch: sample
    ``i`` (of ``w``, (n, 3)) of the body ``moments[row[i]]`` ((R, 3)) at the times ``times[row[i]]`` ((R, T)), all
    validated; :func:`tumble.kernels.cuda.closed_form.omega_rows`. A launch with a spin within ``TINY_TRANSVERSE`` of an
    axis is evaluated as the CPU's is (:func:`solve_rows`, :func:`omega_rows`), on the CPU."""
    out, tiny, non_finite = device_closed_form().omega_rows(moments, w, times, row)
    if tiny:
        return omega_rows(solve_rows(np.ascontiguousarray(moments[row]), w), times, row)
    if non_finite:
        raise FloatingPointError("exact.omega produced non-finite values; please report this spin")
    return out


def phase_fit_rows_on_device(moments, w, times, row, columns, weights, floor, max_step):
    """The phase fit (:func:`tumble.kernels.fits.phase_fit`) of the motion of the samples of
    :func:`omega_rows_on_device` (its first four arguments), evaluated and fitted on the CUDA device
    (:func:`tumble.kernels.cuda.closed_form.omega_rows_phase_fit`): the states stay there and only the frequency, the median
    radius and the fit's code of each sample come back. ``columns``, ``weights``, ``floor`` and ``max_step`` as
    :func:`tumble.kernels.fits.phase_fit` takes them. A launch with a spin within ``TINY_TRANSVERSE`` of an axis is
    evaluated and fitted as the CPU's is, on the CPU.

    Returns
    -------
    frequency, radius : ndarray, shape (n,)
    code : ndarray of int8, shape (n,)
    """
    fit, tiny, non_finite = device_closed_form().omega_rows_phase_fit(moments, w, times, row, columns, weights, floor,
                                                                      max_step)
    if tiny:
        states = omega_rows(solve_rows(np.ascontiguousarray(moments[row]), w), times, row)
        n = w.shape[0]
        fit = np.empty(n), np.empty(n), np.empty(n, dtype=np.int8)
        _fits.phase_fit(np.ascontiguousarray(times, dtype=float), np.ascontiguousarray(row, dtype=np.int64), states,
                        np.ascontiguousarray(columns, dtype=np.int64), np.ascontiguousarray(weights, dtype=float),
                        np.ascontiguousarray(floor, dtype=float), float(max_step), *fit)
        return fit
    if non_finite:
        raise FloatingPointError("exact.omega produced non-finite values; please report this spin")
    return fit


def omega_on_device(moments, w, times):
    """Angular velocity (n, T, 3), rad/s, of spins ``w`` (n, 3) of one body ``moments`` (3,) at ``times`` (T,), all
    validated, on the CUDA device (resolved by the caller: :func:`tumble.engine.device.resolve_device`), one thread
    per sample: :func:`tumble.kernels.cuda.closed_form.omega_at` for one time, else
    :func:`tumble.kernels.cuda.closed_form.omega_grid` (set-up and evaluation). They agree with :func:`omega_at` and
    :func:`omega` to a few ulps of ``|w|`` (not bit for bit: the CPU's one-time kernel runs in SIMD lanes, and a
    GPU fuses multiply-adds its own way). A call with a spin within ``TINY_TRANSVERSE`` of an axis (whose
    invariants underflow) is evaluated as the CPU's is, by :func:`omega_apart` (the lifted set-up), on the CPU."""
    kernels = device_closed_form()
    if times.shape[0] == 1:
        out, tiny, non_finite = kernels.omega_at(moments, w, float(times[0]))
        out = out[:, None]
    else:
        out, tiny, non_finite = kernels.omega_grid(moments, w, times)
    if tiny:
        return omega_apart(moments, w, times)
    if non_finite:
        raise FloatingPointError("exact.omega produced non-finite values; please report this spin")
    return out


def _omega_grid(body, w0, tt):
    """:func:`omega` on the time grid ``tt`` (validated, 1-d): :func:`omega_apart`, its kernels compiled side by side
    where numba's cache lacks them (:func:`compile_kernels_side_by_side`)."""
    w = spin_vectors(w0)
    moments = one_body(body)
    compile_kernels_side_by_side("grid", regimes=regimes_to_compile(moments, w))
    out = omega_apart(moments, np.ascontiguousarray(w.reshape(-1, 3)), np.ascontiguousarray(tt))
    return out.reshape(w.shape[:-1] + out.shape[1:])


def parameters(body, w0):
    """Parameters of the exact solution for each initial spin.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body (moments in kg m², any order).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    EllipticParameters
        Fields shaped ``w0.shape[:-1]`` (see :class:`EllipticParameters`).

    See Also
    --------
    tumble.exact.omega : The motion these parameters describe.
    tumble.exact.period : ``4 K / |nu|``.

    Examples
    --------
    Near the intermediate axis (regime ``-1``: the smallest-moment component keeps its sign) and on it
    (a steady spin):

    >>> import tumble
    >>> p = tumble.exact.parameters((1.0, 2.0, 3.0), [[0.01, 1.0, 0.0], [0.0, 1.0, 0.0]])
    >>> p.regime.tolist(), p.stationary.tolist(), p.mid_axis
    ([-1, 0], [False, True], 1)
    >>> round(float(p.m[0]), 6), round(float(p.kc[0]), 6)
    (0.9999, 0.01)
    """
    sol = _solve(body, w0)
    n = sol.kind.shape[0]
    elliptic = sol.kind == _ell.KIND_ELLIPTIC
    u0 = sol.phase0.copy()
    # elliptic: u0 = K + r0 + 2K n0, with n0 = 1 where the sn amplitude was flipped; wrap into (-2K, 2K]
    K = np.where(elliptic, sol.K, 0.0)
    n0 = np.where(sol.amp[:, 1] < 0, 1.0, 0.0)
    u = K + sol.phase0 + 2.0 * K * n0
    u = np.where(u > 2.0 * K, u - 4.0 * K, u)
    u0 = np.where(elliptic, u, u0)
    amplitude = np.empty((n, 3))
    rows = np.arange(n)[:, None]
    amplitude[rows, sol.cols] = np.abs(sol.amp)
    dn_axis = sol.cols[:, 2].copy()
    shape = sol.shape
    return EllipticParameters(
        m=sol.m.reshape(shape),
        kc=sol.kc.reshape(shape),
        K=sol.K.reshape(shape),
        nu=sol.nu.reshape(shape),
        u0=u0.reshape(shape),
        regime=sol.regime.reshape(shape),
        stationary=sol.stationary.reshape(shape),
        energy=sol.energy.reshape(shape),
        L2=sol.L2.reshape(shape),
        delta=sol.delta.reshape(shape),
        amplitude=amplitude.reshape(shape + (3,)),
        mid_axis=sol.mid_axis,
        dn_axis=dn_axis.reshape(shape),
    )


def period(body, w0):
    r"""Period of the body-frame motion, ``4 K(m) / |nu|`` (Landau & Lifshitz §37).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body (moments in kg m², any order).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    ndarray, shape (...)
        Period, s. ``2 pi / |Omega|`` for a symmetric top; ``inf`` for a stationary spin (steady rotation
        about a principal axis, any spin of a sphere, zero spin) and exactly on the separatrix.

    See Also
    --------
    tumble.exact.flip_spacing : Half of it.
    tumble.exact.parameters : ``K``, ``nu`` and ``m``.

    Notes
    -----
    :math:`\operatorname{sn}` and :math:`\operatorname{cn}` have the period :math:`4K(m)` in their argument
    :math:`u = u_0 + \nu t` (:func:`omega`), so [1]_

    .. math::

        T = \frac{4 K(m)}{|\nu|}, \qquad K(m) = \int_0^{\pi/2} \frac{d\theta}{\sqrt{1 - m \sin^2\theta}}.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    >>> import tumble
    >>> round(float(tumble.exact.period((1.0, 2.0, 3.0), [0.01, 1.0, 0.0])), 4)
    41.5092
    >>> float(tumble.exact.period((1.0, 2.0, 3.0), [0.0, 1.0, 0.0]))  # a steady spin
    inf
    """
    sol = _solve(body, w0)
    with np.errstate(divide="ignore"):
        out = np.where(sol.kind == _ell.KIND_ELLIPTIC, 4.0 * sol.K / np.abs(sol.nu), np.inf)
    return out.reshape(sol.shape)


def flip_spacing(body, w0):
    r"""Time between successive sign changes of the intermediate-axis component, ``2 K / |nu|``.

    In both regimes ``w_mid ∝ sn(u)``, which changes sign at every ``u = 2K j`` (Landau & Lifshitz §37).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body (moments in kg m², any order).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    ndarray, shape (...)
        Flip spacing, s; ``inf`` where ``w_mid`` never or only once changes sign (stationary spins, the
        separatrix).

    See Also
    --------
    tumble.exact.first_flip_time : The first flip.
    tumble.exact.period : Twice the spacing.

    Notes
    -----
    :math:`\omega_\mathrm{mid} \propto \operatorname{sn} u` vanishes at every :math:`u = 2Kj` [1]_, so successive flips
    are

    .. math::

        \Delta t = \frac{2 K(m)}{|\nu|}

    apart, half the period of the body-frame motion.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    >>> import tumble
    >>> body, w0 = (1.0, 2.0, 3.0), [1e-3, 1.0, 0.0]
    >>> round(float(tumble.exact.flip_spacing(body, w0)), 3)
    28.731
    >>> round(float(2 * tumble.exact.flip_spacing(body, w0) / tumble.exact.period(body, w0)), 12)
    1.0
    """
    sol = _solve(body, w0)
    return flip_spacings(sol).reshape(sol.shape)


def first_flip_time(body, w0):
    r"""Time of the first sign change of the intermediate-axis component ``w_mid`` after ``t = 0``.

    ``w_mid ∝ sn(u)`` in both regimes (Landau & Lifshitz §37), so it changes sign at the first zero of
    ``sn`` after ``u0`` in the direction of ``nu``: at ``(K - sign(nu) (u0 - K)) / |nu|`` with ``u0 - K``
    reduced into ``(-K, K]``. A spin whose ``w_mid`` is exactly zero at ``t = 0`` flips at the *next* zero,
    one flip spacing later. On the separatrix ``w_mid ∝ tanh(u0 + nu t)`` changes sign once, at
    ``-u0 / nu`` if that is positive.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body (moments in kg m², any order).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    ndarray, shape (...)
        First flip time, s (> 0); ``inf`` where ``w_mid`` never changes sign for ``t > 0`` (stationary
        spins; separatrix spins already past their flip).

    See Also
    --------
    tumble.exact.flip_spacing : The time between later flips.
    tumble.theory.flip_time_asymptote : Its linear-theory estimate near the separatrix.

    Notes
    -----
    With :math:`\omega_\mathrm{mid} \propto \operatorname{sn}(u_0 + \nu t)` [1]_ and :math:`u_0 - K` reduced into
    :math:`(-K, K]`,

    .. math::

        t_1 = \frac{K - \operatorname{sign}(\nu)\,(u_0 - K)}{|\nu|}.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    >>> import tumble
    >>> round(float(tumble.exact.first_flip_time((1.0, 2.0, 3.0), [1e-3, 1.0, 0.0])), 3)
    14.366
    >>> float(tumble.exact.first_flip_time((1.0, 2.0, 3.0), [0.0, 0.0, 1.0]))  # a steady spin never flips
    inf
    """
    sol = _solve(body, w0)
    return first_flips(sol).reshape(sol.shape)


# ---------------------------------------------------------------------------------------------------
# The attitude: body-to-space rotation in closed form
def attitude(body, w0, t):
    r"""Orientation of the torque-free rigid body in closed form: the body-to-space rotation.

    The space frame is the body frame at ``t = 0`` (``q(0) = 1``). In the frame where the angular momentum
    ``L`` is along ``Z``, the rotation is ``R_z(φ) R_x(θ) R_z(ψ)`` in the body axes ``(a, b, p)`` (Landau &
    Lifshitz §35, §37), with ``p`` the axis the polhode circles (whose component goes as ``dn``) and
    ``(a, b, p)`` right-handed. ``θ`` and ``ψ`` follow from the body-frame direction of ``L``
    (``L / |L| = (sin θ sin ψ, sin θ cos ψ, cos θ)``, from :func:`omega`); the precession angle obeys
    ``φ' = |L| (2E - I_p w_p²) / (|L|² - I_p² w_p²)``, which with ``w_p ∝ dn u`` integrates to

    ``φ(t) = |L| t / I_p + |L| (I_p - I_q) / (I_q I_p ν) [Π(u) - Π(u0)]``,

    ``Π(u) = ∫_0^u du' / (1 - n sn² u')``, ``n = -I_p (I_mid - I_q) / (I_q (I_p - I_mid))`` (``q`` the third
    extreme axis, ``u = u0 + ν t`` the elliptic argument of :func:`omega`): an elliptic integral of the third
    kind, evaluated with Carlson's ``R_F`` and ``R_J``; ``φ`` never needs a quadrature.
    ``ψ`` is carried continuously in time from the amplitude ``am u``, so ``q(t)`` is continuous in ``t``
    (``q`` and ``-q`` are the same rotation; the sign here is the one reached continuously from ``q(0) = 1``).
    Steady spins turn uniformly about their fixed axis.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body (moments in kg m², any order).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.
    t : array_like, shape (T,) or scalar
        Times, s.

    Returns
    -------
    ndarray, shape (..., T, 4)
        Unit quaternions, scalar first (``v_space = q v_body q*``); shape ``(..., 4)`` for a scalar ``t``.

    See Also
    --------
    tumble.exact.omega : The body-frame angular velocity.
    tumble.exact.rotation_per_period : The turn per period about ``L``, by Montgomery's formula.
    tumble.integrate : ``attitude=True``: the attitude stepped by any method.
    tumble.rotations.rotate : Turn vectors by the quaternions.

    Notes
    -----
    The precession angle about :math:`\mathbf L` obeys
    :math:`\dot\varphi = |L| (2E - I_p \omega_p^2) / (L^2 - I_p^2 \omega_p^2)` [1]_, which with
    :math:`\omega_p \propto \operatorname{dn} u` integrates to

    .. math::

        \varphi(t) = \frac{|L|\,t}{I_p} + \frac{|L|\,(I_p - I_q)}{I_q I_p \nu} \left[\Pi(u) - \Pi(u_0)\right],
        \qquad \Pi(u) = \int_0^u \frac{du'}{1 - n \operatorname{sn}^2 u'},

    an elliptic integral of the third kind, evaluated with Carlson's :math:`R_F` and :math:`R_J` [2]_.

    Evaluated by :mod:`tumble.kernels.closed_form.elliptic_attitude`, one sample and one time at a time, in parallel over both:
    the per-sample code the CUDA device runs too (:func:`attitude_on_device`). Carlson's ``R_J`` there agrees with
    ``scipy.special.elliprj`` to a few ulps.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §35 and §37.
    .. [2] B. C. Carlson, "Numerical computation of real or complex elliptic integrals", Numer. Algorithms 10,
       13 (1995).

    Examples
    --------
    The angular momentum turned into space stays where it was at ``t = 0``:

    >>> import numpy as np, tumble
    >>> from tumble import rotations
    >>> body, w0, t = tumble.Body(1.0, 2.0, 3.0), [0.2, 0.0, 1.0], np.linspace(0.0, 5.0, 3)
    >>> q = tumble.exact.attitude(body, w0, t)
    >>> q.shape, bool(np.allclose(np.linalg.norm(q, axis=-1), 1.0))
    ((3, 4), True)
    >>> L = rotations.rotate(q, body.moments * tumble.exact.omega(body, w0, t))
    >>> bool(np.allclose(L, body.moments * w0))
    True
    """
    tt = _check_t(t)
    moments = one_body(body)
    w = np.ascontiguousarray(spin_vectors(w0).reshape(-1, 3))
    compile_kernels_side_by_side("grid", attitude=True, regimes=regimes_to_compile(moments, w))
    sol = _solve(body, w0)
    times = np.ascontiguousarray(np.atleast_1d(tt))
    out = attitude_rows(np.broadcast_to(moments, w.shape), w, sol, times)
    out = out.reshape(sol.shape + (times.shape[0], 4))
    return out[..., 0, :] if tt.ndim == 0 else out


def attitude_rows(moments, w, sol, times):
    """The attitude (n, T, 4) of spins ``w`` (n, 3) of bodies ``moments`` (n, 3), set up as ``sol``
    (:func:`solve_rows`), at ``times`` (T,), all validated: :func:`attitude` below its checks. Raises
    ``FloatingPointError`` on a non-finite quaternion (the one check at the layer boundary)."""
    n = w.shape[0]
    row = np.zeros(n, dtype=np.int64)
    omega_t = omega_rows(sol, times[None, :], row)
    start = omega_rows(sol, np.zeros((1, 1)), row)[:, 0]
    constants = np.empty((n, _ell_attitude.CONSTANTS))
    landen_a, landen_c = np.zeros((n, _ell_attitude.LANDEN)), np.zeros((n, _ell_attitude.LANDEN))
    _ell_attitude.attitude_setup(np.array(moments, dtype=float), w, sol.kind, sol.amp, sol.cols, sol.kc,
                                 sol.K, sol.phase0, sol.nu, np.ascontiguousarray(start), constants, landen_a,
                                 landen_c)
    out = np.empty((n, times.shape[0], 4))
    _ell_attitude.attitude_rows(constants, landen_a, landen_c, times, omega_t, out)
    if not np.all(np.isfinite(out)):
        raise FloatingPointError("exact.attitude produced non-finite values; please report this spin")
    return out


def attitude_on_device(moments, w, times):
    """:func:`attitude` (n, T, 4) of spins ``w`` (n, 3) of one body ``moments`` (3,) at ``times`` (T,), all validated,
    on the CUDA device (resolved by the caller), one thread per sample: the closed form's set-up, its angular velocity
    at each time and the CPU's per-sample attitude code (:func:`tumble.kernels.cuda.closed_form.attitude_rows`). Agrees
    with :func:`attitude` to a few ulps where the angular velocity does (:func:`omega_on_device`). A call with a spin
    within ``TINY_TRANSVERSE`` of an axis is evaluated as the CPU's is (the lifted set-up), on the CPU."""
    out, tiny, non_finite = device_closed_form().attitude_rows(np.reshape(moments, (1, 3)), w,
                                                               np.reshape(times, (1, -1)), np.zeros(1, dtype=np.int64))
    if tiny:
        rows = np.broadcast_to(moments, w.shape)
        return attitude_rows(rows, w, solve_rows(rows, w), np.ascontiguousarray(times, dtype=float))
    if non_finite:
        raise FloatingPointError("exact.attitude produced non-finite values; please report this spin")
    return out


def rotation_per_period(body, w0, *, nodes=256, max_nodes=1 << 16, tol=1e-13):
    r"""Montgomery's formula for how far the body turns about ``L`` in one period of its body-frame motion.

    After one period ``T`` (:func:`period`) the body-frame motion repeats and the body has turned about the
    fixed angular momentum by ``Δθ = 2 E T / |L| - S`` (mod 2π) (R. Montgomery, "How much does the rigid
    body rotate? A Berry's phase from the 18th century", Am. J. Phys. 59, 394 (1991)), with ``S`` the solid
    angle enclosed by the path of ``L / |L|`` in the body frame: the cap about the pole ``±e_p`` it circles
    (``p`` the axis whose component keeps its sign), counted positive when ``L / |L|`` circles that pole
    counterclockwise seen from outside the sphere (right-handed about it), negative when clockwise.

    ``S = -s ∮ (1 - s cos θ) dψ`` (``s = ±1`` the pole) is computed here from the closed-form motion
    (:func:`omega`) with the trapezoid rule over one period, which converges geometrically for this smooth periodic integrand; ``ψ' = (n_b
    n_a' - n_a n_b') / (n_a² + n_b²)`` with ``n' = n × w`` (``n = L/|L|`` in body axes ``(a, b, p)``, ``p``
    the axis the polhode circles, ``cos θ = n_p``). The nodes double until two estimates agree to ``tol``.
    It is independent of :func:`attitude`, which gives the same angle from an elliptic integral of the third
    kind.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    delta : ndarray, shape (...)
        ``2 E T / |L| - S``, rad (not reduced mod 2π); NaN where the motion is not periodic (steady spins,
        the separatrix, a symmetric top's motion is periodic and included).
    solid_angle : ndarray, shape (...)
        ``S``, sr.

    See Also
    --------
    tumble.exact.attitude : The same angle from the closed-form attitude.
    tumble.exact.period : The period ``T``.

    Notes
    -----
    After one period :math:`T` the body has turned about the fixed angular momentum by [1]_

    .. math::

        \Delta\theta = \frac{2 E T}{|L|} - S \pmod{2\pi},

    :math:`S` the solid angle the path of :math:`\mathbf L / |L|` encloses in the body frame.

    References
    ----------
    .. [1] R. Montgomery, "How much does the rigid body rotate? A Berry's phase from the 18th century",
       Am. J. Phys. 59, 394 (1991).

    Examples
    --------
    >>> import tumble
    >>> delta, solid_angle = tumble.exact.rotation_per_period((1.0, 2.0, 3.0), [0.2, 0.0, 1.0])
    >>> round(float(delta), 4), round(float(solid_angle), 4)
    (6.3463, 0.0279)
    """
    moments = one_body(body)
    for name, value, low in (("nodes", nodes, 2), ("max_nodes", max_nodes, nodes)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < low:
            raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
    if isinstance(tol, (bool, np.bool_)) or not isinstance(tol, (int, float, np.number)) or not 0 < tol < 1:
        raise ValueError(f"tol must be a number in (0, 1), got {tol!r}")
    sol = _solve(body, w0)
    w = np.ascontiguousarray(spin_vectors(w0).reshape(-1, 3))
    n = w.shape[0]
    delta = np.full(n, np.nan)
    solid = np.full(n, np.nan)
    periodic = np.flatnonzero(sol.kind == _ell.KIND_ELLIPTIC)
    for i in periodic:
        T = 4.0 * sol.K[i] / abs(sol.nu[i])
        p = sol.cols[i, 2]
        a, b = (p + 1) % 3, (p + 2) % 3
        previous = None
        count = nodes
        while True:
            t = np.arange(count) * (T / count)
            wt = omega(moments, w[i], t)
            L = moments * wt
            u = L / np.linalg.norm(L, axis=1, keepdims=True)
            du = np.cross(u, wt)
            psi_rate = (u[:, b] * du[:, a] - u[:, a] * du[:, b]) / (u[:, a] ** 2 + u[:, b] ** 2)
            pole = 1.0 if u[0, p] > 0 else -1.0  # the cap about the pole L circles (n_p keeps its sign)
            estimate = -pole * np.mean((1.0 - pole * u[:, p]) * psi_rate) * T
            if previous is not None and abs(estimate - previous) <= tol * max(1.0, abs(estimate)):
                break
            if count >= max_nodes:
                raise FloatingPointError(f"rotation_per_period: the solid angle did not converge for spin {w[i]}")
            previous = estimate
            count *= 2
        solid[i] = estimate
        delta[i] = sol.energy[i] * 2.0 * T / np.sqrt(sol.L2[i]) - estimate
    return delta.reshape(sol.shape), solid.reshape(sol.shape)
