"""Models: the systems tumble studies, as right-hand sides with analytic Jacobians (numpy).

A model is a frozen record of a body's principal moments (kg m², body frame = principal axes) and the model's
parameters, validated once when it is built. Its state is a flat vector ``y`` of :attr:`Model.state_size`
components; every function here is vectorised over leading axes, ``y`` of shape ``(..., n)``:

* :meth:`Model.rhs` ``y' = f(y)``, :meth:`Model.jacobian` ``∂f/∂y`` (analytic, ``(..., n, n)``);
* :meth:`Model.invariants`: the quantities the motion conserves, by name (``registry.MODELS``);
* :meth:`Model.equilibrium`: the steady spin about a principal axis, the point linear theory expands about
  (:func:`tumble.physics.theory.linear` of a model: eigenvalues of the Jacobian there);
* :meth:`Model.transverse`: which components of a state measure a perturbation of that spin, and their
  weights, as plain arrays (a kernel or an estimator takes them as columns and numbers).

State layout (``registry.MODELS``, ``registry.STATE_BLOCKS``): the first three components are always the
body-frame angular velocity ``w`` (rad/s); the model's own blocks follow, each named by the first letter of its
components: ``g`` the unit vector pointing up in the body frame (heavy top), ``q`` an attitude quaternion,
scalar first (gravity gradient), ``s`` an internal body's angular velocity (damper). A kernel finds a block by
the offsets of ``registry.state_blocks(kind)``. The gravity gradient and the damper have kernels
(``tumble.kernels.MODEL_CODES``) but no studies yet (``registry.MODELS``' ``implemented`` is False: the studies
refuse them; ``physics`` is True).

Models (Landau & Lifshitz, *Mechanics*, §35-§37; Wittenburg, *Dynamics of Multibody Systems*, §3.6 for the
gyrostat; Arnold, *Mathematical Methods of Classical Mechanics*, §30 and Goldstein §5.7 for the heavy top):

* :class:`FreeBody`: ``I w' = (I w) × w``.
* :class:`Gyrostat`: a rotor of constant angular momentum ``h`` relative to the body (N m s, body frame),
  ``L = I w + h``, ``I w' = (I w + h) × w``.
* :class:`HeavyTop` (Euler-Poisson): moments about the fixed pivot, centre of mass on body axis 3 at distance
  ``l`` above the pivot, ``mgl = M g l`` (N m); ``g`` the unit up vector in the body frame:
  ``I w' = (I w) × w + mgl (g × e3)``, ``g' = g × w``. The torque ``r × F = l e3 × (−M g g) = mgl (g × e3)``
  tips the top away from upright: a top at rest upright falls at the rate ``sqrt(mgl / I1)`` (``I1 <= I2``).
* :class:`GravityGradient`: a satellite in a circular orbit of rate ``n``; ``w`` and the attitude ``q`` relative
  to the orbit frame (roll, pitch, yaw): ``I w' = (I w) × w + 3 n² (c3 × I c3)``, ``q' = ½ q ⊗ (0, w + n c2)``.
  Linear theory in a 3-angle attitude error (:meth:`Model.tangent_jacobian`), not the quaternion's 4 components.
* :class:`Damper` (Kane's spherical damper): ``I w' = (I w) × w + c (s − w)``, ``J (s' + w × s) = −c (s − w)``;
  ``|I w + J s|`` is kept, the energy decays.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from .. import registry
from .bodies import finite_array, one_body

__all__ = ["CLASSES", "IMPLEMENTED", "Damper", "FreeBody", "GravityGradient", "Gyrostat", "HeavyTop", "Model", "Transverse",
           "from_kind"]

#: A rotor component across the spin axis smaller than this fraction of |rotor| counts as 0 (equilibrium check).
ROTOR_RTOL = 1e-12


class Transverse(NamedTuple):
    """How a perturbation of a steady spin is measured, as plain arrays (for kernels and estimators).

    The perturbation's norm is ``sqrt(sum(weights * (y[..., columns] - centre) ** 2))``, ``centre`` the
    equilibrium's value of the listed components (the model kernels subtract the whole equilibrium state,
    ``y_eq``, the same thing). ``centre`` is None, i.e. 0, for the free body, the gyrostat and the heavy top: there
    the norm is ``sqrt(sum(weights * y[..., columns] ** 2))``; the gravity gradient's pitch rate ``w2`` has
    ``−n`` at its equilibrium. ``phase`` is the pair of components whose angle
    ``atan2(sqrt(wc) y[c], sqrt(wb) y[b])`` a phase fit follows (``wb, wc`` their weights; both 0 at the
    equilibrium).
    """

    columns: np.ndarray  # intp, shape (k,): state components of the norm
    weights: np.ndarray  # float64, shape (..., k): weight of each squared component (units: (rad/s)² / unit²)
    phase: np.ndarray  # intp, shape (2,): the pair of the phase fit, in the order (b, c)
    centre: np.ndarray | None = None  # float64, shape (k,): the equilibrium's value of each column (None: all 0)


def _cross_matrix(v):
    """``[v]×`` of shape (..., 3, 3) for ``v`` of shape (..., 3): ``[v]× @ u = v × u`` (entries filled in place: a
    scene's linear theory builds a dozen of these, and nested ``np.stack`` calls cost several times the arithmetic)."""
    v = np.asarray(v)
    out = np.zeros(v.shape[:-1] + (3, 3), dtype=v.dtype)
    v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -v3, v2
    out[..., 1, 0], out[..., 1, 2] = v3, -v1
    out[..., 2, 0], out[..., 2, 1] = -v2, v1
    return out


def _one_axis(axis):
    """A 1-based principal axis (one integer) as a 0-based int; ValueError naming ``axis`` otherwise."""
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (one integer), got {axis!r}")
    return int(axis) - 1


def _parameter(key, value):
    """A model parameter checked against its row of ``registry.MODEL_PARAMETERS`` (size, finite, > 0)."""
    spec = registry.model_parameter(key)
    arr = finite_array(value, key)
    shape = () if spec.size == 1 else (spec.size,)
    if arr.shape != shape:
        what = "a number" if spec.size == 1 else f"a {spec.size}-vector"
        raise ValueError(f"{key} must be {what} ({spec.units}), got shape {arr.shape}")
    if spec.positive and not arr > 0:
        raise ValueError(f"{key} must be > 0 {spec.units}, got {float(arr)!r}")
    arr = arr.copy()
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True, eq=False)
class Model:
    """Base of the models: principal moments and what every model offers (see the module docstring).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments ``(I1, I2, I3)``, kg m², validated as :func:`tumble.physics.bodies.validate_moments`
        does (finite, > 0, triangle inequality). Stored as a read-only float64 array.
    """

    moments: np.ndarray
    kind: ClassVar[str] = ""
    #: Components of the state: the length of the kind's ``registry.MODELS`` row's ``state`` (set for each class).
    state_size: ClassVar[int] = 0
    #: Parameters of the Python API beyond the study keys of ``registry.MODELS`` (the heavy top's ``centre``, the
    #: gravity gradient's ``eccentricity``), in the constructor's order after them.
    extras: ClassVar[tuple] = ()

    # --- what the model says about its scenes (read by the engine's sampler, the scene planner and the study checks,
    # so that none of them switches on a kind's name) ------------------------------------------------------------
    #: The principal axes (1-based) it has a steady spin about, and why when not all three (a study's message).
    spin_axes: ClassVar[tuple] = (1, 2, 3)
    spin_axes_reason: ClassVar[str] = ""
    #: The parameter that fixes its steady state in place of a study's spin (axis and rate), and why ("": the spin
    #: sets it). See :meth:`steady_spin`.
    equilibrium_parameter: ClassVar[str] = ""
    equilibrium_reason: ClassVar[str] = ""
    #: Why the Lie–Poisson splittings do not step it ("": they do; ``registry.LIE_POISSON_MODELS``).
    not_lie_poisson: ClassVar[str] = ""
    #: Measured in the modal coordinate of its measured eigenvalue (:meth:`mode_space`,
    #: :func:`tumble.measure.model_scenes.mode`): no fixed weights of its transverse components make its linear
    #: motion one circle or one exponential. False: the weighted :meth:`transverse_norm` and its phase pair.
    modal: ClassVar[bool] = False
    #: A scene's tilt of the spin as a fraction of its amplitude (``perturbation.amplitude``), which tilts the
    #: model's own block where :meth:`perturbed` draws one (the heavy top's up vector).
    spin_tilt: ClassVar[float] = 1.0
    #: Its step must resolve the spin itself, not only the linearisation's eigenvalues (the heavy top's up vector
    #: turns at ``w3`` in the body frame; a gyrostat's spin is no time scale of its body-frame motion).
    resolves_spin: ClassVar[bool] = False
    #: Near a stability threshold its linear regime of growth ends sooner (the second-order change of the spin shifts
    #: the rate): a growth scene's saturation is scaled by ``rate_theory / |spin|`` (:mod:`tumble.measure.model_scenes`).
    saturates_near_threshold: ClassVar[bool] = True

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.kind:
            cls.state_size = len(registry.model_kind(cls.kind).state)

    def __post_init__(self):
        moments = one_body(self.moments).copy()
        moments.setflags(write=False)
        object.__setattr__(self, "moments", moments)
        for key in self.spec.parameters:  # each study key checked against its registry row: a number or a vector
            value = _parameter(key, getattr(self, key))
            object.__setattr__(self, key, float(value) if value.ndim == 0 else value)

    # --- what the registry says -------------------------------------------------------------------------------
    @property
    def spec(self):
        """The model's row of ``registry.MODELS`` (name, parameters, state components, invariants)."""
        return registry.model_kind(self.kind)

    @property
    def parameters(self):
        """``{name: value}`` of the model's parameters: its study keys (``registry.MODEL_PARAMETERS``), then
        :attr:`extras`, in the constructor's order."""
        return {key: getattr(self, key) for key in (*self.spec.parameters, *self.extras)}

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self):
        return hash(self._key())

    def __reduce__(self):  # rebuilt through the constructor: checked again, arrays read-only again
        return type(self), (self.moments, *self.parameters.values())

    def _key(self):
        return (self.kind, self.moments.tobytes(), *(np.asarray(v).tobytes() for v in self.parameters.values()))

    # --- states ---------------------------------------------------------------------------------------------
    def _state(self, state, name="state"):
        """``state`` as an array of shape (..., n): float64, or complex as given (complex-step derivatives)."""
        arr = np.asarray(state)
        if arr.dtype.kind == "f":
            arr = arr.astype(float, copy=False)
        elif arr.dtype.kind != "c":
            arr = finite_array(arr, name)
        if arr.ndim == 0 or arr.shape[-1] != self.state_size:
            raise ValueError(f"{name} of a {self.kind} model must have shape (..., {self.state_size}) "
                             f"({', '.join(self.spec.state)}), got shape {arr.shape}")
        return arr

    def angular_velocity(self, momentum):
        """Body-frame angular velocity with the given angular momentum: ``w = I⁻¹ (L − h)``.

        ``h`` is the gyrostat's rotor (0 for the other models; the heavy top's ``L`` is about the pivot).

        Parameters
        ----------
        momentum : array_like, shape (..., 3)
            Angular momentum ``L`` in the body frame, N m s (kg m²/s).

        Returns
        -------
        ndarray, shape (..., 3)
            ``w``, rad/s.

        Raises
        ------
        ValueError
            ``momentum`` not finite or not of shape (..., 3).
        """
        m = finite_array(momentum, "momentum")
        if m.ndim == 0 or m.shape[-1] != 3:
            raise ValueError(f"momentum must have shape (..., 3) (body frame, N m s), got shape {m.shape}")
        return (m - self._rotor()) / self.moments

    def _rotor(self):
        return np.zeros(3)

    def transverse_norm(self, state, axis, spin=1.0):
        """Norm of the perturbation of the steady spin about ``axis`` in ``state`` (see :class:`Transverse`).

        Parameters
        ----------
        state : array_like, shape (..., n)
        axis : {1, 2, 3}
        spin : float or array_like, broadcastable to (...)
            The steady spin, rad/s (the gyrostat's weights depend on it).

        Returns
        -------
        ndarray, shape (...)
            rad/s.
        """
        state = self._state(state)
        t = self.transverse(axis, spin)
        part = state[..., t.columns] if t.centre is None else state[..., t.columns] - t.centre
        return np.sqrt(np.sum(t.weights * part ** 2, axis=-1))

    @property
    def tangent_size(self):
        """Size of the coordinates of :meth:`tangent_jacobian`: :attr:`state_size`, less one per unit quaternion."""
        return self.state_size

    def tangent_jacobian(self, state):
        """The Jacobian in the model's tangent coordinates, shape (..., m, m), ``m = tangent_size``: the one linear
        theory takes the eigenvalues of (:func:`tumble.physics.theory.eigenvalues`).

        For the models whose state is free (no constraint) it is :meth:`jacobian` itself. A model with a unit
        quaternion in its state (the gravity gradient) linearises in a 3-parameter attitude error instead: the
        quaternion's norm is a constraint, and the 4 components' Jacobian carries an eigenvalue 0 along it that
        is no motion of the body.
        """
        return self.jacobian(state)

    # --- its scenes ------------------------------------------------------------------------------------------------
    def steady_spin(self, spin):
        """The spin rate (rad/s) of the steady state a scene of spin ``spin`` measures: ``spin`` itself, unless a
        parameter fixes the equilibrium (:attr:`equilibrium_parameter`)."""
        return spin

    def mode_space(self, axis, spin=1.0):
        """``(columns, rows, factor, weights)`` of the transverse motion a :attr:`modal` model is measured in: the
        state's columns (:meth:`transverse`), the rows of :meth:`tangent_jacobian` they are (``factor`` times the
        column less the equilibrium's value), and the transverse norm's weights on the columns. The columns must be
        invariant under the linearised motion. By default the transverse columns are their own tangent coordinates.
        """
        transverse = self.transverse(axis, spin)
        columns = np.asarray(transverse.columns)
        return columns, columns, np.ones(len(columns)), np.asarray(transverse.weights, dtype=float)

    def perturbed(self, draws, axis, spin):
        """States of shape (N, n) near the steady spin about ``axis``, from a sampler's random draws
        (:func:`tumble.engine.sampling.perturbed_states`): ``w`` is ``draws.spins()`` (the steady spin tilted, N x 3,
        rad/s), the model's own components the equilibrium's; a model whose own block is perturbed too takes it from
        ``draws.up()`` (a unit vector near ``e3``, N x 3) or ``draws.attitudes()`` (unit quaternions near ``(1, 0, 0,
        0)``, N x 4), or sets it from ``w``.

        Raises
        ------
        ValueError
            An axis the model has no steady spin about; any argument the draws refuse.
        """
        equilibrium = self.equilibrium(axis, 1.0)
        w = draws.spins()
        states = np.empty((len(w), self.state_size))
        states[:] = equilibrium
        states[:, :3] = w
        return states

    def coordinates(self, axis):
        """``{key: value}`` of the model's numeric study parameters as a scene record's scalar coordinates (a
        vector parameter as its component along ``axis``, 1-based; the others as they are)."""
        out = {}
        for key in self.spec.parameters:
            value = getattr(self, key)
            out[key] = float(value) if np.ndim(value) == 0 else float(value[axis - 1])
        return out

    # Each model defines: rhs, jacobian, invariants, equilibrium, transverse.
    def rhs(self, state):  # pragma: no cover - abstract
        """The time derivative of ``state`` (shape (..., n), n = :attr:`state_size`), same shape; each model
        says its units."""
        raise NotImplementedError

    def jacobian(self, state):  # pragma: no cover - abstract
        """``∂ rhs / ∂ state`` at ``state`` (shape (..., n)): shape (..., n, n)."""
        raise NotImplementedError

    def invariants(self, state):  # pragma: no cover - abstract
        """The conserved quantities of ``state`` (shape (..., n)): ``{name: array of shape (...)}``, named as in
        ``registry.MODELS``."""
        raise NotImplementedError

    def equilibrium(self, axis, spin=1.0):  # pragma: no cover - abstract
        """The steady state of a spin ``spin`` (rad/s) about body ``axis`` (1, 2 or 3): shape (..., n)."""
        raise NotImplementedError

    def transverse(self, axis, spin=1.0):  # pragma: no cover - abstract
        """The :class:`Transverse` description of a perturbation of the steady spin about ``axis``: the state
        columns across it and their weights (:meth:`transverse_norm`)."""
        raise NotImplementedError


