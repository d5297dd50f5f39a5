"""A rigid body with a rotor of constant relative angular momentum (Wittenburg, *Dynamics of Multibody
Systems*, §3.6)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..bodies import finite_array
from . import base

__all__ = ["Gyrostat"]

#: A rotor component across the spin axis smaller than this fraction of |rotor| counts as 0 (equilibrium check).
ROTOR_RTOL = 1e-12

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
    """

    rotor: np.ndarray
    kind: ClassVar[str] = "gyrostat"

    def _rotor(self):
        return self.rotor

    def rhs(self, state):
        """``w'`` (rad/s²) for states ``w`` of shape (..., 3), rad/s."""
        return base.euler_rhs(self.moments, self._state(state), self.rotor)

    def jacobian(self, state):
        """``∂w'/∂w`` (1/s), shape (..., 3, 3): ``I⁻¹ ([I w + h]× − [w]× I)``."""
        return base.euler_jacobian(self.moments, self._state(state), self.rotor)

    def invariants(self, state):
        """``{"energy": ½ w·Iw (J), "momentum_squared": |Iw + h|² ((N m s)²)}``, each of shape (...)."""
        w = self._state(state)
        lw = self.moments * w
        total = lw + self.rotor
        return {"energy": 0.5 * np.sum(lw * w, axis=-1), "momentum_squared": np.sum(total * total, axis=-1)}

    def equilibrium(self, axis, spin=1.0):
        """The steady spin ``w = spin e_axis`` (shape (..., 3)); it is one only with the rotor along ``axis``.

        Raises
        ------
        ValueError
            The rotor has a component across ``axis`` (beyond ``ROTOR_RTOL |h|``): ``(I w + h) × w ≠ 0``.
        """
        k = base.one_axis(axis)
        across = np.delete(self.rotor, k)
        if np.abs(across).max() > ROTOR_RTOL * np.linalg.norm(self.rotor):
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
