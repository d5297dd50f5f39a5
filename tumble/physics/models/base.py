"""The base of the models (:mod:`tumble.physics.models`): :class:`Model`, :class:`Transverse` and the helpers
the models share (the rigid body's constants, the Jacobian of Euler's equations with the differences of the
moments, a steady spin's state, circular weights, a parameter checked against its registry row).

A model's module holds its equations once, as per-sample scalar code (plain Python that numba compiles: the kernels'
copy of it is generated, :mod:`tumble.kernels.steps.model_codegen`): ``Constants`` (the named numbers the equations
read), ``constants(moments, **parameters)``, ``rate(t, *y, c)``, ``tangent(t, *y, *v, c)`` (``J(y) v``) and
``invariants(*y, c)``. Called with numpy arrays as the components (:func:`on_arrays`: the same code, its ``math``
read as numpy), the same functions give :meth:`Model.rhs`, :meth:`Model.jacobian` and :meth:`Model.invariants` here:
there is no second transcription of the equations in numpy.
"""

from __future__ import annotations

import functools
import importlib
import types
from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np

from ... import registry
from ..bodies import finite_array, one_body

__all__ = ["Model", "Transverse", "circular_weights", "cross_matrix", "euler_jacobian", "on_arrays", "one_axis",
           "parameter", "spin_state"]


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


def cross_matrix(v):
    """``[v]×`` of shape (..., 3, 3) for ``v`` of shape (..., 3): ``[v]× @ u = v × u`` (entries filled in place: a
    scene's linear theory builds a dozen of these, and nested ``np.stack`` calls cost several times the arithmetic)."""
    v = np.asarray(v)
    out = np.zeros(v.shape[:-1] + (3, 3), dtype=v.dtype)
    v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
    out[..., 0, 1], out[..., 0, 2] = -v3, v2
    out[..., 1, 0], out[..., 1, 2] = v3, -v1
    out[..., 2, 0], out[..., 2, 1] = -v2, v1
    return out


def one_axis(axis):
    """A 1-based principal axis (one integer) as a 0-based int; ValueError naming ``axis`` otherwise."""
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or axis not in (1, 2, 3):
        raise ValueError(f"axis must be 1, 2 or 3 (one integer), got {axis!r}")
    return int(axis) - 1


def parameter(key, value):
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


_ON_ARRAYS = {}


def on_arrays(module):
    """The functions of a system's ``module`` as functions of numpy arrays: the same code objects with the module's
    names, ``math`` replaced by numpy (whose ``sqrt``, ``sin``, ``floor``, ... broadcast; ``math``'s take one
    number, and numba's device code takes ``math``'s only), as a namespace (``.rate``, ``.tangent``, ...). Made once
    a module."""
    if module.__name__ not in _ON_ARRAYS:
        names = {**vars(module), "math": np}
        for name, value in vars(module).items():
            if isinstance(value, types.FunctionType) and value.__module__ == module.__name__:
                names[name] = types.FunctionType(value.__code__, names, name, value.__defaults__, value.__closure__)
        _ON_ARRAYS[module.__name__] = types.SimpleNamespace(**names)
    return _ON_ARRAYS[module.__name__]