_CYCLIC = ((0, 1, 2), (1, 2, 0), (2, 0, 1))


def _euler_rhs(moments, w, h):
    """``I⁻¹ ((I w + h) × w)`` for ``w`` (..., 3), ``h`` (3,): ``w_i' = ((I_j − I_k) w_j w_k + h_j w_k − h_k w_j) / I_i``.

    Written with the differences of the moments, as Euler's equations are: ``I_j − I_k`` is exact for close moments
    (Sterbenz), where ``I_j w_j w_k − I_k w_k w_j`` would lose their common digits (a nearly symmetric body).
    """
    h = np.broadcast_to(np.asarray(h, dtype=float), (3,))
    out = np.empty(w.shape, dtype=np.result_type(w, float))
    for i, j, k in _CYCLIC:
        wj, wk = w[..., j], w[..., k]
        out[..., i] = ((moments[j] - moments[k]) * wj * wk + h[j] * wk - h[k] * wj) / moments[i]
    return out


def _euler_jacobian(moments, w, h):
    """``∂/∂w`` of :func:`_euler_rhs`, shape (..., 3, 3): ``I⁻¹ ([I w + h]× − [w]× I)``, entry by entry from the
    differences of the moments (as :func:`_euler_rhs`, so that linear theory of a nearly symmetric body keeps its
    digits): ``J_ij = ((I_j − I_k) w_k − h_k) / I_i``, ``J_ik = ((I_j − I_k) w_j + h_j) / I_i`` for ``(i, j, k)``
    cyclic, ``J_ii = 0``."""
    h = np.broadcast_to(np.asarray(h, dtype=float), (3,))
    jac = np.zeros(w.shape + (3,), dtype=np.result_type(w, float))
    for i, j, k in _CYCLIC:
        d = moments[j] - moments[k]
        jac[..., i, j] = (d * w[..., k] - h[k]) / moments[i]
        jac[..., i, k] = (d * w[..., j] + h[j]) / moments[i]
    return jac


