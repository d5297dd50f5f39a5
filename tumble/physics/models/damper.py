"""A rigid body with Kane's spherical damper: a sphere of moment ``J`` inside the body, coupled by viscosity ``c``.

``I w' = (I w) × w + c (s − w)``, ``J (s' + w × s) = −c (s − w)`` (body frame; ``I`` excludes the sphere): state
``w1 w2 w3`` and the sphere's angular velocity ``s1 s2 s3`` (rad/s); parameters ``damper_inertia`` ``J`` (kg m²) and
``damping`` ``c`` (N m s). ``|I w + J s|`` is kept, the energy decays (the drift observer tracks ``|L|²`` only).

The system in one module, as :mod:`tumble.physics.models.gyrostat`: its per-sample equations and the model with
its scenes.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ... import registry
from . import base

__all__ = ["Constants", "Damper", "constants", "invariants", "rate", "tangent"]


#: The rigid body's fields (``I`` excludes the sphere), ``c/I_i`` and ``c/J`` (1/s), and ``J`` (kg m²).
Constants = namedtuple("Constants", (*registry.RIGID_BODY, "c_i1", "c_i2", "c_i3", "c_j", "j"))


def constants(moments, damper_inertia, damping):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²), ``J`` (kg m²) and ``c`` (N m s); ``J = 0`` (no
    damper) gives ``c/J = 0`` (no damping either)."""
    rigid = registry.rigid_body(moments)
    i1, i2, i3 = rigid[:3]
    j, c = float(damper_inertia), float(damping)
    return Constants(*rigid, c / i1, c / i2, c / i3, c / j if j > 0 else 0.0, j)


def rate(t, w1, w2, w3, s1, s2, s3, c):
    """``(w', s')``, rad/s²."""
    d1, d2, d3 = s1 - w1, s2 - w2, s3 - w3
    return (c.a1 * w2 * w3 + c.c_i1 * d1,
            c.a2 * w3 * w1 + c.c_i2 * d2,
            c.a3 * w1 * w2 + c.c_i3 * d3,
            (s2 * w3 - s3 * w2) - c.c_j * d1,
            (s3 * w1 - s1 * w3) - c.c_j * d2,
            (s1 * w2 - s2 * w1) - c.c_j * d3)


def tangent(t, w1, w2, w3, s1, s2, s3, v1, v2, v3, u1, u2, u3, c):
    # size: the state's six components, the tangent's six (v along w, u along s), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``s``)."""
    e1, e2, e3 = u1 - v1, u2 - v2, u3 - v3
    return (c.a1 * (v2 * w3 + w2 * v3) + c.c_i1 * e1,
            c.a2 * (v3 * w1 + w3 * v1) + c.c_i2 * e2,
            c.a3 * (v1 * w2 + w1 * v2) + c.c_i3 * e3,
            ((u2 * w3 - u3 * w2) + (s2 * v3 - s3 * v2)) - c.c_j * e1,
            ((u3 * w1 - u1 * w3) + (s3 * v1 - s1 * v3)) - c.c_j * e2,
            ((u1 * w2 - u2 * w1) + (s1 * v2 - s2 * v1)) - c.c_j * e3)


def invariants(w1, w2, w3, s1, s2, s3, c):
    """``(|I w + J s|² ((N m s)²), 0, 0)`` and their scales ``((|I w| + J |s|)², 1, 1)``: ``|L|²`` may vanish."""
    l1, l2, l3 = c.i1 * w1, c.i2 * w2, c.i3 * w3
    t1, t2, t3 = l1 + c.j * s1, l2 + c.j * s2, l3 + c.j * s3
    scale = math.sqrt(l1 * l1 + l2 * l2 + l3 * l3) + c.j * math.sqrt(s1 * s1 + s2 * s2 + s3 * s3)
    return t1 * t1 + t2 * t2 + t3 * t3, 0.0, 0.0, scale * scale, 1.0, 1.0


