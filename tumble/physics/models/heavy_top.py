"""The heavy top (Euler–Poisson): a rigid body on a fixed pivot in uniform gravity.

Moments about the pivot; ``c`` the direction of the centre of mass from the pivot in body axes (a unit vector:
the top's axis 3 by default), at distance ``l``, ``mgl = M g l`` (N m); ``g`` the unit vector pointing up, in body
axes. The torque of the weight ``r × F = l c × (−M g g) = mgl (g × c)`` (Arnold, *Mathematical Methods of Classical
Mechanics*, §30; Goldstein §5.7)::

    I w' = (I w) × w + mgl (g × c),    g' = g × w

State ``w1 w2 w3`` (rad/s), ``g1 g2 g3`` (1); parameters ``mgl`` and ``centre``. Kept: the energy ``½ w·I w + mgl
g·c``, ``L·g`` and ``|g|²``. With ``c = e3`` the products with the zero components of ``c`` add exact zeros: the
equations of a top with its centre on axis 3 to the last bit.

The system in one module, as :mod:`tumble.physics.models.gyrostat`: its per-sample equations and the model with
its scenes.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..bodies import finite_array
from ... import registry
from . import base

__all__ = ["Constants", "HeavyTop", "constants", "invariants", "rate", "tangent"]


#: The rigid body's fields (moments about the pivot), ``mgl`` (N m), the centre's direction ``c1 c2 c3`` and the
#: products ``m_ij = (mgl/I_i) c_j`` (1/s²) the torque's components are made of (two multiply-adds each: the general
#: centre costs the rate four more than the centre on axis 3 did, and the same bits there).
Constants = namedtuple("Constants", (*registry.RIGID_BODY, "mgl", "c1", "c2", "c3", "m12", "m13", "m21", "m23", "m31",
                                     "m32"))


def constants(moments, mgl, centre=(0.0, 0.0, 1.0)):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m², about the pivot), ``mgl`` (N m) and ``centre`` (the
    centre of mass's direction, body axes; normalised here)."""
    rigid = registry.rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    c = np.asarray(centre, dtype=float)
    c1, c2, c3 = (float(x) for x in c / np.linalg.norm(c))
    mgl = float(mgl)
    m1, m2, m3 = mgl / i1, mgl / i2, mgl / i3
    return Constants(*rigid, mgl, c1, c2, c3, m1 * c2, m1 * c3, m2 * c1, m2 * c3, m3 * c1, m3 * c2)


def rate(t, w1, w2, w3, g1, g2, g3, c):
    """``(w', g')``: rad/s², then 1/s."""
    return (c.a1 * w2 * w3 + (c.m13 * g2 - c.m12 * g3),
            c.a2 * w3 * w1 + (c.m21 * g3 - c.m23 * g1),
            c.a3 * w1 * w2 + (c.m32 * g1 - c.m31 * g2),
            g2 * w3 - g3 * w2,
            g3 * w1 - g1 * w3,
            g1 * w2 - g2 * w1)


def tangent(t, w1, w2, w3, g1, g2, g3, v1, v2, v3, u1, u2, u3, c):
    # size: the state's six components, the tangent's six (v along w, u along g), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``g``)."""
    return (c.a1 * (v2 * w3 + w2 * v3) + (c.m13 * u2 - c.m12 * u3),
            c.a2 * (v3 * w1 + w3 * v1) + (c.m21 * u3 - c.m23 * u1),
            c.a3 * (v1 * w2 + w1 * v2) + (c.m32 * u1 - c.m31 * u2),
            (u2 * w3 - u3 * w2) + (g2 * v3 - g3 * v2),
            (u3 * w1 - u1 * w3) + (g3 * v1 - g1 * v3),
            (u1 * w2 - u2 * w1) + (g1 * v2 - g2 * v1))


def invariants(w1, w2, w3, g1, g2, g3, c):
    """``(energy ½ w·Iw + mgl g·c (J), L·g (N m s), |g|²)`` and their scales ``(½ w·Iw + mgl |g|, |I w| |g|,
    |g|²)``.

    The energy and ``L·g`` may vanish (a top hanging or lying flat, a spin across the vertical), so their scales
    are the largest magnitudes they can take for the given ``|I w|`` and ``|g|``; ``|g|²`` is its own scale.
    """
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    kinetic = 0.5 * (l1 * w1 + l2 * w2 + l3 * w3)
    up = g1 * g1 + g2 * g2 + g3 * g3
    g_norm = math.sqrt(up)
    height = g1 * c.c1 + g2 * c.c2 + g3 * c.c3
    return (kinetic + c.mgl * height, l1 * g1 + l2 * g2 + l3 * g3, up,
            kinetic + c.mgl * g_norm, math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) * g_norm, up)


