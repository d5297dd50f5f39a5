"""Linear stability theory and closed-form special cases of Euler's equations.

Everything here is vectorised with numpy broadcasting: a body is a :class:`~tumble.physics.bodies.Body` or an
array of principal moments of shape ``(..., 3)`` (kg m²), spins and other arguments broadcast against the
leading shape. Axis arguments are 1-based (1, 2, 3) as in the physics.

* :func:`stability_exponent`, :func:`linear`: small perturbations of a steady spin about a principal axis
  (Landau & Lifshitz, *Mechanics*, §37; DESIGN.md "Physics").
* :func:`eigenvalues`, and :func:`linear` of a model (:mod:`tumble.physics.models`): linear theory of any model,
  from the eigenvalues of its Jacobian at the steady spin; :func:`gyrostat_linear`, :func:`sleeping_top_linear`,
  :func:`sleeping_top_precession`, the gravity gradient's :func:`gravity_gradient_pitch_frequency`,
  :func:`gravity_gradient_roll_yaw`, :func:`gravity_gradient_stable` (Lagrange and DeBra–Delp regions,
  :func:`gravity_gradient_region`) and the damper's :func:`damper_nutation_rate` are the closed forms it is
  tested against.
* :func:`symmetric_top_precession`: torque-free symmetric top (L&L §33, §36).
* :func:`constant_torque_symmetric_top`: symmetric top under a constant body torque about its symmetry
  axis (problem sheet "Part 8: Rigid Body Dynamics", problem 6, "the wobbly space station").
* :func:`first_flip_time`, :func:`flip_spacing` (from :mod:`tumble.physics.exact`) and
  :func:`flip_time_asymptote`: timing of the flips of a spin near the intermediate axis.

Degenerate axes
---------------
When the spin axis shares its moment with another axis (a symmetric top spun about a transverse axis, or
a sphere), ``q = 0`` and linear theory predicts neither oscillation nor exponential growth: the kind is
``"neutral"`` and the value ``0.0`` (never NaN). Moments that differ by no more than
``DEGENERATE_RTOL`` times the largest moment count as equal, so that bodies diagonalised numerically
(whose equal moments differ in the last bits) are classified the same way as exact ones.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import registry
from .bodies import as_moments, finite_array, moment_unit
from .models import FreeBody, Model
from .system import System, with_parameters

__all__ = [
    "DEGENERATE_RTOL",
    "EIGEN_RTOL",
    "GRAVITY_GRADIENT_REGIONS",
    "KINDS",
    "Linearisation",
    "TORQUE_PROFILE_FORMULAS",
    "constant_torque_symmetric_top",
    "damper_nutation_rate",
    "eigenvalues",
    "eigenvalues_at",
    "first_flip_time",
    "flip_spacing",
    "flip_time_asymptote",
    "gravity_gradient_k",
    "gravity_gradient_pitch_frequency",
    "gravity_gradient_region",
    "gravity_gradient_roll_yaw",
    "gravity_gradient_stable",
    "gyrostat_linear",
    "linear",
    "linearisation",
    "linear_rate",
    "profile_integrals",
    "sleeping_top_linear",
    "sleeping_top_precession",
    "stability_exponent",
    "symmetric_top_precession",
]

#: Moments within this fraction of the body's largest moment are treated as equal (degenerate axes).
DEGENERATE_RTOL = 1e-12

#: The kinds :func:`linear` can return.
KINDS = ("periodic", "exponential", "neutral")


def _axis_index(axis, name="axis"):
    """Validate a 1-based axis (int or integer array) and return it 0-based."""
    if type(axis) is int and axis in (1, 2, 3):  # the common case, without array machinery
        return np.intp(axis - 1)
    arr = np.asarray(axis)
    if arr.dtype == bool or arr.dtype.kind not in "iu":
        raise ValueError(f"{name} must be 1, 2 or 3 (an integer), got {axis!r}")
    if not np.isin(arr, (1, 2, 3)).all():
        raise ValueError(f"{name} must be 1, 2 or 3, got {axis!r}")
    return arr.astype(np.intp) - 1


def _pick(moments, index):
    """``moments[..., index]`` with ``index`` broadcast against the leading shape of ``moments``."""
    if moments.shape == (3,) and np.ndim(index) == 0:
        return moments[index]
    shape = np.broadcast_shapes(moments.shape[:-1], np.shape(index))
    moments = np.broadcast_to(moments, shape + (3,))
    index = np.broadcast_to(index, shape)
    return np.take_along_axis(moments, index[..., None], axis=-1)[..., 0]


def _differences(ia, ib, scale):
    """``ia − ib``, snapped to exactly 0 where it is within ``DEGENERATE_RTOL * scale``."""
    d = ia - ib
    return np.where(np.abs(d) <= DEGENERATE_RTOL * scale, 0.0, d)


def stability_exponent(body, axis):
    r"""Linear stability exponent ``q`` of a steady spin about a principal axis.

    For a spin ``w`` about axis ``a`` (the other two ``b``, ``c``), small perturbations obey
    ``δw_b'' = −q w² δw_b`` with

    ``q = (Ia − Ib)(Ia − Ic) / (Ib Ic)``

    (Landau & Lifshitz §37; DESIGN.md). ``q > 0``: oscillation at angular frequency ``|w| sqrt(q)``
    (largest and smallest axes); ``q < 0``: exponential growth at rate ``|w| sqrt(−q)`` (intermediate
    axis); ``q = 0``: degenerate axis, neutral. ``q`` is dimensionless, unchanged by scaling all moments.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m².
    axis : int or array_like of int, shape broadcastable to (...)
        Spin axis, 1-based.

    Returns
    -------
    ndarray, shape (...)
        ``q``, dimensionless; exactly 0 for degenerate axes (moments equal within ``DEGENERATE_RTOL``).

    See Also
    --------
    tumble.theory.linear : The kind and the rate that ``q`` gives.
    tumble.theory.linear_rate : The same as one signed number.

    Notes
    -----
    Euler's equations linearised about the steady spin :math:`\omega` about axis :math:`a` give, for the
    transverse components [1]_,

    .. math::

        \delta\ddot\omega_b = -q\,\omega^2\,\delta\omega_b, \qquad q = \frac{(I_a - I_b)(I_a - I_c)}{I_b I_c}.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    Largest and smallest axes oscillate (:math:`q > 0`), the intermediate one grows (:math:`q < 0`):

    >>> from tumble import theory
    >>> theory.stability_exponent((1.0, 2.0, 3.0), [1, 2, 3]).round(4)
    array([ 0.3333, -0.3333,  1.    ])
    """
    moments = as_moments(body)
    k = _axis_index(axis)
    # q is scale invariant: moments in units of the power of two nearest the largest one (exact, so the same bits
    # as unscaled wherever those do not under- or overflow), so that moments of 1e-170 or 1e200 kg m², whose
    # products leave the float range, give the q of moments of order 1 (issue 17, cause 9).
    moments = moments / moment_unit(moments)[..., None]
    ia = _pick(moments, k)
    ib = _pick(moments, (k + 1) % 3)
    ic = _pick(moments, (k + 2) % 3)
    scale = moments.max() if moments.shape == (3,) else np.max(np.broadcast_to(moments, ia.shape + (3,)), axis=-1)
    return _differences(ia, ib, scale) * _differences(ia, ic, scale) / (ib * ic)


def linear_rate(body, axis, spin=1.0):
    """Signed linear rate: ``+|w| sqrt(q)`` (periodic, rad/s) or ``−|w| sqrt(−q)`` (exponential, 1/s).

    A compact, purely numeric form of :func:`linear` for array code: the sign carries the kind, 0 is
    neutral.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m².
    axis : int or array_like of int
        Spin axis, 1-based.
    spin : float or array_like
        Spin rate ``w`` about ``axis``, rad/s; finite.

    Returns
    -------
    ndarray, shape (...)

    See Also
    --------
    tumble.theory.linear : The kind and the rate as a pair.
    tumble.theory.stability_exponent : ``q``.

    Examples
    --------
    >>> from tumble import theory
    >>> theory.linear_rate((1.0, 2.0, 3.0), [1, 2, 3]).round(4)
    array([ 0.5774, -0.5774,  1.    ])
    """
    q = stability_exponent(body, axis)
    w = np.abs(finite_array(spin, "spin"))
    return np.sign(q) * w * np.sqrt(np.abs(q))


def linear(body, axis, spin=1.0):
    r"""Linear-theory behaviour of a perturbed steady spin about a principal axis (of a free body or any model).

    ``body`` may be a model (:class:`tumble.physics.models.Model`): then the answer comes from the eigenvalues of
    the model's Jacobian at its steady spin (:func:`eigenvalues`; the rule is in :func:`_linear_model`), and for
    a :class:`~tumble.physics.models.FreeBody` it equals the free body's answer below to round-off. For a body
    (a Body or moments) the closed form below is used, as always.

    With ``q`` from :func:`stability_exponent` (Landau & Lifshitz §37; DESIGN.md "Physics"):

    * ``q > 0`` → ``("periodic", |w| sqrt(q))``: perturbations oscillate at this angular frequency, rad/s;
    * ``q < 0`` → ``("exponential", |w| sqrt(−q))``: perturbations grow at this rate, 1/s;
    * ``q = 0`` → ``("neutral", 0.0)``: a degenerate axis (the spin axis shares its moment with another:
      a symmetric top spun about a transverse axis, or a sphere). Linearised perturbations neither
      oscillate nor grow exponentially (at most they drift linearly in time), so no rate is defined.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m², any order.
    axis : int or array_like of int, broadcastable to (...)
        Spin axis, 1, 2 or 3.
    spin : float or array_like, broadcastable to (...)
        Spin rate ``w`` about ``axis``, rad/s; finite (its sign does not matter).

    Returns
    -------
    kind : str, or ndarray of str, shape (...)
        ``"periodic"``, ``"exponential"`` or ``"neutral"``.
    value : float, or ndarray of float, shape (...)
        Angular frequency (rad/s), growth rate (1/s), or 0.0.
        For a single body (a Body or moments of shape (3,)), a scalar axis and a scalar spin the result
        is exactly the tuple ``(str, float)``.

    Raises
    ------
    ValueError
        Invalid moments, an axis other than 1, 2, 3, or a non-finite spin.

    See Also
    --------
    tumble.theory.stability_exponent : ``q`` alone.
    tumble.theory.eigenvalues : A model's Jacobian eigenvalues at its steady spin.
    tumble.measure : The rate measured on an ensemble, against this one.

    Notes
    -----
    For a steady spin :math:`\omega` about axis :math:`a` (the others :math:`b`, :math:`c`), Euler's equations
    linearised about it give [1]_

    .. math::

        \delta\ddot\omega_b = -q\,\omega^2\,\delta\omega_b, \qquad q = \frac{(I_a - I_b)(I_a - I_c)}{I_b I_c},

    so a perturbation oscillates at the angular frequency :math:`|\omega|\sqrt{q}` when :math:`q > 0` (the largest
    and the smallest axes) and grows as :math:`e^{\lambda t}`, :math:`\lambda = |\omega|\sqrt{-q}`, when
    :math:`q < 0` (the intermediate axis).

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §37.

    Examples
    --------
    >>> linear((1.0, 2.0, 3.0), 2, 1.0)
    ('exponential', 0.5773502691896257)
    >>> kind, value = linear((1.0, 2.0, 3.0), 3, 2.0)
    >>> kind, round(value, 12)
    ('periodic', 2.0)
    """
    if isinstance(body, Model):
        return _linear_model(body, axis, spin)
    one = _linear_one(body, axis, spin)
    if one is not None:
        return one
    q = stability_exponent(body, axis)
    w = np.abs(finite_array(spin, "spin"))
    value = w * np.sqrt(np.abs(q))
    q = np.broadcast_to(q, np.shape(value))
    kind = np.where(q > 0, KINDS[0], np.where(q < 0, KINDS[1], KINDS[2]))
    if np.ndim(value) == 0:
        return str(kind), float(value)
    return kind, value


def _linear_one(body, axis, spin):
    """:func:`linear` of one body, one axis and one finite spin in Python floats (the same operations in the same
    order, so the same bits; a scan plans thousands of scenes); ``None`` for anything else."""
    if isinstance(axis, bool) or not isinstance(axis, (int, np.integer)) or axis not in (1, 2, 3):
        return None
    if isinstance(spin, bool) or not isinstance(spin, (float, int)) or not math.isfinite(spin):
        return None
    moments = as_moments(body)
    if moments.shape != (3,):
        return None
    i1, i2, i3 = moments.tolist()
    e = -math.frexp(max(i1, i2, i3))[1]  # as in stability_exponent: exact scaling, same bits, no under/overflow
    i1, i2, i3 = math.ldexp(i1, e), math.ldexp(i2, e), math.ldexp(i3, e)
    k = int(axis) - 1
    ia, ib, ic = (i1, i2, i3)[k], (i1, i2, i3)[(k + 1) % 3], (i1, i2, i3)[(k + 2) % 3]
    snap = DEGENERATE_RTOL * max(i1, i2, i3)
    d_b, d_c = ia - ib, ia - ic
    q = (0.0 if abs(d_b) <= snap else d_b) * (0.0 if abs(d_c) <= snap else d_c) / (ib * ic)
    return KINDS[0] if q > 0 else KINDS[1] if q < 0 else KINDS[2], abs(float(spin)) * math.sqrt(abs(q))


#: Round-off scale of computed eigenvalues, relative (see :func:`_linear_model`).
EIGEN_RTOL = 1e-9


def _equilibrium_jacobian(model, axis, spin):
    """The model's Jacobian at its steady spin about ``axis`` (one axis, or an array broadcast with ``spin``)."""
    if not isinstance(model, Model):
        raise TypeError(f"model must be a tumble.models model (FreeBody, Gyrostat, HeavyTop, GravityGradient, "
                        f"Damper), got {model!r}")
    k = _axis_index(axis)
    if np.ndim(k) == 0:
        return model.tangent_jacobian(model.equilibrium(int(k) + 1, spin))
    spin = finite_array(spin, "spin")
    shape = np.broadcast_shapes(k.shape, spin.shape)
    k, spin = np.broadcast_to(k, shape), np.broadcast_to(spin, shape)
    state = np.empty(shape + (model.state_size,))
    for a in np.unique(k):
        chosen = k == a
        state[chosen] = model.equilibrium(int(a) + 1, spin[chosen])
    return model.tangent_jacobian(state)