def _spin_state(size, k, spin):
    """States of shape (..., size), zero but for the spin (..., rad/s) in component ``k``."""
    spin = finite_array(spin, "spin")
    state = np.zeros(spin.shape + (size,))
    state[..., k] = spin
    return state


def _circular_weights(moments, k, spin, h):
    """Weights ``(g_b, g_c)`` that make the linearised transverse motion about axis ``k`` (0-based) circular.

    Linearised about ``w = W e_a`` with the rotor along ``a``, ``k_b w_b² + k_c w_c²`` is conserved with
    ``k_i = I_i ((I_a − I_i) W + h_a)`` (for ``h = 0`` the free body's ``I_i (I_a − I_i)`` times ``W``, as
    ``measure.estimators.invariant_weights``); ``g_b = sqrt|k_b / k_c|``, ``g_c = 1 / g_b``. Degenerate
    (``k_b`` or ``k_c`` within 1e-12 of its scale): 1, 1.
    """
    b, c = (k + 1) % 3, (k + 2) % 3
    spin = np.asarray(spin, dtype=float)
    p_b = (moments[k] - moments[b]) * spin + h
    p_c = (moments[k] - moments[c]) * spin + h
    k_b, k_c = moments[b] * p_b, moments[c] * p_c
    scale = moments.max() * (moments.max() * np.abs(spin) + np.abs(h))
    ok = np.minimum(np.abs(k_b), np.abs(k_c)) > 1e-12 * scale
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(ok, np.sqrt(np.abs(k_b / k_c)), 1.0)
    return np.stack([ratio, 1.0 / ratio], axis=-1)


