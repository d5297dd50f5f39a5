"""A satellite under the gravity-gradient torque, in a circular or an elliptic orbit.

State: the body-frame angular velocity ``w1 w2 w3`` (rad/s, inertial) and the attitude ``q0 q1 q2 q3`` relative to
the orbit frame (unit quaternion, scalar first; orbit axes: 1 roll along track, 2 pitch = negative orbit normal, 3
yaw = nadir). ``c2``, ``c3`` are the orbit's pitch and nadir axes in the body frame (rows of ``C(q)``). Parameters:
the orbit's mean motion ``n`` (rad/s) and eccentricity ``e`` in [0, 1), perigee at ``t = 0``. With the true anomaly
``ν(t)`` and the radius ``r`` (Kepler's equation ``E − e sin E = n t``; ``a/r = 1/(1 − e cos E)``), the orbit frame
turns at ``ν' = n sqrt(1 − e²) (a/r)²`` and the gradient's strength is ``3 μ/r³ = 3 n² (a/r)³`` (Hughes,
*Spacecraft Attitude Dynamics*, §8.1)::

    I w' = (I w) × w + 3 n² (a/r)³ (c3 × I c3),    q' = ½ q ⊗ (0, w + ν' c2)

In a circular orbit (``e = 0``: ``ν' = n``, ``a/r = 1``, the equations of the circular model to the last bit) the
motion conserves the Jacobi integral ``½ w_r·I w_r + (3/2) n² c3·I c3 − ½ n² c2·I c2`` (``w_r = w + n c2``); an
eccentric orbit makes the torque periodic in time and conserves none (only ``|q|²``). The quaternion is put back
on the unit sphere after every step (:func:`project`, called by the generated block loop): the right-hand side
keeps ``|q|`` only exactly, a Runge–Kutta step only to its order, and ``c2``, ``c3`` are a rotation's only on the
unit sphere.

The system in one module, as :mod:`tumble.physics.models.gyrostat`: its per-sample equations and the model with
its scenes (Hughes, *Spacecraft Attitude Dynamics*, §8.1-8.3).
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

__all__ = ["KEPLER_ITERATIONS", "Constants", "GravityGradient", "constants", "forcing", "invariants", "orbit",
           "project", "rate", "rate_forced", "tangent", "tangent_forced"]


#: Newton iterations at most for Kepler's equation (from Danby's start ``E = M + 0.85 e sign(sin M)``): 8 reach
#: round-off for every mean anomaly up to e = 0.99 (4e-16 of ``M``; 6 suffice to e = 0.9), more near e = 1.
KEPLER_ITERATIONS = 64

_TWO_PI = 2.0 * math.pi


#: The rigid body's fields, the mean motion ``n`` (rad/s), ``n²``, ``3 n²`` (1/s²), the eccentricity ``e`` and
#: ``sqrt(1 − e²)``.
Constants = namedtuple("Constants", (*registry.RIGID_BODY, "n", "n2", "three_n2", "e", "root"))


def constants(moments, orbit_rate, eccentricity=0.0):
    """:class:`Constants` of moments ``(I1, I2, I3)`` (kg m²), the orbit's mean motion (rad/s) and eccentricity."""
    n, e = float(orbit_rate), float(eccentricity)
    return Constants(*registry.rigid_body(moments), n, n * n, 3 * (n * n), e, math.sqrt(1.0 - e * e))


def orbit(t, c):
    """``(ν', 3 μ/r³)`` at time ``t`` (s from perigee): the orbit frame's rate (rad/s) and the gradient's strength
    (1/s²); ``(n, 3 n²)`` exactly in a circular orbit."""
    if c.e == 0.0:
        return c.n, c.three_n2
    mean = c.n * t
    mean -= _TWO_PI * math.floor(mean / _TWO_PI + 0.5)  # in [-pi, pi)
    big = mean + 0.85 * c.e * (1.0 if math.sin(mean) >= 0.0 else -1.0)
    for _ in range(KEPLER_ITERATIONS):
        step = (big - c.e * math.sin(big) - mean) / (1.0 - c.e * math.cos(big))
        big -= step
        if abs(step) <= 1e-15 * (1.0 + abs(big)):
            break
    a_r = 1.0 / (1.0 - c.e * math.cos(big))
    return c.n * c.root * a_r * a_r, c.three_n2 * a_r * a_r * a_r