def eigenvalues(model, axis, spin=1.0):
    """Eigenvalues of a model's Jacobian at its steady spin about a principal axis.

    The linearised motion about the equilibrium ``y*`` (:meth:`tumble.physics.models.Model.equilibrium`) is
    ``δy' = J δy``, ``J = ∂f/∂y (y*)`` (the model's analytic
    :meth:`~tumble.physics.models.Model.tangent_jacobian`: its :meth:`~tumble.physics.models.Model.jacobian`, but
    for a gravity gradient, linearised in the 3 angles of the attitude error instead of the quaternion's 4
    components, whose norm is a constraint): a perturbation is a sum of modes ``exp(λ t)``. Real parts are growth
    rates (1/s), imaginary parts angular frequencies in the body frame (rad/s). A damper's steady spins form a
    line (any rate ``W``): one ``λ`` is 0, a neutral direction :func:`linear` does not count.

    Parameters
    ----------
    model : tumble.physics.models.Model
    axis : int or array_like of int
        Spin axis, 1-based (3 only for a heavy top).
    spin : float or array_like
        Steady spin rate about ``axis``, rad/s, signed (for a gyrostat the sign relative to the rotor matters).
        ``axis`` and ``spin`` broadcast together to the leading shape (...).

    Returns
    -------
    ndarray of complex, shape (..., n)
        ``numpy.linalg.eigvals`` of the Jacobian, ``n = model.tangent_size`` (the state's size, 6 for a gravity
        gradient), in LAPACK's order.

    Raises
    ------
    TypeError
        ``model`` is not a model (a Body or moments: use :func:`linear`).
    ValueError
        An axis the model has no steady spin about (heavy top: not 3; gyrostat: rotor across it); a non-finite
        spin.

    See Also
    --------
    tumble.theory.eigenvalues_at : The same at any state of any system.
    tumble.theory.linear : The kind and the rate these eigenvalues give.

    Examples
    --------
    The largest real part about the free body's intermediate axis is its growth rate:

    >>> import tumble
    >>> lam = tumble.theory.eigenvalues(tumble.models.FreeBody((1.0, 2.0, 3.0)), 2)
    >>> round(float(lam.real.max()), 6)
    0.57735
    """
    return np.linalg.eigvals(_equilibrium_jacobian(model, axis, spin))