@dataclass(frozen=True, eq=False)
class FreeBody(Model):
    """The torque-free rigid body: ``I w' = (I w) × w`` (Landau & Lifshitz §36). State ``w`` (3), rad/s.

    Invariants: ``energy`` ``½ w·Iw`` (J) and ``momentum_squared`` ``|I w|²`` ((N m s)²).

    Examples
    --------
    >>> FreeBody((1.0, 2.0, 3.0)).rhs([0.0, 1.0, 0.0])
    array([0., 0., 0.])
    """

    kind: ClassVar[str] = "free"

    def rhs(self, state):
        """``w'`` (rad/s²) for states ``w`` of shape (..., 3), rad/s."""
        return _euler_rhs(self.moments, self._state(state), 0.0)

    def jacobian(self, state):
        """``∂w'/∂w`` (1/s), shape (..., 3, 3), for states of shape (..., 3)."""
        return _euler_jacobian(self.moments, self._state(state), 0.0)

    def invariants(self, state):
        """``{"energy": ½ w·Iw (J), "momentum_squared": |Iw|² ((N m s)²)}``, each of shape (...)."""
        w = self._state(state)
        lw = self.moments * w
        return {"energy": 0.5 * np.sum(lw * w, axis=-1), "momentum_squared": np.sum(lw * lw, axis=-1)}

    def equilibrium(self, axis, spin=1.0):
        """The steady spin ``w = spin e_axis``: shape (..., 3) for ``spin`` (...) rad/s; ``axis`` 1, 2 or 3."""
        return _spin_state(3, _one_axis(axis), spin)

    def transverse(self, axis, spin=1.0):
        """The two components across ``axis`` (cyclic order), weighted so that a linear oscillation is circular."""
        k = _one_axis(axis)
        weights = _circular_weights(self.moments, k, 1.0, 0.0)
        return Transverse(np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp), weights,
                          np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp))


