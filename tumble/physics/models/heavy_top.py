"""The heavy top on a fixed pivot (Euler-Poisson; Arnold, *Mathematical Methods of Classical Mechanics*, §30;
Goldstein §5.7)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..bodies import finite_array
from . import base

__all__ = ["HeavyTop"]


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

    def rhs(self, state):
        """``(w', g')`` for states of shape (..., 6): rad/s² then 1/s."""
        y = self._state(state)
        w, g = y[..., :3], y[..., 3:]
        torque = self.mgl * np.cross(g, self.centre)
        return np.concatenate([base.euler_rhs(self.moments, w, 0.0) + torque / self.moments, np.cross(g, w)], axis=-1)

    def jacobian(self, state):
        """``∂(w', g')/∂(w, g)`` (1/s), shape (..., 6, 6).

        Blocks: ``∂w'/∂w = I⁻¹ ([Iw]× − [w]× I)``, ``∂w'/∂g = mgl I⁻¹ (−[c]×)``, ``∂g'/∂w = [g]×``,
        ``∂g'/∂g = −[w]×``.
        """
        y = self._state(state)
        w, g = y[..., :3], y[..., 3:]
        jac = np.zeros(y.shape + (6,), dtype=y.dtype)
        jac[..., :3, :3] = base.euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = -self.mgl * base.cross_matrix(self.centre) / self.moments[:, None]
        jac[..., 3:, :3] = base.cross_matrix(g)
        jac[..., 3:, 3:] = -base.cross_matrix(w)
        return jac

    def invariants(self, state):
        """``energy`` (J), ``vertical_momentum`` ``L·g`` (N m s), ``up_squared`` ``|g|²``; each of shape (...)."""
        y = self._state(state)
        w, g = y[..., :3], y[..., 3:]
        lw = self.moments * w
        return {"energy": 0.5 * np.sum(lw * w, axis=-1) + self.mgl * (g @ self.centre),
                "vertical_momentum": np.sum(lw * g, axis=-1), "up_squared": np.sum(g * g, axis=-1)}

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