def eigenvalues_at(system, state, parameters=None, *, t=0.0):
    """Eigenvalues of any system's Jacobian ``∂f/∂y`` at a state the caller gives (not only a steady spin).

    Parameters
    ----------
    system : Body, array_like (3,), model or System
        Moments (the free body), a built-in model (:mod:`tumble.models`) or a user's :class:`tumble.System`.
    state : array_like, shape (..., n)
        The state(s) to linearise about, in the system's components (``spec.state``).
    parameters : mapping, optional
        A model's or System's parameters, by name, in place of its own.
    t : float
        Time, s, for a System whose rate depends on it.

    Returns
    -------
    ndarray of complex, shape (..., n)
        ``numpy.linalg.eigvals`` of the Jacobian (LAPACK's order): a model's analytic one
        (:meth:`~tumble.physics.models.Model.jacobian`: for a gravity gradient in the quaternion's 4 components, so
        one eigenvalue, along the norm, is 0); a System's ``jacobian`` when it has one, else ``rate`` (both called as
        the Python functions they are) differentiated
        by :func:`scipy.differentiate.jacobian` (adaptive central differences of order 8 with Richardson
        extrapolation: about 1e-13 of the Jacobian's largest entry for a smooth rate, where one-sided differences
        give 1e-8; a complex step would be exact but needs a rate written for complex numbers).

    Raises
    ------
    ValueError
        A state of the wrong size or not finite, an unknown parameter, a Jacobian or rate that fails or gives a
        non-finite Jacobian (one line naming the system).

    See Also
    --------
    tumble.theory.eigenvalues : A model's at its steady spin.
    tumble.measure : A System's perturbations measured against these eigenvalues.

    Examples
    --------
    A pendulum balanced upside down is a saddle:

    >>> import math, tumble
    >>> def pendulum(t, y, p, dydt):
    ...     dydt[0] = y[1]
    ...     dydt[1] = -math.sin(y[0])
    >>> sys = tumble.System(pendulum, state=("x", "v"), name="pendulum")
    >>> lam = tumble.theory.eigenvalues_at(sys, [math.pi, 0.0])
    >>> sorted(round(float(x), 6) for x in lam.real)
    [-1.0, 1.0]
    """
    if isinstance(system, System):
        return _system_eigenvalues(system, state, parameters, t)
    model = system if isinstance(system, Model) else FreeBody(system)
    model, _ = with_parameters(model, parameters)
    y = finite_array(state, "state")
    if y.ndim == 0 or y.shape[-1] != model.state_size:
        raise ValueError(f"state must have shape (..., {model.state_size}) ({', '.join(model.spec.state)} of the "
                         f"{model.kind} model), got shape {y.shape}")
    return np.linalg.eigvals(model.jacobian(y))


def _system_eigenvalues(system, state, parameters, t):
    """:func:`eigenvalues_at` of a :class:`System`."""
    jacobians = system_jacobian(system, state, parameters, t=t)
    return np.linalg.eigvals(jacobians)


def system_linearisation(system, state, parameters=None, *, t=0.0):
    """:class:`Linearisation` of a :class:`System` at one state (n,): the kind and value :func:`linear` would
    report (the largest real part of the eigenvalues if it is growth beyond round-off, else the least damped
    oscillation's frequency, else neutral), its Jacobian and eigenvalues. A built-in model's is its exact Jacobian
    (:meth:`~tumble.physics.models.Model.jacobian`; its parameters are its own)."""
    if isinstance(system, Model):
        y = finite_array(state, "state")
        jac = system.jacobian(y) if y.shape == (system.state_size,) else np.empty(0)
    else:
        jac = system_jacobian(system, state, parameters, t=t)
    if jac.ndim != 2:
        raise ValueError(f"state must be one state of shape ({system.state_size},), got shape {np.shape(state)}")
    lam = np.linalg.eigvals(jac)
    kind, value = _classified(jac, lam)
    return Linearisation(kind, value, jac, lam)


def system_jacobian(system, state, parameters=None, *, t=0.0):
    """The Jacobian ``∂f/∂y`` of a :class:`System` at states (..., n), shape (..., n, n): its ``jacobian``, else its
    rate differentiated by :func:`scipy.differentiate.jacobian`; both called as the Python they are (a few dozen
    calls: nothing to compile)."""
    n = system.state_size
    y = finite_array(state, "state")
    if y.ndim == 0 or y.shape[-1] != n:
        raise ValueError(f"state must have shape (..., {n}) ({', '.join(system.state)} of system {system.name!r}), "
                         f"got shape {y.shape}")
    p = system.parameter_values(parameters)
    t = float(finite_array(t, "t"))
    flat = y.reshape(-1, n)
    jacobians = np.full((len(flat), n, n), np.nan)

    def call(fn, what, *args):
        try:
            fn(t, *args)
        except Exception as err:  # noqa: BLE001 - a user's function: its failure is reported in one line
            raise ValueError(f"system {system.name!r}: its {what} raised {type(err).__name__}: {err}") from None

    if system.jacobian is not None:
        for i, row in enumerate(flat):
            call(system.jacobian, "jacobian", row.copy(), p, jacobians[i])
    else:
        from scipy.differentiate import jacobian as differentiate

        def f(x):  # x (n, ...) -> the rate at every column, (n, ...)
            columns = np.moveaxis(x, 0, -1).reshape(-1, n)
            out = np.full_like(columns, np.nan)
            for j, column in enumerate(columns):
                call(system.rate, "rate", column.copy(), p, out[j])
            return np.moveaxis(out.reshape(*x.shape[1:], n), -1, 0)

        for i, row in enumerate(flat):
            jacobians[i] = differentiate(f, row).df
    if not np.all(np.isfinite(jacobians)):
        raise ValueError(f"system {system.name!r}: its Jacobian at the state is not finite (NaN or inf: an entry left "
                         f"unset, or a rate that is not differentiable there)")
    return jacobians.reshape(*y.shape[:-1], n, n)


def _linear_model(model, axis, spin):
    """:func:`linear` of a model, from the eigenvalues ``λ`` of its Jacobian at the steady spin.

    * ``"exponential"``, ``max Re λ``, when the largest real part exceeds ``EIGEN_RTOL · max|λ|``;
    * else ``"periodic"``, ``max |Im λ|``: the fastest body-frame frequency of the transverse components. For the
      free body and the gyrostat there is one transverse pair ``±iν`` (and ``0``, the spin itself): the
      components oscillate at ``ν`` — the frequency a phase fit of the transverse pair measures, and the free
      body's ``|w| sqrt(q)``. The *norm* of the perturbation oscillates at ``2ν`` (an ellipse) or not at all
      (circular, e.g. with the weights of :meth:`~tumble.physics.models.Model.transverse`), so ``ν`` is reported,
      never the norm's frequency. A sleeping top has two transverse frequencies (body frame, ``|Ω± − w3|``);
      the faster one is reported, and its tilt's norm beats at their difference, the nutation frequency;
    * ``"neutral"``, ``0.0``, when every ``|λ|`` is round-off (``max|λ| <= EIGEN_RTOL · max|J|``) or there is
      neither growth nor oscillation above round-off.

    With damping (a :class:`~tumble.physics.models.Damper` about its major axis) every mode but the neutral
    ``λ = 0`` decays, at different rates: the frequency reported is that of the least damped oscillation (largest
    ``Re λ`` among the ``|Im λ| > EIGEN_RTOL · max|λ|``, the fastest of those within ``EIGEN_RTOL · max|λ|`` of it),
    the one that remains — the nutation, not the damper's fast relative motion. Without damping every ``Re λ`` is
    round-off and this is ``max |Im λ|`` as above. A neutral ``λ`` (the damper's line of steady spins, ``|λ|`` and
    ``Re λ`` round-off) is counted neither as growth nor as an oscillation.

    Why ``EIGEN_RTOL = 1e-9`` relative to ``max|λ|``: LAPACK's eigenvalues carry errors of a few ``eps · |J|``
    times each eigenvalue's condition number, so a purely imaginary pair comes out with real parts of order
    ``1e-16 … 1e-13`` of ``|λ|`` (ill-conditioned, very elliptic modes) — a threshold relative to the
    eigenvalues' own magnitude is unit-free and scale-free, and 1e-9 leaves four orders of margin above that.
    A true growth rate below ``1e-9 |λ|`` would take over a hundred million periods to e-fold: no run measures
    it. Exactly at a collision of eigenvalues (a stability threshold: ``P = 0`` of a gyrostat, ``L3² = 4 I1 mgl``
    of a sleeping top) the pair is defective and its computed real parts are ``~sqrt(eps) |λ| ≈ 1e-8 |λ|``, so
    there the kind is round-off, as the physics is marginal.
    """
    jac = _equilibrium_jacobian(model, axis, spin)
    return _classified(jac, np.linalg.eigvals(jac))