@dataclass(frozen=True, eq=False)
class Model:
    """Base of the models: principal moments and what every model offers (see the module docstring).

    Parameters
    ----------
    moments : Body or array_like, shape (3,)
        Principal moments ``(I1, I2, I3)``, kg m², validated as :func:`tumble.physics.bodies.validate_moments`
        does (finite, > 0, triangle inequality). Stored as a read-only float64 array.

    See Also
    --------
    tumble.models.from_kind : A model by the name a study gives it.
    tumble.System : A user's own system, which the engine runs the same way.
    tumble.theory.linearisation : A model's linear theory at a steady spin.

    Examples
    --------
    Every model has a state size, a steady spin to expand about and invariants by name:

    >>> import tumble
    >>> top = tumble.models.HeavyTop((1.0, 1.0, 0.5), 0.1)
    >>> isinstance(top, tumble.models.Model), top.state_size
    (True, 6)
    >>> top.equilibrium(3, 5.0)
    array([0., 0., 5., 0., 0., 1.])
    >>> sorted(top.invariants(top.equilibrium(3, 5.0)))
    ['energy', 'up_squared', 'vertical_momentum']
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
    #: The blocks of its state (``registry.STATE_BLOCKS`` letters) that are unit vectors in every state it can be in:
    #: the heavy top's up vector, the gravity gradient's quaternion (:meth:`state_problem`).
    unit_blocks: ClassVar[tuple] = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.kind:
            cls.state_size = len(registry.model_kind(cls.kind).state)

    def __post_init__(self):
        moments = one_body(self.moments).copy()
        moments.setflags(write=False)
        object.__setattr__(self, "moments", moments)
        for key in self.spec.parameters:  # each study key checked against its registry row: a number or a vector
            value = parameter(key, getattr(self, key))
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

    def state_problem(self, states, rtol=1e-9):
        """Why ``states`` (N, n) lie outside the model's domain, as one line, or None: a block of
        :attr:`unit_blocks` whose norm is not 1 (within ``rtol``), naming the first such sample."""
        states = np.asarray(states, dtype=float)
        for letter, start, stop in registry.state_blocks(self.kind):
            if letter in self.unit_blocks:
                norms = np.linalg.norm(states[:, start:stop], axis=1)
                bad = np.flatnonzero(~(np.abs(norms - 1.0) <= rtol))
                if len(bad):
                    names = ", ".join(self.spec.state[start:stop])
                    return (f"({names}) of a {self.kind} model must be a unit vector in every state; sample "
                            f"{int(bad[0])} has norm {float(norms[bad[0]])!r}")
        return None

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

    # --- its equations: the per-sample functions of its module (see the module docstring) ------------------------
    @classmethod
    def equations(cls):
        """The module that holds the model's per-sample equations (``registry.Model.equations_module``): its own,
        the gyrostat's for the free body."""
        return importlib.import_module(f"{__package__}.{registry.model_kind(cls.kind).equations_module}")

    @functools.cached_property
    def constants(self):
        """The equations' ``Constants`` record of this model: its moments and parameters as named numbers (built
        once)."""
        return self.equations().constants(self.moments, **self.parameters)

    def _equations_on(self, state, tangent=False):
        """``(y, the module's function on arrays, its state arguments)``: ``y`` (..., n) as its ``n`` columns; for
        the tangent flow each with a last axis of length ``n``, along which the tangent runs over the unit vectors
        (one call gives the Jacobian's every column)."""
        y = self._state(state)
        functions = on_arrays(self.equations())
        if not tangent:
            return y, functions.rate, tuple(y[..., i] for i in range(self.state_size))
        columns = tuple(y[..., i, None] for i in range(self.state_size))
        return y, functions.tangent, (*columns, *np.eye(self.state_size))

    def rhs(self, state, t=0.0):
        """The time derivative of ``state`` (shape (..., n), n = :attr:`state_size`) at time ``t`` (s; only an
        eccentric orbit's equations depend on it), same shape: the module's ``rate``; each model says its units."""
        y, rate, arguments = self._equations_on(state)
        out = np.empty(y.shape, dtype=np.result_type(y, float))
        for i, value in enumerate(rate(t, *arguments, self.constants)):
            out[..., i] = value
        return out

    def jacobian(self, state, t=0.0):
        """``∂ rhs / ∂ state`` at ``state`` (shape (..., n)) and time ``t``: shape (..., n, n), column ``k`` the
        module's ``tangent`` along the unit vector ``e_k`` (its exact derivative)."""
        y, tangent, arguments = self._equations_on(state, tangent=True)
        jac = np.empty(y.shape + (self.state_size,), dtype=np.result_type(y, float))
        for i, row in enumerate(tangent(t, *arguments, self.constants)):
            jac[..., i, :] = row
        return jac

    def invariants(self, state):
        """The conserved quantities of ``state`` (shape (..., n)): ``{name: array of shape (...)}``, named as in
        ``registry.MODELS`` (the module's ``invariants``, in that order)."""
        y = self._state(state)
        values = on_arrays(self.equations()).invariants(*(y[..., i] for i in range(self.state_size)), self.constants)
        return {name: np.broadcast_to(value, y.shape[:-1]) + 0.0 for name, value in zip(self.spec.invariants, values)}

    # Each model defines: equilibrium, transverse.
    def equilibrium(self, axis, spin=1.0):  # pragma: no cover - abstract
        """The steady state of a spin ``spin`` (rad/s) about body ``axis`` (1, 2 or 3): shape (..., n)."""
        raise NotImplementedError

    def transverse(self, axis, spin=1.0):  # pragma: no cover - abstract
        """The :class:`Transverse` description of a perturbation of the steady spin about ``axis``: the state
        columns across it and their weights (:meth:`transverse_norm`)."""
        raise NotImplementedError


_CYCLIC = ((0, 1, 2), (1, 2, 0), (2, 0, 1))


def euler_jacobian(moments, w, h):
    """``∂w'/∂w`` of Euler's equations with a rotor ``h``, ``I w' = (I w + h) × w``, shape (..., 3, 3): ``I⁻¹ ([I w +
    h]× − [w]× I)``, entry by entry from the differences of the moments (so that linear theory of a nearly symmetric
    body keeps its digits; the gravity gradient's Jacobian in its attitude error): ``J_ij = ((I_j − I_k) w_k − h_k) /
    I_i``, ``J_ik = ((I_j − I_k) w_j + h_j) / I_i`` for ``(i, j, k)`` cyclic, ``J_ii = 0``."""
    h = np.broadcast_to(np.asarray(h, dtype=float), (3,))
    jac = np.zeros(w.shape + (3,), dtype=np.result_type(w, float))
    for i, j, k in _CYCLIC:
        d = moments[j] - moments[k]
        jac[..., i, j] = (d * w[..., k] - h[k]) / moments[i]
        jac[..., i, k] = (d * w[..., j] + h[j]) / moments[i]
    return jac


def spin_state(size, k, spin):
    """States of shape (..., size), zero but for the spin (..., rad/s) in component ``k``."""
    spin = finite_array(spin, "spin")
    state = np.zeros(spin.shape + (size,))
    state[..., k] = spin
    return state


def circular_weights(moments, k, spin, h):
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