@dataclass(frozen=True, eq=False)
class HeavyTop(base.Model):
    """A heavy top on a fixed pivot (Euler-Poisson equations; Arnold §30, Goldstein §5.7).

    ``I w' = (I w) × w + mgl (g × c)``, ``g' = g × w``: moments about the pivot, centre of mass in the direction
    ``c`` (body frame, a unit vector; body axis 3 by default) at distance ``l`` from it, ``g`` the unit vector
    pointing up (against gravity) in the body frame. State ``(w1, w2, w3, g1, g2, g3)``: rad/s, then dimensionless.
    Invariants: ``energy`` ``½ w·Iw + mgl g·c`` (J), ``vertical_momentum`` ``L·g`` (N m s), ``up_squared``
    ``|g|²`` (1); ``|L|²`` is not conserved. A centre off the principal axes makes the top asymmetric in a way no
    choice of axes undoes: in general not integrable (the chaos indicators' heavy top).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments about the pivot, kg m².
    mgl : float
        ``M g l``, N m; finite and > 0.
    centre : array_like, shape (3,)
        Direction of the centre of mass from the pivot, body axes (normalised here); default ``(0, 0, 1)``.

    Raises
    ------
    ValueError
        Invalid moments, ``mgl`` not a finite number > 0, or ``centre`` not a finite non-zero 3-vector (the message
        names the parameter).

    See Also
    --------
    tumble.theory.sleeping_top_linear : Whether an upright symmetric top sleeps.
    tumble.lyapunov : Chaos of an asymmetric top.
    tumble.shapes.cone : The moments of a cone about its apex.

    Examples
    --------
    A sleeping top: stable when it spins fast, it falls when it spins slowly:

    >>> import tumble
    >>> top = tumble.models.HeavyTop((1.0, 1.0, 0.5), mgl=0.1)
    >>> top.spec.state
    ('w1', 'w2', 'w3', 'g1', 'g2', 'g3')
    >>> tumble.theory.linear(top, 3, 5.0)[0], tumble.theory.linear(top, 3, 0.1)[0]
    ('periodic', 'exponential')
    """

    mgl: float
    centre: np.ndarray = (0.0, 0.0, 1.0)
    kind: ClassVar[str] = "heavy_top"
    extras: ClassVar[tuple] = ("centre",)
    unit_blocks: ClassVar[tuple] = ("g",)
    spin_axes: ClassVar[tuple] = (3,)
    spin_axes_reason: ClassVar[str] = "the centre of mass lies on body axis 3: the sleeping top spins about it"
    modal: ClassVar[bool] = True  # an asymmetric top's modes are elliptical in any fixed weights
    spin_tilt: ClassVar[float] = 1e-3  # a scene's amplitude tilts the up vector; the spin by a thousandth of it
    resolves_spin: ClassVar[bool] = True
    saturates_near_threshold: ClassVar[bool] = False

    def __post_init__(self):
        super().__post_init__()
        centre = finite_array(self.centre, "centre")
        if centre.shape != (3,) or not np.any(centre):
            raise ValueError(f"centre must be a non-zero 3-vector (the centre of mass's direction, body axes), got "
                             f"{self.centre!r}")
        centre = centre / np.linalg.norm(centre)
        centre.setflags(write=False)
        object.__setattr__(self, "centre", centre)

    def _on_axis_3(self):
        if self.centre[0] != 0.0 or self.centre[1] != 0.0:
            raise ValueError(f"a steady spin about axis 3 (the sleeping top) needs the centre of mass on body axis 3; "
                             f"this top's centre is {self.centre.tolist()} (integrate it, or use "
                             f"tumble.theory.eigenvalues_at at a state of your choice)")

    def equilibrium(self, axis, spin=1.0):
        """The sleeping top: ``w = (0, 0, spin)``, ``g = (0, 0, 1)`` (upright), shape (..., 6).

        Raises
        ------
        ValueError
            ``axis`` other than 3 (spin.axis: the centre of mass lies on body axis 3), or a centre off axis 3.
        """
        self._on_axis_3()
        if base.one_axis(axis) != 2:
            raise ValueError(f"axis (spin.axis) must be 3 for a heavy_top: the centre of mass lies on body axis 3, "
                             f"got {axis!r}")
        state = base.spin_state(6, 2, spin)
        state[..., 5] = 1.0
        return state

    def transverse(self, axis, spin=1.0):
        """``(w1, w2, g1, g2)`` with weights ``(1, 1, mgl/I1, mgl/I2)`` (all terms in (rad/s)²); phase: the tilt.

        ``(g1, g2)`` is the tilt of the top's axis from the vertical (rad, to first order); ``mgl / I_i`` is the
        squared rate at which an upright top at rest falls, which makes the two halves comparable whatever the
        spin (also for a top at rest). The phase fit follows the tilt ``(g1, g2)``.
        """
        self._on_axis_3()
        if base.one_axis(axis) != 2:
            raise ValueError(f"axis (spin.axis) must be 3 for a heavy_top, got {axis!r}")
        weights = np.array([1.0, 1.0, self.mgl / self.moments[0], self.mgl / self.moments[1]])
        return base.Transverse(np.array([0, 1, 3, 4], dtype=np.intp), weights, np.array([3, 4], dtype=np.intp))

    def perturbed(self, draws, axis, spin):
        """:meth:`Model.perturbed`, with the up vector ``g`` from ``draws.up()``: ``e3`` tilted by its own angle."""
        states = super().perturbed(draws, axis, spin)
        states[:, 3:6] = draws.up()
        return states