def _classified(jac, lam):
    """:func:`_linear_model`'s ``(kind, value)`` from the Jacobian and its eigenvalues."""
    size = np.abs(lam).max(axis=-1)
    growth = lam.real.max(axis=-1)
    tol = EIGEN_RTOL * size[..., None]
    oscillating = np.abs(lam.imag) > tol
    lead = np.where(oscillating, lam.real, -np.inf).max(axis=-1)
    least_damped = oscillating & (lam.real >= lead[..., None] - tol)
    frequency = np.where(least_damped, np.abs(lam.imag), 0.0).max(axis=-1)
    matrix_scale = np.abs(jac).max(axis=(-2, -1))
    exponential = (growth > EIGEN_RTOL * size) & (size > EIGEN_RTOL * matrix_scale)
    periodic = ~exponential & (frequency > EIGEN_RTOL * size) & (size > EIGEN_RTOL * matrix_scale)
    kind = np.where(exponential, KINDS[1], np.where(periodic, KINDS[0], KINDS[2]))
    value = np.where(exponential, growth, np.where(periodic, frequency, 0.0))
    if np.ndim(value) == 0:
        return str(kind), float(value)
    return kind, value


class Linearisation(NamedTuple):
    """A model's linear theory at one steady spin (:func:`linearisation`).

    See Also
    --------
    tumble.theory.linearisation : What returns it.
    tumble.theory.linear : Its ``kind`` and ``value`` alone.

    Examples
    --------
    >>> import tumble
    >>> lin = tumble.theory.linearisation(tumble.models.FreeBody((1.0, 2.0, 3.0)), 2)
    >>> lin.kind, round(lin.value, 6), lin.jacobian.shape
    ('exponential', 0.57735, (3, 3))
    """

    kind: str  # "periodic", "exponential" or "neutral" (:func:`linear`)
    value: float  # rad/s or 1/s (:func:`linear`)
    jacobian: np.ndarray  # (n, n), 1/s: the tangent Jacobian at the steady spin (:func:`eigenvalues`' matrix)
    eigenvalues: np.ndarray  # (n,) complex: :func:`eigenvalues`


def linearisation(model, axis, spin=1.0):
    """:func:`linear` of a model at one steady spin together with the Jacobian and the eigenvalues it came from
    (the same bits as :func:`linear`, :func:`eigenvalues` and the model's ``tangent_jacobian`` at its
    ``equilibrium``): a scene's planning needs all three, and each costs a Jacobian.

    Parameters
    ----------
    model : tumble.physics.models.Model
    axis : int
        Spin axis, 1-based (one axis).
    spin : float
        Steady spin rate, rad/s (one rate).

    Returns
    -------
    Linearisation

    See Also
    --------
    tumble.theory.linear : The kind and the rate alone.
    tumble.theory.eigenvalues : The eigenvalues alone.

    Examples
    --------
    A heavy top spinning fast enough to sleep:

    >>> import tumble
    >>> lin = tumble.theory.linearisation(tumble.models.HeavyTop((1.0, 1.0, 0.5), 0.1), 3, 5.0)
    >>> lin.kind, round(lin.value, 4), lin.eigenvalues.shape
    ('periodic', 4.9593, (6,))
    """
    if isinstance(axis, (bool, np.bool_)) or np.ndim(axis) != 0 or np.ndim(spin) != 0:
        raise ValueError(f"linearisation takes one axis and one spin, got axis={axis!r}, spin={spin!r}")
    jac = _equilibrium_jacobian(model, axis, spin)
    lam = np.linalg.eigvals(jac)
    kind, value = _classified(jac, lam)
    return Linearisation(kind, value, jac, lam)


def _kind_of(p):
    """``"periodic"`` where ``p > 0``, ``"exponential"`` where ``p < 0``, ``"neutral"`` where 0."""
    return np.where(p > 0, KINDS[0], np.where(p < 0, KINDS[1], KINDS[2]))


def gyrostat_linear(body, h, axis, spin=1.0):
    """Linear theory of a gyrostat spinning about a principal axis, rotor along that axis (closed form).

    ``I w' = (I w + h) × w`` with ``h = h_a e_a`` and ``w = W e_a``; with ``(a, b, c)`` cyclic the transverse
    perturbations obey ``δw_b'' = −(P / (I_b I_c)) δw_b`` with

    ``P = [(I_a − I_b) W + h_a] [(I_a − I_c) W + h_a]``

    (Hughes, *Spacecraft Attitude Dynamics*, §7.3; for ``a = 3``: ``[(I3 − I1)W + h3][(I3 − I2)W + h3]``).
    ``P > 0`` → periodic, angular frequency ``sqrt(P / (I_b I_c))``; ``P < 0`` → exponential, rate
    ``sqrt(−P / (I_b I_c))``; ``P = 0`` → neutral. With ``h_a = 0`` it is the free body's :func:`linear`. A
    rotor with ``|h_a|`` beyond ``max(|(I_a − I_b) W|, |(I_a − I_c) W|)`` (same sign for both factors)
    stabilises any axis, the intermediate one included.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m².
    h : float or array_like
        Rotor angular momentum along ``axis``, N m s, signed (positive along ``+e_axis``).
    axis : int or array_like of int
        Spin axis, 1-based.
    spin : float or array_like
        ``W``, rad/s, signed. ``h``, ``axis``, ``spin`` and the body broadcast to (...).

    Returns
    -------
    kind : str or ndarray of str
    value : float or ndarray
        Angular frequency (rad/s), growth rate (1/s) or 0.0.

    Raises
    ------
    ValueError
        Invalid moments or axis; non-finite ``h`` or ``spin``.

    See Also
    --------
    tumble.models.Gyrostat : The gyrostat's equations, any rotor.
    tumble.theory.linear : The free body's, ``h = 0``.

    Examples
    --------
    A rotor along the intermediate axis stabilises it once ``|h|`` is large enough:

    >>> from tumble import theory
    >>> theory.gyrostat_linear((1.0, 2.0, 3.0), 0.0, 2)[0], theory.gyrostat_linear((1.0, 2.0, 3.0), 5.0, 2)[0]
    ('exponential', 'periodic')
    """
    moments = as_moments(body)
    k = _axis_index(axis)
    ia, ib, ic = _pick(moments, k), _pick(moments, (k + 1) % 3), _pick(moments, (k + 2) % 3)
    w = finite_array(spin, "spin")
    h = finite_array(h, "h")
    p = ((ia - ib) * w + h) * ((ia - ic) * w + h) / (ib * ic)
    value = np.sqrt(np.abs(p))
    kind = _kind_of(p)
    if np.ndim(value) == 0:
        return str(kind), float(value)
    return kind, value


def _sleeping_top(body, mgl, w3, rtol):
    """``(A, C, L3, D)`` of a symmetric heavy top (``A = I1 = I2``, ``C = I3``, ``D = L3² − 4 A mgl``)."""
    moments = as_moments(body)
    c, a, _ = _symmetric_pair(moments, 3, rtol)
    mgl = finite_array(mgl, "mgl")
    if not np.all(mgl > 0):
        raise ValueError(f"mgl must be > 0 N m, got {mgl.ravel()[:3].tolist()}")
    l3 = c * finite_array(w3, "w3")
    return a, c, l3, l3 * l3 - 4.0 * a * mgl


