"""A rigid body with a viscously coupled spherical damper (Kane & Levinson, *Spacecraft Dynamics*, §4.4)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import base

__all__ = ["Damper"]


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
    """

    damper_inertia: float
    damping: float
    kind: ClassVar[str] = "damper"
    not_lie_poisson: ClassVar[str] = "a damper is dissipative"
    modal: ClassVar[bool] = True  # the sphere's components couple to the body's nutation
    saturates_near_threshold: ClassVar[bool] = False

    def rhs(self, state):
        """``(w', s')`` (rad/s²) for states of shape (..., 6), rad/s."""
        y = self._state(state)
        w, s = y[..., :3], y[..., 3:]
        slip = self.damping * (s - w)
        return np.concatenate([base.euler_rhs(self.moments, w, 0.0) + slip / self.moments,
                               np.cross(s, w) - slip / self.damper_inertia], axis=-1)

    def jacobian(self, state):
        """``∂(w', s')/∂(w, s)`` (1/s), shape (..., 6, 6).

        Blocks (``C = c I⁻¹``, ``k = c / J``): ``∂w'/∂w = I⁻¹ ([Iw]× − [w]× I) − C``, ``∂w'/∂s = C``,
        ``∂s'/∂w = [s]× + k``, ``∂s'/∂s = −[w]× − k``. At a steady spin one eigenvalue is 0: the steady spins
        ``s = w = W e_a`` form a line (the spin rate, set by ``|L|``, is neutral).
        """
        y = self._state(state)
        w, s = y[..., :3], y[..., 3:]
        eye = np.eye(3)
        k = self.damping / self.damper_inertia
        jac = np.zeros(y.shape + (6,), dtype=np.result_type(y, float))
        jac[..., :3, :3] = base.euler_jacobian(self.moments, w, 0.0) - np.diag(self.damping / self.moments)
        jac[..., :3, 3:] = np.diag(self.damping / self.moments)
        jac[..., 3:, :3] = base.cross_matrix(s) + k * eye
        jac[..., 3:, 3:] = -base.cross_matrix(w) - k * eye
        return jac

    def _momentum(self, y):
        return self.moments * y[..., :3] + self.damper_inertia * y[..., 3:]

    def invariants(self, state):
        """``{"momentum_squared": |I w + J s|²}`` ((N m s)²), shape (...)."""
        lm = self._momentum(self._state(state))
        return {"momentum_squared": np.sum(lm * lm, axis=-1)}

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