@dataclass(frozen=True, eq=False)
class Gyrostat(Model):
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
        return _euler_rhs(self.moments, self._state(state), self.rotor)

    def jacobian(self, state):
        """``∂w'/∂w`` (1/s), shape (..., 3, 3): ``I⁻¹ ([I w + h]× − [w]× I)``."""
        return _euler_jacobian(self.moments, self._state(state), self.rotor)

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
        k = _one_axis(axis)
        across = np.delete(self.rotor, k)
        if np.abs(across).max() > ROTOR_RTOL * np.linalg.norm(self.rotor):
            raise ValueError(f"rotor must lie along the spin axis {k + 1} for a steady spin about it, got rotor = "
                             f"{self.rotor.tolist()} N m s")
        return _spin_state(3, k, spin)

    def transverse(self, axis, spin=1.0):
        """The two components across ``axis``, weighted so that the linear motion is circular for that spin.

        ``weights`` has shape ``spin.shape + (2,)``: ``k_i = I_i ((I_a − I_i) W + h_a)`` depend on the spin.
        """
        k = _one_axis(axis)
        weights = _circular_weights(self.moments, k, finite_array(spin, "spin"), float(self.rotor[k]))
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return Transverse(pair, weights, pair.copy())




@dataclass(frozen=True, eq=False)
class HeavyTop(Model):
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
        return np.concatenate([_euler_rhs(self.moments, w, 0.0) + torque / self.moments, np.cross(g, w)], axis=-1)

    def jacobian(self, state):
        """``∂(w', g')/∂(w, g)`` (1/s), shape (..., 6, 6).

        Blocks: ``∂w'/∂w = I⁻¹ ([Iw]× − [w]× I)``, ``∂w'/∂g = mgl I⁻¹ (−[c]×)``, ``∂g'/∂w = [g]×``,
        ``∂g'/∂g = −[w]×``.
        """
        y = self._state(state)
        w, g = y[..., :3], y[..., 3:]
        jac = np.zeros(y.shape + (6,), dtype=y.dtype)
        jac[..., :3, :3] = _euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = -self.mgl * _cross_matrix(self.centre) / self.moments[:, None]
        jac[..., 3:, :3] = _cross_matrix(g)
        jac[..., 3:, 3:] = -_cross_matrix(w)
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
        if _one_axis(axis) != 2:
            raise ValueError(f"axis (spin.axis) must be 3 for a heavy_top: the centre of mass lies on body axis 3, "
                             f"got {axis!r}")
        state = _spin_state(6, 2, spin)
        state[..., 5] = 1.0
        return state

    def transverse(self, axis, spin=1.0):
        """``(w1, w2, g1, g2)`` with weights ``(1, 1, mgl/I1, mgl/I2)`` (all terms in (rad/s)²); phase: the tilt.

        ``(g1, g2)`` is the tilt of the top's axis from the vertical (rad, to first order); ``mgl / I_i`` is the
        squared rate at which an upright top at rest falls, which makes the two halves comparable whatever the
        spin (also for a top at rest). The phase fit follows the tilt ``(g1, g2)``.
        """
        self._on_axis_3()
        if _one_axis(axis) != 2:
            raise ValueError(f"axis (spin.axis) must be 3 for a heavy_top, got {axis!r}")
        weights = np.array([1.0, 1.0, self.mgl / self.moments[0], self.mgl / self.moments[1]])
        return Transverse(np.array([0, 1, 3, 4], dtype=np.intp), weights, np.array([3, 4], dtype=np.intp))

    def perturbed(self, draws, axis, spin):
        """:meth:`Model.perturbed`, with the up vector ``g`` from ``draws.up()``: ``e3`` tilted by its own angle."""
        states = super().perturbed(draws, axis, spin)
        states[:, 3:6] = draws.up()
        return states


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
class GravityGradient(Model):
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
        return (strength / self.moments[:, None]) * (_cross_matrix(c3) * self.moments - _cross_matrix(self.moments * c3))

    def rhs(self, state, t=0.0):
        """``(w', q')`` for states of shape (..., 7) at time ``t`` (s; only an eccentric orbit depends on it): rad/s²,
        then 1/s."""
        _, w, q, _, c3, w_r, _, strength = self._parts(state, t)
        torque = strength * np.cross(c3, self.moments * c3)
        dq = 0.5 * np.einsum("...ij,...j->...i", _xi(q), w_r)
        return np.concatenate([_euler_rhs(self.moments, w, 0.0) + torque / self.moments, dq], axis=-1)

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
        jac[..., :3, :3] = _euler_jacobian(self.moments, w, 0.0)
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
        jac[..., :3, :3] = _euler_jacobian(self.moments, w, 0.0)
        jac[..., :3, 3:] = self._torque_jacobian(c3, strength) @ _cross_matrix(c3)
        jac[..., 3:, :3] = np.eye(3)
        jac[..., 3:, 3:] = self.orbit_rate * _cross_matrix(c2) - _cross_matrix(w_r)
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
        _one_axis(axis)
        state = _spin_state(7, 1, finite_array(spin, "spin") * 0.0 - self.orbit_rate)
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
        return Transverse(np.array([0, 1, 2, 4, 5, 6], dtype=np.intp),
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


@dataclass(frozen=True, eq=False)
class Damper(Model):
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
        return np.concatenate([_euler_rhs(self.moments, w, 0.0) + slip / self.moments,
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
        jac[..., :3, :3] = _euler_jacobian(self.moments, w, 0.0) - np.diag(self.damping / self.moments)
        jac[..., :3, 3:] = np.diag(self.damping / self.moments)
        jac[..., 3:, :3] = _cross_matrix(s) + k * eye
        jac[..., 3:, 3:] = -_cross_matrix(w) - k * eye
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
        k = _one_axis(axis)
        state = _spin_state(6, k, spin)
        state[..., k + 3] = state[..., k]
        return state

    def transverse(self, axis, spin=1.0):
        """The body's two components ``w_b, w_c`` across ``axis``, weighted as the free body's of moments ``I``
        (a weakly damped nutation is then circular); the sphere's components are not part of the norm (they follow
        the body's nutation, and their relative motion decays at about ``c / J``)."""
        k = _one_axis(axis)
        pair = np.array([(k + 1) % 3, (k + 2) % 3], dtype=np.intp)
        return Transverse(pair, _circular_weights(self.moments, k, 1.0, 0.0), pair.copy())

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


#: Every model with a class here, by kind (``registry.MODELS``' ``physics`` flag).
CLASSES = {cls.kind: cls for cls in (FreeBody, Gyrostat, HeavyTop, GravityGradient, Damper)}

#: The models studies run (``registry.MODELS``' ``implemented`` flag); the others have no studies yet (:func:`from_kind`
#: builds them, ``theory.linear`` linearises them, the kernels step them: ``tumble.kernels.MODEL_CODES``).
IMPLEMENTED = {kind: cls for kind, cls in CLASSES.items() if registry.model_kind(kind).implemented}


def from_kind(kind, body, **parameters):
    """The model ``kind`` of ``body`` with its parameters, as a study's ``[model]`` table names them.

    Parameters
    ----------
    kind : str
        One of ``registry.MODEL_KINDS``: ``"free"``, ``"gyrostat"``, ``"heavy_top"`` (kernels and studies too),
        ``"gravity_gradient"``, ``"damper"`` (kernels too, no studies yet).
    body : Body or array_like, shape (3,)
        Principal moments, kg m².
    **parameters
        The kind's numeric parameters by study key (``rotor`` N m s, ``mgl`` N m, ``orbit_rate`` rad/s,
        ``damper_inertia`` kg m², ``damping`` N m s), all of them, no others.

    Returns
    -------
    Model

    Raises
    ------
    ValueError
        An unknown kind; a kind with no class yet (``registry.MODELS``' ``physics``); a parameter the kind does
        not have, or lacks;
        an invalid parameter or body. The message names the kind or the key.

    Examples
    --------
    >>> from_kind("heavy_top", (1.0, 1.0, 0.5), mgl=2.0).state_size
    6
    """
    spec = registry.model_kind(kind)
    if not spec.physics or kind not in CLASSES:
        keys = ", ".join(spec.parameters)
        raise ValueError(f"model kind {kind!r} is reserved but not implemented yet (parameters {keys}); "
                         f"implemented: {', '.join(CLASSES)}")
    allowed = (*spec.parameters, *CLASSES[kind].extras)  # the study keys (required), then the API's own (optional)
    for key in parameters:
        if key not in allowed:
            raise ValueError(f"{key}: not a parameter of model kind {kind!r} "
                             f"(its parameters: {', '.join(allowed) or 'none'})")
    for key in spec.parameters:
        if key not in parameters:
            raise ValueError(f"{key}: model kind {kind!r} needs it")
    return CLASSES[kind](body, **parameters)
