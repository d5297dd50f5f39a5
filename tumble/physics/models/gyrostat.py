"""The gyrostat (and the free body, its ``h = 0``): a rigid body with a rotor of constant relative angular momentum.

``I w' = (I w + h) × w`` in the body frame (Wittenburg, *Dynamics of Multibody Systems*, §3.6), i.e. for ``(i, j, k)``
cyclic ``w_i' = (I_j − I_k)/I_i w_j w_k + (h_j/I_i) w_k − (h_k/I_i) w_j``. State ``w1 w2 w3`` (rad/s); parameter
``rotor`` ``h`` (N m s, body frame). Kept: the energy ``½ w·I w`` and ``|I w + h|²``.

The system in one module: its per-sample equations (:class:`Constants`, :func:`constants`, :func:`rate`,
:func:`tangent`, :func:`invariants`, and :func:`euler`, the free body's rate: scalar code that numba compiles into the kernels' generated steps, and that
:class:`Gyrostat` evaluates on numpy arrays, :mod:`tumble.physics.models.base`) and the model with its scenes.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ... import registry
from ..bodies import finite_array
from . import base

__all__ = ["Constants", "FreeBody", "Gyrostat", "constants", "euler", "free_rate", "invariants", "rate", "tangent"]

#: The rigid body's fields (:data:`tumble.registry.RIGID_BODY`), ``h_j/I_i`` (1/s) and the rotor ``h``
#: (N m s).
Constants = namedtuple("Constants", (*registry.RIGID_BODY, "h2_i1", "h3_i1", "h3_i2", "h1_i2", "h1_i3", "h2_i3", "h1",
                                     "h2", "h3"))


def constants(moments, rotor=(0.0, 0.0, 0.0)):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²) and ``rotor`` (N m s)."""
    rigid = registry.rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    h1, h2, h3 = (float(x) for x in np.asarray(rotor, dtype=float))
    return Constants(*rigid, h2 / i1, h3 / i1, h3 / i2, h1 / i2, h1 / i3, h2 / i3, h1, h2, h3)


def euler(w1, w2, w3, a1, a2, a3):
    """The free body's rate, Euler's equations ``w_i' = a_i w_j w_k`` (rad/s²; ``a_i = (I_j − I_k)/I_i``, ``(i, j, k)``
    cyclic): the first terms of :func:`rate`, and the rate of the free body's own fused steps
    (:func:`tumble.kernels.steps.steppers.euler_rate`, where a torque is added to it)."""
    return a1 * w2 * w3, a2 * w3 * w1, a3 * w1 * w2


def rate(t, w1, w2, w3, c):
    """``w'`` (rad/s²) at ``w`` (rad/s): Euler's equations plus the rotor's terms ``(h × w) / I``."""
    e1, e2, e3 = euler(w1, w2, w3, c.a1, c.a2, c.a3)
    return (e1 + (c.h2_i1 * w3 - c.h3_i1 * w2),
            e2 + (c.h3_i2 * w1 - c.h1_i2 * w3),
            e3 + (c.h1_i3 * w2 - c.h2_i3 * w1))


def free_rate(t, w1, w2, w3, c):
    """The free body's rate (no rotor): :func:`rate` with ``h = 0``, the same numbers in fewer operations (the
    rotor's terms are a third of :func:`rate`'s, all zero here): what the free body's error-controlled step calls."""
    return euler(w1, w2, w3, c.a1, c.a2, c.a3)


def tangent(t, w1, w2, w3, v1, v2, v3, c):
    """The tangent flow ``J(w) v``: the derivative of :func:`rate` at ``w`` along ``v``."""
    return (c.a1 * (v2 * w3 + w2 * v3) + (c.h2_i1 * v3 - c.h3_i1 * v2),
            c.a2 * (v3 * w1 + w3 * v1) + (c.h3_i2 * v1 - c.h1_i2 * v3),
            c.a3 * (v1 * w2 + w1 * v2) + (c.h1_i3 * v2 - c.h2_i3 * v1))


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