def sleeping_top_linear(body, mgl, w3, *, rtol=1e-10):
    """Linear theory of a sleeping symmetric top (upright heavy top spinning about its axis), closed form.

    With ``A = I1 = I2`` (about the pivot), ``C = I3``, ``L3 = C w3``, the tilt ``δg1 + i δg2 ∝ exp(iσt)`` of the
    Euler-Poisson equations (:class:`tumble.physics.models.HeavyTop`) linearised about ``w = (0, 0, w3)``,
    ``g = (0, 0, 1)`` obeys ``A σ² + (2A − C) w3 σ − (C − A) w3² + mgl = 0``, i.e. ``σ = Ω − w3`` with
    ``A Ω² − L3 Ω + mgl = 0`` (Goldstein §5.7, Arnold §30; ``Ω``: :func:`sleeping_top_precession`). Its
    discriminant is ``D = L3² − 4 A mgl``:

    * ``D < 0`` → ``("exponential", sqrt(4 A mgl − L3²) / (2A))``: the top wakes (falls);
    * ``D >= 0`` → ``("periodic", (|(C − 2A) w3| + sqrt(D)) / (2A))``: the fastest body-frame frequency
      ``max |Ω± − w3|``, as :func:`linear` of the model reports it (the "fast top" is stable for
      ``L3² > 4 A mgl``).

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments about the pivot, kg m²; ``I1 = I2`` within ``rtol``.
    mgl : float or array_like
        ``M g l``, N m, > 0.
    w3 : float or array_like
        Spin about the symmetry axis, rad/s, signed.
    rtol : float
        Relative tolerance for ``I1 = I2``.

    Returns
    -------
    kind : str or ndarray of str
    value : float or ndarray
        Growth rate (1/s) or angular frequency (rad/s).

    Raises
    ------
    ValueError
        Not symmetric about axis 3; ``mgl <= 0``; non-finite ``w3``.

    See Also
    --------
    tumble.theory.sleeping_top_precession : The precession rates of a sleeping top.
    tumble.models.HeavyTop : The top's equations.

    Examples
    --------
    The top sleeps once ``L3² > 4 A mgl``, here ``w3 > 1.26`` rad/s:

    >>> from tumble import theory
    >>> top = (1.0, 1.0, 0.5)
    >>> theory.sleeping_top_linear(top, 0.1, 0.5)[0], theory.sleeping_top_linear(top, 0.1, 5.0)[0]
    ('exponential', 'periodic')
    """
    a, c, _, d = _sleeping_top(body, mgl, w3, rtol)
    w3 = finite_array(w3, "w3")
    value = np.where(d < 0, np.sqrt(np.abs(d)) / (2 * a), (np.abs((c - 2 * a) * w3) + np.sqrt(np.abs(d))) / (2 * a))
    kind = np.where(d < 0, KINDS[1], KINDS[0])
    if np.ndim(value) == 0:
        return str(kind), float(value)
    return kind, value


def sleeping_top_precession(body, mgl, w3, *, rtol=1e-10):
    """Precession rates of the axis of a stable sleeping symmetric top, space frame: ``Ω±``, rad/s.

    ``Ω± = (L3 ± sqrt(L3² − 4 A mgl)) / (2A)``, the roots of ``A Ω² − L3 Ω + mgl = 0`` (Goldstein §5.7):
    the tilt of a slightly disturbed top turns about the vertical at a mix of these two rates (fast nutation
    ``≈ L3/A`` and slow precession ``≈ mgl/L3`` for a fast top). In the body frame, which turns at ``w3``,
    the same modes have frequencies ``Ω± − w3`` (the imaginary parts of the Jacobian's eigenvalues,
    :func:`eigenvalues`). The smaller root is computed as ``mgl / (A Ω_large)`` (no cancellation).

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments about the pivot, kg m²; ``I1 = I2`` within ``rtol``.
    mgl : float or array_like
        ``M g l``, N m, > 0.
    w3 : float or array_like
        Spin about the symmetry axis, rad/s, signed.

    Returns
    -------
    (omega_plus, omega_minus) : floats or ndarrays
        rad/s; NaN where the top is not stable (``L3² < 4 A mgl``).

    Raises
    ------
    ValueError
        As :func:`sleeping_top_linear`.

    See Also
    --------
    tumble.theory.sleeping_top_linear : Whether the top sleeps, and its body-frame frequency.
    tumble.models.HeavyTop : The top's equations.

    Examples
    --------
    Fast nutation near ``L3/A = 2.5`` rad/s and slow precession near ``mgl/L3 = 0.04`` rad/s:

    >>> from tumble import theory
    >>> fast, slow = theory.sleeping_top_precession((1.0, 1.0, 0.5), 0.1, 5.0)
    >>> round(float(fast), 4), round(float(slow), 4)
    (2.4593, 0.0407)
    """
    a, _, l3, d = _sleeping_top(body, mgl, w3, rtol)
    mgl = finite_array(mgl, "mgl")
    root = np.sqrt(np.where(d >= 0, d, np.nan))
    sign = np.where(l3 >= 0, 1.0, -1.0)
    large = (l3 + sign * root) / (2 * a)
    small = mgl / (a * large)
    plus, minus = np.where(l3 >= 0, large, small), np.where(l3 >= 0, small, large)
    if np.ndim(plus) == 0:
        return float(plus), float(minus)
    return plus, minus


def _orbit(body, orbit_rate):
    """``(I1, I2, I3, n)`` of a gravity-gradient closed form, checked (``n`` > 0)."""
    moments = as_moments(body)
    n = finite_array(orbit_rate, "orbit_rate")
    if not np.all(n > 0):
        raise ValueError(f"orbit_rate must be > 0 rad/s, got {n.ravel()[:3].tolist()}")
    return moments[..., 0], moments[..., 1], moments[..., 2], n


def gravity_gradient_k(body):
    """The inertia ratios of the gravity-gradient problem: ``k1 = (I2 − I3)/I1``, ``k3 = (I2 − I1)/I3``.

    Axes as :class:`tumble.physics.models.GravityGradient`: 1 roll, 2 pitch (orbit normal), 3 yaw (nadir).
    Hughes, *Spacecraft Attitude Dynamics*, §9.2 (his ``k1``, ``k3`` with the pitch axis 2); the triangle
    inequality bounds both to ``[−1, 1]``, and every point of that square is a body.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments ``(I1, I2, I3)``, kg m².

    Returns
    -------
    (k1, k3) : floats or ndarrays, shape (...)
        Dimensionless.

    See Also
    --------
    tumble.theory.gravity_gradient_stable : Whether ``(k1, k3)`` is stable.
    tumble.theory.gravity_gradient_region : Which region of the plane.

    Examples
    --------
    >>> from tumble import theory
    >>> theory.gravity_gradient_k((2.0, 2.5, 1.0))
    (0.75, 0.5)
    """
    moments = as_moments(body)
    i1, i2, i3 = moments[..., 0], moments[..., 1], moments[..., 2]
    k1, k3 = (i2 - i3) / i1, (i2 - i1) / i3
    if np.ndim(k1) == 0:
        return float(k1), float(k3)
    return k1, k3


def gravity_gradient_pitch_frequency(body, orbit_rate):
    """Linear pitch motion of a gravity-gradient satellite about its orbit-following attitude, closed form.

    The pitch angle ``θ2`` (about the orbit normal) decouples: ``I2 θ2'' + 3 n² (I1 − I3) θ2 = 0`` (Hughes §9.2),
    so ``w_p² = 3 n² (I1 − I3)/I2``: periodic at ``w_p`` when ``I1 > I3`` (``k1 > k3``), exponential at
    ``n sqrt(3 (I3 − I1)/I2)`` when ``I1 < I3``, neutral when equal.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments ``(I1, I2, I3)`` about roll, pitch, yaw, kg m².
    orbit_rate : float or array_like
        ``n``, rad/s, > 0; broadcast with the body's leading shape.

    Returns
    -------
    kind : str or ndarray of str
    value : float or ndarray
        Angular frequency (rad/s) or growth rate (1/s).

    Raises
    ------
    ValueError
        Invalid moments; ``orbit_rate`` not finite and > 0.

    See Also
    --------
    tumble.theory.gravity_gradient_roll_yaw : The coupled roll and yaw.
    tumble.models.GravityGradient : The satellite's equations.

    Examples
    --------
    >>> from tumble import theory
    >>> kind, value = theory.gravity_gradient_pitch_frequency((2.0, 2.5, 1.0), 1e-3)
    >>> kind, round(float(value), 8)
    ('periodic', 0.00109545)
    """
    i1, i2, i3, n = _orbit(body, orbit_rate)
    p = 3.0 * (i1 - i3) / i2
    value = n * np.sqrt(np.abs(p))
    kind = np.broadcast_to(_kind_of(p), np.shape(value))
    if np.ndim(value) == 0:
        return str(kind), float(value)
    return kind, value


