"""A rigid satellite in a circular or elliptic orbit under the gravity-gradient torque (Hughes, *Spacecraft
Attitude Dynamics*, §8.1-8.3)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..bodies import finite_array
from . import base

__all__ = ["GravityGradient"]


def _rows_of_attitude(q):
    """``(c2, c3)``: the orbit frame's pitch axis ``o2`` and nadir ``o3`` in the body frame, each (..., 3), for
    attitudes ``q`` (..., 4) (scalar first, body to orbit frame): the second and third rows of the rotation matrix
    ``C(q)`` (``v_orbit = C v_body``), ``1 − 2(…)`` on the diagonal (the rotation's matrix on the unit sphere)."""
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    c2 = np.stack([2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1)], axis=-1)
    c3 = np.stack([2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)], axis=-1)
    return c2, c3


def _rows_derivatives(q):
    """``(∂c2/∂q, ∂c3/∂q)`` of :func:`_rows_of_attitude`, each (..., 3, 4)."""
    q0, q1, q2, q3 = (2 * q[..., i] for i in range(4))
    z = np.zeros_like(q0)
    d2 = np.stack([np.stack([q3, q2, q1, q0], -1), np.stack([z, -2 * q1, z, -2 * q3], -1),
                   np.stack([-q1, -q0, q3, q2], -1)], -2)
    d3 = np.stack([np.stack([-q2, q3, -q0, q1], -1), np.stack([q1, q0, q3, q2], -1),
                   np.stack([z, -2 * q1, -2 * q2, z], -1)], -2)
    return d2, d3


def _xi(q):
    """``Ξ(q)``, (..., 4, 3): ``q ⊗ (0, v) = Ξ(q) v`` (Hamilton product, scalar first)."""
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([np.stack([-q1, -q2, -q3], -1), np.stack([q0, -q3, q2], -1), np.stack([q3, q0, -q1], -1),
                     np.stack([-q2, q1, q0], -1)], -2)


def _omega_right(v):
    """``Ω(v)``, (..., 4, 4): ``q ⊗ (0, v) = Ω(v) q``."""
    v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
    z = np.zeros_like(v1)
    return np.stack([np.stack([z, -v1, -v2, -v3], -1), np.stack([v1, z, v3, -v2], -1),
                     np.stack([v2, -v3, z, v1], -1), np.stack([v3, v2, -v1, z], -1)], -2)