@dataclass(frozen=True, eq=False)
class Gyrostat(base.Model):
    """A rigid body carrying a rotor of constant relative angular momentum ``h``: ``I w' = (I w + h) × w``.

    ``L = I w + h`` (Wittenburg §3.6; Hughes, *Spacecraft Attitude Dynamics*, ch. 7). State ``w`` (3), rad/s.
    Invariants: ``energy`` ``½ w·Iw`` (J; the rotor's own energy is constant) and ``momentum_squared``
    ``|I w + h|²``. A rotor along a principal axis stabilises a spin about it, the intermediate one included,
    once ``|h|`` is large enough (:func:`tumble.physics.theory.gyrostat_linear`).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments of the whole body with the rotor, kg m².
    rotor : array_like, shape (3,)
        ``h``, N m s, body frame; finite.

    Raises
    ------
    ValueError
        Invalid moments, or a rotor that is not a finite 3-vector (the message names ``rotor``).

    See Also
    --------
    tumble.theory.gyrostat_linear : Linear theory, rotor along the spin axis.
    tumble.models.FreeBody : The gyrostat without a rotor.

    Examples
    --------
    A fast enough rotor along the intermediate axis keeps a spin about it steady:

    >>> import tumble
    >>> slow = tumble.models.Gyrostat((1.0, 2.0, 3.0), rotor=(0.0, 0.1, 0.0))
    >>> fast = tumble.models.Gyrostat((1.0, 2.0, 3.0), rotor=(0.0, 5.0, 0.0))
    >>> tumble.theory.linear(slow, 2, 1.0)[0], tumble.theory.linear(fast, 2, 1.0)[0]
    ('exponential', 'periodic')
    """

    rotor: np.ndarray
    kind: ClassVar[str] = "gyrostat"
    #: A rotor component across the spin axis smaller than this fraction of ``|rotor|`` counts as 0 (equilibrium check).
    rotor_rtol: ClassVar[float] = 1e-12

    def _rotor(self):
        return self.rotor

    def equilibrium(self, axis, spin=1.0):
        """The steady spin ``w = spin e_axis`` (shape (..., 3)); it is one only with the rotor along ``axis``.

        Raises
        ------
        ValueError
            The rotor has a component across ``axis`` (beyond ``rotor_rtol |h|``): ``(I w + h) × w ≠ 0``.
        """
        k = base.one_axis(axis)
        across = np.delete(self.rotor, k)
        if np.abs(across).max() > self.rotor_rtol * np.linalg.norm(self.rotor):
            raise ValueError(f"rotor must lie along the spin axis {k + 1} for a steady spin about it, got rotor = "
                             f"{self.rotor.tolist()} N m s")
        return base.spin_state(3, k, spin)

    def transverse(self, axis, spin=1.0):
        """The two components across ``axis``, weighted so that the linear motion is circular for that spin.

        ``weights`` has shape ``spin.shape + (2,)``: ``k_i = I_i ((I_a − I_i) W + h_a)`` depend on the spin.
        """
        k = base.one_axis(axis)
        weights = base.circular_weights(self.moments, k, finite_array(spin, "spin"), float(self.rotor[k]))
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return base.Transverse(pair, weights, pair.copy())


@dataclass(frozen=True, eq=False)
class FreeBody(base.Model):
    """The torque-free rigid body: ``I w' = (I w) × w`` (Landau & Lifshitz §36), the gyrostat's equations with no rotor.
    State ``w`` (3), rad/s.

    Invariants: ``energy`` ``½ w·Iw`` (J) and ``momentum_squared`` ``|I w|²`` ((N m s)²). Its fused SIMD steps, which
    ``tumble.integrate`` runs, are the kernels' own (:mod:`tumble.kernels.loops.free_body_parts`); as a model of studies
    and of :func:`tumble.run_ensemble` it runs the gyrostat's generated steps with ``h = 0``.

    See Also
    --------
    tumble.Body : The free body as the engine takes it most often.
    tumble.models.Gyrostat : With a rotor.

    Examples
    --------
    >>> FreeBody((1.0, 2.0, 3.0)).rhs([0.0, 1.0, 0.0])
    array([0., 0., 0.])
    """

    kind: ClassVar[str] = "free"

    def equilibrium(self, axis, spin=1.0):
        """The steady spin ``w = spin e_axis``: shape (..., 3) for ``spin`` (...) rad/s; ``axis`` 1, 2 or 3."""
        return base.spin_state(3, base.one_axis(axis), spin)

    def transverse(self, axis, spin=1.0):
        """The two components across ``axis`` (cyclic order), weighted so that a linear oscillation is circular."""
        k = base.one_axis(axis)
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return base.Transverse(pair, base.circular_weights(self.moments, k, 1.0, 0.0), pair.copy())
