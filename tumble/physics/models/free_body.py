"""The torque-free rigid body (Landau & Lifshitz, *Mechanics*, §36): the gyrostat's equations with no rotor.

Its fused SIMD steps, which ``tumble.integrate`` runs, are the kernels' own (:mod:`tumble.kernels.free_body_parts`);
as a model of studies and of :func:`tumble.run_ensemble` it runs the gyrostat's generated steps with ``h = 0``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from . import base

__all__ = ["FreeBody"]


@dataclass(frozen=True, eq=False)
class FreeBody(base.Model):
    """The torque-free rigid body: ``I w' = (I w) × w`` (Landau & Lifshitz §36). State ``w`` (3), rad/s.

    Invariants: ``energy`` ``½ w·Iw`` (J) and ``momentum_squared`` ``|I w|²`` ((N m s)²).

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
        weights = base.circular_weights(self.moments, k, 1.0, 0.0)
        return base.Transverse(np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp), weights,
                          np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp))