def _orbit_rows(q0, q1, q2, q3):
    """Rows ``c2`` (orbit normal, negative) and ``c3`` (nadir) of the orbit frame in the body frame, from the attitude
    quaternion: ``(c21, c22, c23, c31, c32, c33)``."""
    return (2.0 * (q1 * q2 + q0 * q3), 1.0 - 2.0 * (q1 * q1 + q3 * q3), 2.0 * (q2 * q3 - q0 * q1),
            2.0 * (q1 * q3 - q0 * q2), 2.0 * (q2 * q3 + q0 * q1), 1.0 - 2.0 * (q1 * q1 + q2 * q2))


def forcing(t, c):
    """What the rate takes from time: :func:`orbit`. The generated steps evaluate it once per stage for a whole block
    of samples (it is the same for every sample), outside the loop over them, so that the loop keeps no branch and
    vectorises."""
    return orbit(t, c)


def rate(t, w1, w2, w3, q0, q1, q2, q3, c):
    # size: the time, the state's seven components (scalars: the generated steps keep them in registers), the constants
    """``(w', q')`` at time ``t``: rad/s², then 1/s."""
    return rate_forced(forcing(t, c), w1, w2, w3, q0, q1, q2, q3, c)


def rate_forced(f, w1, w2, w3, q0, q1, q2, q3, c):
    # size: the forcing, the state's seven components, the constants
    """:func:`rate` with the orbit's ``f = (ν', 3 μ/r³)`` given (:func:`forcing`)."""
    nu_dot, strength = f
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + nu_dot * c21, w2 + nu_dot * c22, w3 + nu_dot * c23  # w_r, relative to the orbit frame
    return (c.a1 * (w2 * w3 - strength * (c32 * c33)),
            c.a2 * (w3 * w1 - strength * (c33 * c31)),
            c.a3 * (w1 * w2 - strength * (c31 * c32)),
            0.5 * (-q1 * v1 - q2 * v2 - q3 * v3),
            0.5 * (q0 * v1 - q3 * v2 + q2 * v3),
            0.5 * (q3 * v1 + q0 * v2 - q1 * v3),
            0.5 * (-q2 * v1 + q1 * v2 + q0 * v3))


def tangent(t, w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c):
    # size: the time, the state's seven components, the tangent's seven (v along w, u along q), the constants
    """The tangent flow ``J(y) δ`` along ``δ = (v, u)`` (``v`` along ``w``, ``u`` along ``q``): the exact derivative
    of :func:`rate` (the attitude rows are quadratic in ``q``)."""
    return tangent_forced(forcing(t, c), w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c)


def tangent_forced(f, w1, w2, w3, q0, q1, q2, q3, v1, v2, v3, u0, u1, u2, u3, c):
    # size: the forcing, the state's seven components, the tangent's seven, the constants
    """:func:`tangent` with the orbit's ``f = (ν', 3 μ/r³)`` given (:func:`forcing`)."""
    nu_dot, strength = f
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    # derivatives of the rows along u
    d21 = 2.0 * (u1 * q2 + q1 * u2 + u0 * q3 + q0 * u3)
    d22 = -4.0 * (q1 * u1 + q3 * u3)
    d23 = 2.0 * (u2 * q3 + q2 * u3 - u0 * q1 - q0 * u1)
    d31 = 2.0 * (u1 * q3 + q1 * u3 - u0 * q2 - q0 * u2)
    d32 = 2.0 * (u2 * q3 + q2 * u3 + u0 * q1 + q0 * u1)
    d33 = -4.0 * (q1 * u1 + q2 * u2)
    r1, r2, r3 = w1 + nu_dot * c21, w2 + nu_dot * c22, w3 + nu_dot * c23
    s1, s2, s3 = v1 + nu_dot * d21, v2 + nu_dot * d22, v3 + nu_dot * d23  # derivative of w_r
    return (c.a1 * ((v2 * w3 + w2 * v3) - strength * (d32 * c33 + c32 * d33)),
            c.a2 * ((v3 * w1 + w3 * v1) - strength * (d33 * c31 + c33 * d31)),
            c.a3 * ((v1 * w2 + w1 * v2) - strength * (d31 * c32 + c31 * d32)),
            0.5 * ((-u1 * r1 - u2 * r2 - u3 * r3) + (-q1 * s1 - q2 * s2 - q3 * s3)),
            0.5 * ((u0 * r1 - u3 * r2 + u2 * r3) + (q0 * s1 - q3 * s2 + q2 * s3)),
            0.5 * ((u3 * r1 + u0 * r2 - u1 * r3) + (q3 * s1 + q0 * s2 - q1 * s3)),
            0.5 * ((-u2 * r1 + u1 * r2 + u0 * r3) + (-q2 * s1 + q1 * s2 + q0 * s3)))