@dataclass(frozen=True, eq=False)
class GravityGradient(base.Model):
    """A rigid satellite in a circular orbit under the gravity-gradient torque (Hughes, *Spacecraft Attitude
    Dynamics*, §8.1-8.3; Kane, Likins & Levinson, *Spacecraft Dynamics*, §2.7).

    Orbit frame (DESIGN.md): ``o1`` along track (roll), ``o2`` along the negative orbit normal (pitch), ``o3`` to
    nadir (yaw); ``o1 × o2 = o3``. It turns at the orbit rate ``n`` about the orbit normal, i.e. its angular
    velocity is ``−n o2``. State ``(w1, w2, w3, q0, q1, q2, q3)``: ``w`` the body's (inertial) angular velocity in the
    body frame, rad/s; ``q`` the attitude of the body relative to the orbit frame, a unit quaternion, scalar
    first (``v_orbit = q v_body q*``). With ``c2``, ``c3`` the orbit's ``o2``, ``o3`` in the body frame (rows of
    the rotation matrix of ``q``) and ``w_r = w + n c2`` the angular velocity relative to the orbit frame:

    ``I w' = (I w) × w + 3 n² (c3 × I c3)``,  ``q' = ½ q ⊗ (0, w_r)``.

    The equilibrium is the body's axes along the orbit's (``q = (1, 0, 0, 0)``) with ``w = (0, −n, 0)``: a body
    that turns once per orbit. Invariants: ``jacobi_integral``
    ``½ w_r·I w_r + (3/2) n² c3·I c3 − ½ n² c2·I c2`` (J; the energy in the rotating orbit frame: the kinetic energy
    of the relative motion, the gravity-gradient potential ``(3/2) n² I_nadir`` (MacCullagh's formula less a
    constant) and the centrifugal potential ``−½ n² I_pitch``), and ``quaternion_squared`` ``|q|²`` (1: the rhs
    keeps it, ``q·q' = 0``).

    Linear theory (:meth:`tangent_jacobian`, ``theory.gravity_gradient_pitch_frequency``,
    ``theory.gravity_gradient_roll_yaw``): pitch ``θ2'' + 3 n² (I1 − I3)/I2 θ2 = 0``; roll-yaw
    ``s⁴ + n² (1 + 3 k1 + k1 k3) s² + 4 n⁴ k1 k3 = 0``, ``k1 = (I2 − I3)/I1``, ``k3 = (I2 − I1)/I3``.

    **An elliptic orbit** (``eccentricity`` ``e`` > 0; ``n`` the mean motion, perigee at ``t = 0``): the orbit frame
    turns at the rate of the true anomaly ``ν' = n sqrt(1 − e²) (a/r)²`` and the gradient's strength is ``3 n²
    (a/r)³`` (:meth:`orbit`), so ``n`` becomes ``ν'(t)`` in ``w_r`` and ``3 n²`` becomes ``3 n² (a/r)³`` in the
    torque: the equations depend on time (:meth:`rhs` and :meth:`jacobian` take ``t``), no attitude is an
    equilibrium and the Jacobi integral is not conserved (the spin-orbit problem of Hyperion: Wisdom, Peale &
    Mignard 1984).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments ``(I1, I2, I3)`` about roll, pitch, yaw, kg m².
    orbit_rate : float
        ``n``, rad/s; finite and > 0 (the mean motion of an elliptic orbit).
    eccentricity : float
        ``e`` in [0, 1); default 0, a circular orbit.

    Raises
    ------
    ValueError
        Invalid moments, ``orbit_rate`` not a finite number > 0, or ``eccentricity`` outside [0, 1) (the message names
        the parameter).
    """

    orbit_rate: float
    eccentricity: float = 0.0
    kind: ClassVar[str] = "gravity_gradient"
    extras: ClassVar[tuple] = ("eccentricity",)
    unit_blocks: ClassVar[tuple] = ("q",)
    equilibrium_parameter: ClassVar[str] = "orbit_rate"
    equilibrium_reason: ClassVar[str] = "its equilibrium follows the orbit, w = (0, -n, 0)"
    not_lie_poisson: ClassVar[str] = ("a gravity gradient's state is no Lie–Poisson system in these variables (w and "
                                      "a quaternion relative to the turning orbit frame)")
    modal: ClassVar[bool] = True  # w and the attitude error together, the 6 x 6 tangent Jacobian

    def __post_init__(self):
        super().__post_init__()
        e = finite_array(self.eccentricity, "eccentricity")
        if e.ndim or not 0.0 <= float(e) < 1.0:
            raise ValueError(f"eccentricity must be a number in [0, 1) (0: a circular orbit), got {self.eccentricity!r}")
        object.__setattr__(self, "eccentricity", float(e))

    def orbit(self, t=0.0):
        """``(ν', 3 μ/r³)`` at time ``t`` (s from perigee), each of the shape of ``t``: the orbit frame's rate (rad/s)
        and the gradient's strength (1/s²), from Kepler's equation ``E − e sin E = n t`` (Newton's method from
        Danby's start, to round-off); ``(n, 3 n²)`` in a circular orbit."""
        n, e = self.orbit_rate, self.eccentricity
        t = np.asarray(t, dtype=float)
        if e == 0.0:
            return np.full(t.shape, n), np.full(t.shape, 3 * n * n)
        mean = n * t
        mean = mean - 2 * np.pi * np.floor(mean / (2 * np.pi) + 0.5)
        big = mean + 0.85 * e * np.where(np.sin(mean) >= 0.0, 1.0, -1.0)
        for _ in range(64):
            step = (big - e * np.sin(big) - mean) / (1.0 - e * np.cos(big))
            big = big - step
            if np.all(np.abs(step) <= 1e-15 * (1.0 + np.abs(big))):
                break
        a_r = 1.0 / (1.0 - e * np.cos(big))
        return n * np.sqrt(1.0 - e * e) * a_r ** 2, 3 * n * n * a_r ** 3

    @property
    def tangent_size(self):
        """6: ``w`` and the attitude error ``θ`` (rad) of :meth:`tangent_jacobian`."""
        return 6

    def _parts(self, state, t=0.0):
        y = self._state(state)
        w, q = y[..., :3], y[..., 3:]
        c2, c3 = _rows_of_attitude(q)
        rate, strength = (self.orbit_rate, 3 * self.orbit_rate ** 2) if self.eccentricity == 0.0 else (
            float(x) for x in self.orbit(t))
        return y, w, q, c2, c3, w + rate * c2, rate, strength

    def _torque_jacobian(self, c3, strength):
        """``∂/∂c3`` of ``3 μ/r³ I⁻¹ (c3 × I c3)``, (..., 3, 3): ``3 μ/r³ I⁻¹ ([c3]× I − [I c3]×)``."""
        return (strength / self.moments[:, None]) * (base.cross_matrix(c3) * self.moments - base.cross_matrix(self.moments * c3))

    def rhs(self, state, t=0.0):
        """``(w', q')`` for states of shape (..., 7) at time ``t`` (s; only an eccentric orbit depends on it): rad/s²,
        then 1/s."""
        _, w, q, _, c3, w_r, _, strength = self._parts(state, t)
        torque = strength * np.cross(c3, self.moments * c3)
        dq = 0.5 * np.einsum("...ij,...j->...i", _xi(q), w_r)
        return np.concatenate([base.euler_rhs(self.moments, w, 0.0) + torque / self.moments, dq], axis=-1)

    def jacobian(self, state, t=0.0):
        """``∂(w', q')/∂(w, q)`` (1/s), shape (..., 7, 7), in the state's own components, at time ``t`` (s).

        Blocks: ``∂w'/∂w = I⁻¹ ([Iw]× − [w]× I)``; ``∂w'/∂q = 3 n² I⁻¹ ([c3]× I − [I c3]×) ∂c3/∂q``;
        ``∂q'/∂w = ½ Ξ(q)``; ``∂q'/∂q = ½ Ω(w_r) + ½ n Ξ(q) ∂c2/∂q`` (``q ⊗ (0, v) = Ξ(q) v = Ω(v) q``). At the
        equilibrium the row and the column of ``q0`` vanish: the quaternion's norm is a constraint, an eigenvalue
        0 that is no motion (linear theory uses :meth:`tangent_jacobian`).
        """
        y, w, q, _, c3, w_r, rate, strength = self._parts(state, t)
        d2, d3 = _rows_derivatives(q)
        xi = _xi(q)
        jac = np.zeros(y.shape + (7,), dtype=np.result_type(y, float))
        jac[..., :3, :3] = base.euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = self._torque_jacobian(c3, strength) @ d3
        jac[..., 3:, :3] = 0.5 * xi
        jac[..., 3:, 3:] = 0.5 * _omega_right(w_r) + 0.5 * rate * (xi @ d2)
        return jac

    def _circular(self, what):
        if self.eccentricity != 0.0:
            raise ValueError(f"{what} needs a circular orbit; this one's eccentricity is {self.eccentricity:g} (its "
                             f"equations depend on time: integrate it, or use tumble.theory.eigenvalues_at)")

    def following_velocity(self, attitude):
        """The angular velocity ``w = −n c2`` (rad/s, body frame) of a body at ``attitude`` that does not turn
        relative to the orbit frame (``w_r = 0``), shape (..., 3), for unit quaternions of shape (..., 4)."""
        q = finite_array(attitude, "attitude")
        if q.ndim == 0 or q.shape[-1] != 4:
            raise ValueError(f"attitude must have shape (..., 4) (a quaternion, scalar first), got shape {q.shape}")
        return -self.orbit_rate * _rows_of_attitude(q)[0]

    def tangent_jacobian(self, state):
        """The Jacobian in ``(w, θ)``, shape (..., 6, 6) (1/s): ``θ`` the attitude error in the body frame,
        ``q_perturbed = q ⊗ (1, θ/2)`` to first order (rad).

        ``δc = c × θ`` for ``c = c2, c3`` and ``θ' = δw_r − w_r × θ``, so: ``∂w'/∂w = I⁻¹ ([Iw]× − [w]× I)``,
        ``∂w'/∂θ = 3 n² I⁻¹ ([c3]× I − [I c3]×) [c3]×``, ``∂θ'/∂w = 1``, ``∂θ'/∂θ = n [c2]× − [w_r]×``. Its eigenvalues
        at the equilibrium are those of the 7×7 :meth:`jacobian` without the constraint's 0: at the equilibrium
        ``θ = 2 (q1, q2, q3)``, and this is the lower-right 6×6 block of the 7×7 Jacobian in ``(w, q1, q2, q3)``
        with the ``q`` columns doubled and rows halved.
        """
        self._circular("linear theory in the attitude error")
        y, w, _, c2, c3, w_r, _, strength = self._parts(state)
        jac = np.zeros(y.shape[:-1] + (6, 6), dtype=np.result_type(y, float))
        jac[..., :3, :3] = base.euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = self._torque_jacobian(c3, strength) @ base.cross_matrix(c3)
        jac[..., 3:, :3] = np.eye(3)
        jac[..., 3:, 3:] = self.orbit_rate * base.cross_matrix(c2) - base.cross_matrix(w_r)
        return jac

    def invariants(self, state):
        """``jacobi_integral`` (J) and ``quaternion_squared`` ``|q|²`` (1), each of shape (...).

        ``jacobi_integral = ½ w_r·I w_r + (3/2) n² c3·I c3 − ½ n² c2·I c2`` with ``w_r = w + n c2``. In an eccentric
        orbit only ``quaternion_squared``: nothing else is conserved.
        """
        _, _, q, c2, c3, w_r, _, _ = self._parts(state)
        if self.eccentricity != 0.0:
            return {"quaternion_squared": np.sum(q * q, axis=-1)}
        n2 = self.orbit_rate ** 2
        moments = self.moments
        jacobi = 0.5 * np.sum(moments * w_r * w_r, axis=-1) + 1.5 * n2 * np.sum(moments * c3 * c3, axis=-1) \
            - 0.5 * n2 * np.sum(moments * c2 * c2, axis=-1)
        return {"jacobi_integral": jacobi, "quaternion_squared": np.sum(q * q, axis=-1)}

    def equilibrium(self, axis=2, spin=1.0):
        """The orbit-following attitude: ``w = (0, −n, 0)``, ``q = (1, 0, 0, 0)``; shape ``spin.shape + (7,)``.

        A study's ``spin.axis`` and ``spin.rate`` are not used (DESIGN.md): the equilibrium is fixed by the orbit.
        ``axis`` must still be 1, 2 or 3 and ``spin`` finite (its shape gives the leading shape, as for the other
        models, so that vectorised callers work unchanged).

        Raises
        ------
        ValueError
            ``axis`` not 1, 2 or 3; ``spin`` not finite; an eccentric orbit (no attitude is an equilibrium there).
        """
        self._circular("an equilibrium")
        base.one_axis(axis)
        state = base.spin_state(7, 1, finite_array(spin, "spin") * 0.0 - self.orbit_rate)
        state[..., 3] = 1.0
        return state

    def transverse(self, axis=2, spin=1.0):
        """``(w1, w2 + n, w3, q1, q2, q3)`` with weights ``(1, 1, 1, 4n², 4n², 4n²)`` (every term in (rad/s)²).

        The perturbation is ``w`` relative to ``(0, −n, 0)`` (``centre`` holds ``w2``'s ``−n``) and the attitude
        error ``θ ≈ 2 (q1, q2, q3)`` (rad) of the body relative to the orbit frame, each angle weighted by ``n²``
        (an error ``θ`` in the orbit's own time scale). The phase fit follows roll and yaw, ``(q1, q3)``.
        ``axis`` and ``spin`` are not used (checked as by :meth:`equilibrium`).
        """
        self.equilibrium(axis, spin)
        n2 = self.orbit_rate ** 2
        return base.Transverse(np.array([0, 1, 2, 4, 5, 6], dtype=np.intp),
                          np.array([1.0, 1.0, 1.0, 4 * n2, 4 * n2, 4 * n2]), np.array([4, 6], dtype=np.intp),
                          np.array([0.0, -self.orbit_rate, 0.0, 0.0, 0.0, 0.0]))

    def steady_spin(self, spin):
        """The orbit rate ``n`` (rad/s): the equilibrium turns with the orbit frame whatever ``spin`` says."""
        return self.orbit_rate

    def mode_space(self, axis=2, spin=1.0):
        """``w`` and the attitude error ``θ = 2 (q1, q2, q3)``: the whole 6 x 6 tangent Jacobian (:meth:`Model.mode_space`)."""
        columns, _, _, weights = super().mode_space(axis, spin)
        return columns, np.arange(6), np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0]), weights

    def perturbed(self, draws, axis, spin):
        """States near the orbit-following equilibrium: the attitude ``draws.attitudes()`` (tilted about a random axis),
        ``w`` the orbit frame's rate there (:meth:`following_velocity`: the body does not turn relative to the orbit
        frame at first). ``axis`` and ``spin`` are not used (checked as by :meth:`equilibrium`)."""
        self.equilibrium(axis, spin)
        q = draws.attitudes()
        return np.concatenate([self.following_velocity(q), q], axis=-1)