def gravity_gradient_roll_yaw(body, orbit_rate):
    """The four exponents ``s`` of the linear roll-yaw motion of a gravity-gradient satellite, closed form.

    Roll ``θ1`` and yaw ``θ3`` couple through the orbit's rotation (Hughes §9.2):
    ``θ1'' + n (k1 − 1) θ3' + 4 n² k1 θ1 = 0``, ``θ3'' + n (1 − k3) θ1' + n² k3 θ3 = 0``, whose characteristic
    equation is ``s⁴ + n² (1 + 3 k1 + k1 k3) s² + 4 n⁴ k1 k3 = 0`` (``k1``, ``k3``: :func:`gravity_gradient_k`).
    The two roots ``x = s²`` of the quadratic are taken without cancellation (``x_small = c / x_large``).

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments ``(I1, I2, I3)``, kg m².
    orbit_rate : float or array_like
        ``n``, rad/s, > 0.

    Returns
    -------
    ndarray of complex, shape (..., 4)
        ``(+sqrt(x1), −sqrt(x1), +sqrt(x2), −sqrt(x2))``, 1/s: real parts are growth rates, imaginary parts
        angular frequencies (stable: all four on the imaginary axis).

    Raises
    ------
    ValueError
        Invalid moments; ``orbit_rate`` not finite and > 0.

    See Also
    --------
    tumble.theory.gravity_gradient_pitch_frequency : The decoupled pitch.
    tumble.theory.gravity_gradient_stable : Stability from ``k1`` and ``k3``.

    Examples
    --------
    In Lagrange's region the four exponents lie on the imaginary axis (frequencies in units of ``n``):

    >>> from tumble import theory
    >>> s = theory.gravity_gradient_roll_yaw((2.0, 2.5, 1.0), 1e-3)
    >>> bool(abs(s.real).max() < 1e-15), (abs(s.imag) / 1e-3).round(4)
    (True, array([1.7744, 1.7744, 0.6902, 0.6902]))
    """
    i1, i2, i3, n = _orbit(body, orbit_rate)
    k1, k3 = (i2 - i3) / i1, (i2 - i1) / i3
    b = (1.0 + 3.0 * k1 + k1 * k3) * n * n
    c = 4.0 * k1 * k3 * n ** 4
    root = np.sqrt((b * b - 4.0 * c).astype(complex))
    large = -0.5 * (b + np.where(b >= 0, 1.0, -1.0) * root)
    with np.errstate(divide="ignore", invalid="ignore"):
        small = np.where(large != 0, c / np.where(large != 0, large, 1.0), 0.0)
    s1, s2 = np.sqrt(large + 0j), np.sqrt(small + 0j)
    return np.stack([s1, -s1, s2, -s2], axis=-1)


def gravity_gradient_stable(k1, k3):
    """Whether the orbit-following attitude is linearly stable (strictly), from ``k1``, ``k3``.

    Stable iff all three hold (Hughes §9.2): ``k1 > k3`` (pitch: ``I1 > I3``), ``k1 k3 > 0`` and
    ``1 + 3 k1 + k1 k3 > 4 sqrt(k1 k3)`` (roll-yaw: both roots ``s²`` real and negative). The stable set is two
    regions (:func:`gravity_gradient_region`): Lagrange's, ``k1 > k3 > 0`` (``I2 > I1 > I3``: pitch axis major,
    yaw minor), where the third condition always holds; and DeBra–Delp's, ``0 > k1 > k3`` with the third condition
    (``I1 > I3 > I2``: roll axis major, pitch minor), a thin strip next to ``k1 = 0``. A point on a boundary is
    marginal, not stable.

    Parameters
    ----------
    k1, k3 : float or array_like
        :func:`gravity_gradient_k`; broadcast together.

    Returns
    -------
    bool or ndarray of bool

    See Also
    --------
    tumble.theory.gravity_gradient_region : Which stable region.
    tumble.models.GravityGradient : The satellite's equations.

    Examples
    --------
    Pitch axis major and yaw minor (Lagrange's region) is stable; roll major and yaw minor is not:

    >>> from tumble import theory
    >>> bool(theory.gravity_gradient_stable(*theory.gravity_gradient_k((2.0, 2.5, 1.0))))
    True
    >>> bool(theory.gravity_gradient_stable(*theory.gravity_gradient_k((2.5, 2.0, 1.0))))
    False
    """
    k1, k3 = np.asarray(k1, dtype=float), np.asarray(k3, dtype=float)
    product = k1 * k3
    with np.errstate(invalid="ignore"):
        stable = (k1 > k3) & (product > 0) & (1.0 + 3.0 * k1 + product > 4.0 * np.sqrt(np.maximum(product, 0.0)))
    return bool(stable) if stable.ndim == 0 else stable


#: The regions of :func:`gravity_gradient_region`.
GRAVITY_GRADIENT_REGIONS = ("lagrange", "debra_delp", "unstable")


def gravity_gradient_region(k1, k3):
    """Which region of the ``(k1, k3)`` plane: ``"lagrange"`` (stable, ``k1 > k3 > 0``), ``"debra_delp"`` (stable,
    ``0 > k1 > k3``) or ``"unstable"`` (anything else, boundaries included); see :func:`gravity_gradient_stable`.

    Returns
    -------
    str or ndarray of str, shape of ``k1`` and ``k3`` broadcast

    See Also
    --------
    tumble.theory.gravity_gradient_stable : The same as a boolean.
    tumble.theory.gravity_gradient_k : ``k1`` and ``k3`` of a body.

    Examples
    --------
    >>> from tumble import theory
    >>> theory.gravity_gradient_region(0.75, 0.5), theory.gravity_gradient_region(0.5, 0.75)
    ('lagrange', 'unstable')
    """
    k1 = np.asarray(k1, dtype=float)
    stable = np.asarray(gravity_gradient_stable(k1, k3))
    region = np.where(stable, np.where(k1 > 0, GRAVITY_GRADIENT_REGIONS[0], GRAVITY_GRADIENT_REGIONS[1]),
                      GRAVITY_GRADIENT_REGIONS[2])
    return str(region) if region.ndim == 0 else region


def damper_nutation_rate(body, damper_inertia, damping, axis):
    """Growth rate of the nutation of a body with a weakly damped spherical damper, to first order in ``c``.

    Spin ``s = w = W e_a`` (:class:`tumble.physics.models.Damper`), ``(a, b, c)`` cyclic:

    ``σ = (c/2) (2/I_a − 1/I_b − 1/I_c)``  (1/s)

    > 0 about the minor axis (slow growth: the nutation widens until the body turns over to its major axis),
    < 0 about the major axis (decay): the major-axis rule. Derivation (first-order perturbation of the undamped
    eigenvalue ``λ0 = iν``, ``ν² = W² (I_a − I_b)(I_a − I_c)/(I_b I_c)``, ``λ1 = l A1 r / (l r)`` with ``l``, ``r``
    its left and right eigenvectors of the undamped linearisation and ``A1`` the damping's part): at ``c = 0``
    the body's transverse ``δw`` is the free body's nutation ``r_w = (a_bc, iν)``, ``a_bc = (I_b − I_c) W / I_b``,
    and forces the sphere's ``δs`` (turning at ``W`` in the body frame); ``l = (a_cb, iν, 0, 0)`` has no sphere part
    since the sphere does not act on the body at ``c = 0``. Then ``l A1 r`` is the body's friction on the
    relative motion, ``(δs − δw)_b / I_b`` and ``_c / I_c``, with ``W² − ν² = W² I_a (I_b + I_c − I_a)/(I_b I_c)`` in
    the sphere's response; the common factor ``I_b + I_c − I_a`` cancels and ``λ1`` is real,
    ``(2 I_b I_c − I_a (I_b + I_c)) / (2 I_a I_b I_c)``. ``J`` and ``W`` drop out: for weak damping the sphere keeps
    its inertial spin, so the relative motion is fixed by the body's nutation alone. The next term is of order
    ``c²``: the relative error goes as ``(c / (J W))²`` (measured against the Jacobian's eigenvalues for
    ``I = (2, 2.5, 1)``, ``J = 0.1``, minor axis: 6 %, 0.06 %, 6e-6 at ``c / (J W) = 0.1, 0.01, 0.001``). Kane & Levinson, *Spacecraft
    Dynamics*, §5.6 treat the same damper; the energy-sink argument (Hughes §7.5) gives the sign.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments without the sphere, kg m².
    damper_inertia : float or array_like
        ``J``, kg m², > 0 (checked; it does not enter at this order).
    damping : float or array_like
        ``c``, N m s, > 0.
    axis : int or array_like of int
        Spin axis, 1-based.

    Returns
    -------
    float or ndarray
        ``σ``, 1/s.

    Raises
    ------
    ValueError
        Invalid moments or axis; ``damper_inertia`` or ``damping`` not finite and > 0 (named).

    See Also
    --------
    tumble.models.Damper : The damper's equations.
    tumble.theory.eigenvalues : The Jacobian's eigenvalues, any damping.

    Examples
    --------
    The major-axis rule: the nutation grows about the minor axis and decays about the major one:

    >>> from tumble import theory
    >>> round(float(theory.damper_nutation_rate((2.0, 2.5, 1.0), 0.1, 0.01, 3)), 6)
    0.0055
    >>> round(float(theory.damper_nutation_rate((2.0, 2.5, 1.0), 0.1, 0.01, 2)), 6)
    -0.0035
    """
    moments = as_moments(body)
    k = _axis_index(axis)
    for name, value in (("damper_inertia", damper_inertia), ("damping", damping)):
        if not np.all(finite_array(value, name) > 0):
            raise ValueError(f"{name} must be > 0, got {value!r}")
    ia, ib, ic = _pick(moments, k), _pick(moments, (k + 1) % 3), _pick(moments, (k + 2) % 3)
    rate = 0.5 * np.asarray(damping, dtype=float) * (2.0 / ia - 1.0 / ib - 1.0 / ic)
    return float(rate) if np.ndim(rate) == 0 else rate