def project(w1, w2, w3, q0, q1, q2, q3):
    """The state with its quaternion divided by its norm (after each step; ``w`` unchanged)."""
    norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    return w1, w2, w3, q0 / norm, q1 / norm, q2 / norm, q3 / norm


def invariants(w1, w2, w3, q0, q1, q2, q3, c):
    """``(Jacobi integral (J), |q|², 0)`` and their scales ``(T_r + V_g + V_c, |q|², 1)``; in an eccentric orbit the
    Jacobi integral is no invariant: ``(0, |q|², 0)``.

    The Jacobi integral ``T_r + V_g − V_c`` (``T_r = ½ w_r·I w_r``, ``V_g = (3/2) n² c3·I c3``, ``V_c = ½ n²
    c2·I c2``) may vanish, so its scale is the sum of the three terms' magnitudes; ``|q|²`` is its own scale.
    """
    c21, c22, c23, c31, c32, c33 = _orbit_rows(q0, q1, q2, q3)
    v1, v2, v3 = w1 + c.n * c21, w2 + c.n * c22, w3 + c.n * c23
    kinetic = 0.5 * (c.i1 * v1 * v1 + c.i2 * v2 * v2 + c.i3 * v3 * v3)
    gravity = 1.5 * c.n2 * (c.i1 * c31 * c31 + c.i2 * c32 * c32 + c.i3 * c33 * c33)
    centrifugal = 0.5 * c.n2 * (c.i1 * c21 * c21 + c.i2 * c22 * c22 + c.i3 * c23 * c23)
    unit = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    jacobi = kinetic + gravity - centrifugal if c.e == 0.0 else 0.0
    return jacobi, unit, 0.0, kinetic + gravity + centrifugal, unit, 1.0


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

    See Also
    --------
    tumble.theory.gravity_gradient_stable : Whether the orbit-following attitude is stable.
    tumble.theory.gravity_gradient_roll_yaw : Its roll-yaw exponents.

    Examples
    --------
    The equilibrium turns once per orbit about the pitch axis:

    >>> import tumble
    >>> sat = tumble.models.GravityGradient((2.0, 2.5, 1.0), orbit_rate=1e-3)
    >>> sat.spec.state
    ('w1', 'w2', 'w3', 'q0', 'q1', 'q2', 'q3')
    >>> sat.equilibrium(2, 0.0)
    array([ 0.   , -0.001,  0.   ,  1.   ,  0.   ,  0.   ,  0.   ])
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
        and the gradient's strength (1/s²), from Kepler's equation (:func:`orbit`); ``(n, 3 n²)`` in a circular
        orbit."""
        t = np.asarray(t, dtype=float)
        c = self.constants
        pairs = np.array([orbit(x, c) for x in t.ravel().tolist()]).reshape(t.shape + (2,))
        return pairs[..., 0], pairs[..., 1]

    @property
    def tangent_size(self):
        """6: ``w`` and the attitude error ``θ`` (rad) of :meth:`tangent_jacobian`."""
        return 6

    def _parts(self, state):
        """``(y, w, c2, c3, w_r)`` of states (..., 7) in a circular orbit: the rows ``c2``, ``c3`` (..., 3) and ``w_r =
        w + n c2``."""
        y = self._state(state)
        rows = _orbit_rows(*(y[..., 3 + i] for i in range(4)))
        c2, c3 = np.stack(rows[:3], axis=-1), np.stack(rows[3:], axis=-1)
        w = y[..., :3]
        return y, w, c2, c3, w + self.orbit_rate * c2

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
        return -self.orbit_rate * np.stack(_orbit_rows(*(q[..., i] for i in range(4)))[:3], axis=-1)

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
        y, w, c2, c3, w_r = self._parts(state)
        strength = 3 * self.orbit_rate ** 2
        torque = (strength / self.moments[:, None]) * (base.cross_matrix(c3) * self.moments
                                                       - base.cross_matrix(self.moments * c3))
        jac = np.zeros(y.shape[:-1] + (6, 6), dtype=np.result_type(y, float))
        jac[..., :3, :3] = base.euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = torque @ base.cross_matrix(c3)
        jac[..., 3:, :3] = np.eye(3)
        jac[..., 3:, 3:] = self.orbit_rate * base.cross_matrix(c2) - base.cross_matrix(w_r)
        return jac

    def invariants(self, state):
        """``jacobi_integral`` (J) and ``quaternion_squared`` ``|q|²`` (1), each of shape (...) (:func:`invariants`);
        in an eccentric orbit only ``quaternion_squared``: nothing else is conserved."""
        found = super().invariants(state)
        if self.eccentricity != 0.0:
            del found[self.spec.invariants[0]]
        return found

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