@dataclass(frozen=True, eq=False)
class Damper(base.Model):
    """A rigid body with a viscously coupled spherical damper (Kane's damper: Kane & Levinson, *Spacecraft
    Dynamics*, §4.4 and §5.6; Hughes, *Spacecraft Attitude Dynamics*, §7.5).

    A sphere of moment of inertia ``J`` (kg m²) turns in a spherical cavity at the centre of mass, coupled to the
    body by a viscous torque ``c (s − w)``, ``c`` in N m s. State ``(w1, w2, w3, s1, s2, s3)``: the body's and the
    sphere's angular velocities in the body frame, rad/s:

    ``I w' = (I w) × w + c (s − w)``,  ``J (s' + w × s) = −c (s − w)``

    (``I``: the body's principal moments without the sphere, which is symmetric, so the axes stay principal).
    ``L = I w + J s`` is fixed in space: ``momentum_squared`` ``|L|²`` ((N m s)²) is the invariant; the energy
    ``½ w·I w + ½ J |s|²`` (:meth:`energy`) decays at ``c |s − w|²`` (:meth:`dissipation`). A spin
    ``s = w = W e_a`` about any principal axis is steady; about the major axis it is asymptotically stable, about
    the minor one it slowly grows (the major-axis rule; weak-damping rate in
    :func:`tumble.physics.theory.damper_nutation_rate`).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments of the body, sphere excluded, kg m².
    damper_inertia : float
        ``J``, kg m²; finite and > 0.
    damping : float
        ``c``, N m s; finite and > 0.

    Raises
    ------
    ValueError
        Invalid moments, or a parameter not a finite number > 0 (the message names ``damper_inertia`` or
        ``damping``).

    See Also
    --------
    tumble.theory.damper_nutation_rate : The nutation's growth rate, weak damping.
    tumble.models.FreeBody : The body without the damper.

    Examples
    --------
    The major-axis rule: a spin about the major axis (3 here) is stable, about the minor one it is not:

    >>> import tumble
    >>> damper = tumble.models.Damper((1.0, 2.0, 3.0), damper_inertia=0.1, damping=0.05)
    >>> damper.spec.state
    ('w1', 'w2', 'w3', 's1', 's2', 's3')
    >>> tumble.theory.linear(damper, 3, 1.0)[0], tumble.theory.linear(damper, 1, 1.0)[0]
    ('periodic', 'exponential')
    """

    damper_inertia: float
    damping: float
    kind: ClassVar[str] = "damper"
    not_lie_poisson: ClassVar[str] = "a damper is dissipative"
    modal: ClassVar[bool] = True  # the sphere's components couple to the body's nutation
    saturates_near_threshold: ClassVar[bool] = False

    def angular_velocity(self, momentum):
        """The steady spin with angular momentum ``L``: ``w = s = (I + J)⁻¹ L`` (rad/s), shape (..., 3).

        Only along a principal axis is this a steady state (with ``s = w``); ``w`` of other states is not a
        function of ``L`` alone.

        Raises
        ------
        ValueError
            ``momentum`` not finite or not of shape (..., 3).
        """
        return super().angular_velocity(momentum) * self.moments / (self.moments + self.damper_inertia)

    def energy(self, state):
        """``½ w·I w + ½ J |s|²`` (J), shape (...): decreasing, at the rate :meth:`dissipation`."""
        y = self._state(state)
        w, s = y[..., :3], y[..., 3:]
        return 0.5 * np.sum(self.moments * w * w, axis=-1) + 0.5 * self.damper_inertia * np.sum(s * s, axis=-1)

    def dissipation(self, state):
        """``c |s − w|²`` (W), shape (...): minus the rate of change of :meth:`energy`."""
        y = self._state(state)
        slip = y[..., 3:] - y[..., :3]
        return self.damping * np.sum(slip * slip, axis=-1)

    def equilibrium(self, axis, spin=1.0):
        """The steady spin ``w = s = spin e_axis``: shape (..., 6) for ``spin`` (...) rad/s; ``axis`` 1, 2 or 3."""
        k = base.one_axis(axis)
        state = base.spin_state(6, k, spin)
        state[..., k + 3] = state[..., k]
        return state

    def transverse(self, axis, spin=1.0):
        """The body's two components ``w_b, w_c`` across ``axis``, weighted as the free body's of moments ``I``
        (a weakly damped nutation is then circular); the sphere's components are not part of the norm (they follow
        the body's nutation, and their relative motion decays at about ``c / J``)."""
        k = base.one_axis(axis)
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return base.Transverse(pair, base.circular_weights(self.moments, k, 1.0, 0.0), pair.copy())

    def mode_space(self, axis, spin=1.0):
        """The body's and the sphere's components across the spin axis, ``(w_b, w_c, s_b, s_c)`` (invariant under the
        linearised motion: the axis' ``w_a, s_a`` decouple), the norm on the body's only (:meth:`Model.mode_space`)."""
        columns, _, _, weights = super().mode_space(axis, spin)
        both = np.concatenate([columns, columns + 3])
        return both, both, np.ones(4), np.concatenate([weights, np.zeros(2)])

    def perturbed(self, draws, axis, spin):
        """:meth:`Model.perturbed`, with the sphere moving with the body: ``s = w``."""
        states = super().perturbed(draws, axis, spin)
        states[:, 3:6] = states[:, :3]
        return states