def _symmetric_pair(moments, axis, rtol):
    """Moments about the symmetry axis and about the (equal) transverse axes; ValueError if not equal."""
    k = _axis_index(axis)
    if k.ndim:
        raise ValueError(f"axis must be a single integer 1, 2 or 3, got {axis!r}")
    k = int(k)
    i_sym = moments[..., k]
    i_b, i_c = moments[..., (k + 1) % 3], moments[..., (k + 2) % 3]
    if not np.all(np.abs(i_b - i_c) <= rtol * np.maximum(i_b, i_c)):
        raise ValueError(
            f"body is not a symmetric top about axis {k + 1}: the other two moments differ "
            f"(I{(k + 1) % 3 + 1} = {np.asarray(i_b).ravel()[:3]}, I{(k + 2) % 3 + 1} = {np.asarray(i_c).ravel()[:3]})"
        )
    return i_sym, 0.5 * (i_b + i_c), k


def symmetric_top_precession(body, w3, *, axis=3, rtol=1e-10):
    """Body-frame precession rate of a torque-free symmetric top.

    For ``I1 = I2`` (symmetry axis 3) Euler's equations give ``w3`` constant and
    ``w1 + i w2 = (w10 + i w20) exp(i Ω t)`` with

    ``Ω = w3 (I3 − I1) / I1``

    (Landau & Lifshitz §33; DESIGN.md). ``Ω > 0`` for an oblate top (``I3 > I1``) spun with ``w3 > 0``:
    ``(w1, w2)`` turns counter-clockwise about ``+e3`` in the body frame. For another symmetry axis ``s``
    the same holds cyclically: ``w_{s+1} + i w_{s+2}`` turns at ``w_s (I_s − I_⊥)/I_⊥``.

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m²; the two moments other than ``axis`` must be equal (within ``rtol``).
    w3 : float or array_like, broadcastable to (...)
        Spin component along the symmetry axis, rad/s.
    axis : {1, 2, 3}
        The symmetry axis.
    rtol : float
        Relative tolerance for the equality of the transverse moments.

    Returns
    -------
    float or ndarray, shape (...)
        ``Ω``, rad/s, signed.

    Raises
    ------
    ValueError
        If the body is not symmetric about ``axis``, or ``w3`` is not finite.

    See Also
    --------
    tumble.theory.constant_torque_symmetric_top : The same top under a torque about its axis.
    tumble.exact.omega : The closed form of any body.

    Examples
    --------
    ``Ω = w3 (I3 − I1)/I1``:

    >>> from tumble import theory
    >>> float(theory.symmetric_top_precession((1.0, 1.0, 2.0), 3.0))
    3.0
    """
    moments = as_moments(body)
    i_sym, i_perp, _ = _symmetric_pair(moments, axis, rtol)
    omega = finite_array(w3, "w3") * (i_sym - i_perp) / i_perp
    return float(omega) if np.ndim(omega) == 0 else omega


#: Scale s(t) of the named torque profiles (N(t) = vector * s(t); tau the profile's time scale, s).
TORQUE_PROFILE_FORMULAS = {p.name: p.formula for p in registry.TORQUE_PROFILES}


def profile_integrals(profile, tau, t):
    r"""First and second time integrals of a torque profile's scale: ``S(t) = ∫0^t s``, ``∫0^t S``.

    ``s(t)`` is one of :data:`TORQUE_PROFILE_FORMULAS`; ``t >= 0`` (s). With a torque ``N s(t)`` about the
    spin axis ``a``, ``w_a(t) = w_a0 + (N_a / I_a) S(t)`` to first order in the tilt, and the phase of a
    small perturbation advances by ``sqrt(q) (w_a0 t + (N_a / I_a) ∫S)`` (exactly, in linear theory: the
    linearised equations are a constant matrix times ``w_a(t)``).

    See Also
    --------
    tumble.theory.constant_torque_symmetric_top : The symmetric top under such a torque.
    tumble.measure : A scene with a torque profile (``torque=``).

    Examples
    --------
    A ramp over 1 s, at 2 s: :math:`S = 1.5` and :math:`\int_0^2 S = 7/6`:

    >>> from tumble import theory
    >>> S, int_S = theory.profile_integrals("ramp", 1.0, 2.0)
    >>> round(float(S), 12), round(float(int_S), 12)
    (1.5, 1.166666666667)
    """
    t = np.asarray(t, dtype=float)
    if profile == "constant":
        return t, 0.5 * t**2
    if profile not in TORQUE_PROFILE_FORMULAS:
        raise ValueError(f"profile must be one of {', '.join(TORQUE_PROFILE_FORMULAS)}; got {profile!r}")
    if not tau > 0:
        raise ValueError(f"the {profile} profile needs a time scale tau > 0 s, got {tau!r}")
    if profile == "sine":
        k = 2 * np.pi / tau
        return (1 - np.cos(k * t)) / k, (t - np.sin(k * t) / k) / k
    rising, after = np.minimum(t, tau), np.maximum(t - tau, 0.0)
    if profile == "ramp":
        return rising**2 / (2 * tau) + after, rising**3 / (6 * tau) + 0.5 * tau * after + 0.5 * after**2
    return rising, 0.5 * rising**2 + tau * after  # pulse


def constant_torque_symmetric_top(body, w0, torque, t, *, axis=3, rtol=1e-10, profile="constant", tau=0.0):
    """Body-frame angular velocity of a symmetric top under a torque about its symmetry axis.

    Euler's equations ``I1 w1' = (I2 − I3) w2 w3 + N1`` (and cyclic) with ``I1 = I2`` and body torque
    ``N = (0, 0, Γ)`` give (problem sheet, problem 6, "the wobbly space station"; DESIGN.md):

    ``w3(t) = w30 + Γ t / I3``,
    ``w1 + i w2 = (w10 + i w20) exp(i β (w30 t + Γ t² / (2 I3)))``,  ``β = (I3 − I1) / I1``.

    The transverse spin keeps its magnitude and turns at the ever faster rate ``β w3(t)``. With
    ``axis = s`` the same solution is used cyclically (components ``s+1, s+2, s``). A named time profile
    ``Γ s(t)`` (``profile``, ``tau``; see :func:`profile_integrals`) replaces ``t`` by ``S(t)`` in ``w3`` and
    ``t²/2`` by ``∫S`` in the phase (``t >= 0`` then).

    Parameters
    ----------
    body : Body or array_like, shape (..., 3)
        Principal moments, kg m², symmetric about ``axis``.
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.
    torque : float or array_like, broadcastable to (...)
        Body-frame torque ``Γ`` about the symmetry axis, N m.
    t : array_like, shape (T,)
        Times, s (any order, may include negative times).
    axis : {1, 2, 3}
        The symmetry axis.
    rtol : float
        Relative tolerance for the equality of the transverse moments.

    Returns
    -------
    ndarray, shape (..., T, 3)
        ``w(t)``, rad/s; the leading shape is the broadcast of the body's, ``w0``'s and ``torque``'s.

    See Also
    --------
    tumble.theory.symmetric_top_precession : The torque-free precession rate.
    tumble.integrate : The same motion stepped, with ``torque=``.

    Examples
    --------
    The sheet's space station: ``I = (2, 2, 1)``, ``Γ = 1``, ``w0 = (0.3, 0, 1)``:

    >>> w = constant_torque_symmetric_top((2.0, 2.0, 1.0), (0.3, 0.0, 1.0), 1.0, [0.0, 1.0])
    >>> w.shape
    (2, 3)
    >>> round(float(w[1, 2]), 12)  # w3 = w30 + Γ t / I3
    2.0
    """
    moments = as_moments(body)
    i_sym, i_perp, k = _symmetric_pair(moments, axis, rtol)
    w0 = finite_array(w0, "w0")
    if w0.ndim == 0 or w0.shape[-1] != 3:
        raise ValueError(f"w0 must have shape (..., 3), got {w0.shape}")
    gamma = finite_array(torque, "torque")
    t = finite_array(t, "t")
    if t.ndim != 1:
        raise ValueError(f"t must be one-dimensional, shape (T,), got shape {t.shape}")
    b_idx, c_idx = (k + 1) % 3, (k + 2) % 3
    w_sym0 = w0[..., k]
    eta0 = w0[..., b_idx] + 1j * w0[..., c_idx]
    beta = (i_sym - i_perp) / i_perp
    # Add the time axis last to everything per-body.
    ex = lambda a: np.asarray(a)[..., None]  # noqa: E731
    first, second = profile_integrals(profile, tau, t)
    w_sym = ex(w_sym0) + ex(gamma) * first / ex(i_sym)
    phase = ex(beta) * (ex(w_sym0) * t + ex(gamma) * second / ex(i_sym))
    eta = ex(eta0) * np.exp(1j * phase)
    shape = np.broadcast_shapes(w_sym.shape, eta.shape)
    out = np.empty(shape + (3,))
    out[..., b_idx] = eta.real
    out[..., c_idx] = eta.imag
    out[..., k] = w_sym
    return out


# --- Flip timing near the intermediate axis -----------------------------------------------------------
# The closed form lives in tumble.physics.exact; these thin wrappers import it when called (so theory never fails
# to import because of exact) and carry the physics in their docstrings.


def first_flip_time(body, w0):
    """Time of the first flip of a spin, s (re-exported from :func:`tumble.physics.exact.first_flip_time`).

    A flip is a sign change of the spin component along the intermediate axis, ``w_mid`` (the body turns
    over). In the exact solution (Landau & Lifshitz §37) ``w_mid ∝ sn(u)``, ``u = u0 + ν t``, with quarter
    period ``K(m)``; the first flip is at the first zero of ``sn`` after ``u0``. Started at a maximum of
    ``|w_mid|`` (the other small component zero) it comes exactly at ``K/|ν|``, which tends to
    :func:`flip_time_asymptote` near the separatrix. See :func:`tumble.physics.exact.parameters` for ``K``, ``ν``,
    ``u0``.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body: principal moments, kg m², any order.
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    ndarray, shape (...)
        Time of the first flip after ``t = 0``, s; ``inf`` where none comes (steady spins, separatrix spins
        past their flip).

    See Also
    --------
    tumble.theory.flip_time_asymptote : Its linear-theory estimate.
    tumble.theory.flip_spacing : The time between later flips.

    Examples
    --------
    >>> from tumble import theory
    >>> round(float(theory.first_flip_time((1.0, 2.0, 3.0), [1e-3, 1.0, 0.0])), 3)
    14.366
    """
    from . import exact

    return exact.first_flip_time(body, w0)


def flip_spacing(body, w0):
    """Time between successive flips, ``2K(m)/|ν|``, s (re-exported from :func:`tumble.physics.exact.flip_spacing`).

    Half the period ``4K/|ν|`` of the body-frame motion: ``w_mid ∝ sn(u)`` changes sign at every
    ``u = 2Kj`` (Landau & Lifshitz §37).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body: principal moments, kg m², any order.
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s.

    Returns
    -------
    ndarray, shape (...)
        Flip spacing, s; ``inf`` for steady spins and on the separatrix.

    See Also
    --------
    tumble.theory.first_flip_time : The first flip.
    tumble.exact.period : The period, twice the spacing.

    Examples
    --------
    >>> from tumble import theory
    >>> round(float(theory.flip_spacing((1.0, 2.0, 3.0), [1e-3, 1.0, 0.0])), 3)
    28.731
    """
    from . import exact

    return exact.flip_spacing(body, w0)


def flip_time_asymptote(body, w0):
    r"""Linear-theory estimate of the first flip time, ``(1/λ) ln(4/k')``, s.

    Near the separatrix the complementary modulus ``k' = sqrt(1 − m)`` of the exact solution tends to 0,
    ``K(m) = ln(4/k') + O(k'² ln k')`` (Abramowitz & Stegun 17.3.26) and the elliptic frequency ``ν``
    tends to the linear growth rate ``λ`` about the intermediate axis, so ``K/|ν| → (1/λ) ln(4/k')``.
    ``k'`` is taken from :func:`tumble.physics.exact.parameters`.

    ``λ = (|L|/I2) sqrt(−q2)`` is the linear rate (:func:`linear`) for a spin about the intermediate axis
    ``I2`` (the median moment) with the same angular momentum, ``w = |L|/I2``, ``|L| = |I w0|``. ``|L|``
    is conserved, so the estimate does not depend on where along the trajectory ``w0`` is taken, and on
    the separatrix ``ν = λ`` exactly (there ``|L|/I2 = sqrt(2T/I2)``).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        One rigid body: principal moments, kg m², any order (the intermediate one is found).
    w0 : array_like, shape (..., 3)
        Initial body-frame angular velocity, rad/s, in the order of the moments.

    Returns
    -------
    ndarray, shape (...)
        Estimated flip time, s; ``inf`` where no flip happens (``k' = 0``: exactly on the separatrix, or
        no distinct intermediate axis, ``λ = 0``).

    See Also
    --------
    tumble.theory.first_flip_time : The exact first flip time.
    tumble.flip_time_law : The law measured over an amplitude scan.

    Notes
    -----
    With :math:`k'` the complementary modulus of the exact solution and :math:`\lambda` the linear growth rate about
    the intermediate axis, :math:`K(m) = \ln(4/k') + O(k'^2 \ln k')` [1]_ and :math:`|\nu| \to \lambda` give

    .. math::

        t_\mathrm{flip} \approx \frac{K(m)}{|\nu|} \to \frac{1}{\lambda} \ln\frac{4}{k'}.

    References
    ----------
    .. [1] M. Abramowitz and I. A. Stegun, *Handbook of Mathematical Functions* (Dover, 1964), 17.3.26.

    Examples
    --------
    A spin 1 mrad from the intermediate axis: the estimate matches the exact first flip to the digits shown:

    >>> from tumble import theory
    >>> round(float(theory.flip_time_asymptote((1.0, 2.0, 3.0), [1e-3, 1.0, 0.0])), 3)
    14.366
    """
    from . import exact

    moments = as_moments(body)
    w0 = finite_array(w0, "w0")
    if w0.ndim == 0 or w0.shape[-1] != 3:
        raise ValueError(f"w0 must have shape (..., 3), got {w0.shape}")
    out = flip_asymptote_from(moments, w0, np.asarray(exact.parameters(body, w0).kc, dtype=float))
    return float(out) if out.ndim == 0 else out


def flip_asymptote_from(moments, w0, kc):
    """:func:`flip_time_asymptote` from the complementary moduli ``kc`` of the spins ``w0`` (..., 3) of bodies
    ``moments`` (broadcast against ``w0``), already known (the closed form of a batch of scenes has them)."""
    mid = np.argsort(moments, axis=-1)[..., 1]
    i_mid = _pick(moments, mid)
    unit = moment_unit(moments)  # no overflow for moments of 1e200 kg m², the same bits elsewhere
    spin = np.linalg.norm((moments / unit[..., None]) * w0, axis=-1) / (i_mid / unit)
    lam = spin * np.sqrt(np.maximum(-stability_exponent(moments, mid + 1), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where((lam > 0) & (kc > 0), np.log(4.0 / kc) / lam, np.inf)
