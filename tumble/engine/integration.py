"""``tumble.integrate`` and ``tumble.propagate``: validate, run a fixed-step kernel or the closed form.

:func:`integrate` returns an xarray Dataset with provenance; :func:`propagate` is the lean array path (the
same validation and kernels, a plain ndarray back, no Dataset, no progress bar, no signal handling), for
calls inside a user's own loop.
"""

import math
import warnings

import numpy as np

from .. import registry
from ..kernels import METHODS, TABLEAUX
from ..physics import exact
from ..physics.bodies import finite_array, one_body, spin_vectors
from ..physics.models import FreeBody
from ..registry import STATUS_NAMES, STATUS_OK
from . import cost
from .device import check_on_device, resolve_device, stepper
from .ensemble import check_torque_step, checked_torque, run_planned
from .adaptive_runs import fixed_steps_only, no_save_every, run_adaptive, run_attrs, run_variables, warn_stops
from .system_runs import added_tableau, is_system, no_body_parameters, run_system
from .torqued_body import ATTITUDE, body_system, unit_quaternions

__all__ = ["integrate", "propagate", "METHOD_NAMES"]

METHOD_NAMES = tuple(m.name for m in registry.METHODS)

# t_end / dt within this relative distance of an integer counts as that integer (no extra short step).
_STEP_COUNT_SLACK = 1e-9


def _scalar(value, name):
    if type(value) is float or type(value) is int:  # the common case without an array round trip
        try:
            x = float(value)
        except OverflowError:  # an int beyond the float range
            x = math.inf
        if not math.isfinite(x):
            raise ValueError(f"{name} must be finite (found NaN or inf)")
        return x
    x = finite_array(value, name)
    if x.ndim:
        raise ValueError(f"{name} must be a number, got shape {x.shape}")
    return float(x)


def _initial_spins(w0):
    w = spin_vectors(w0)
    if w.ndim == 1:
        w = w[None, :]
    if w.ndim != 2:
        raise ValueError(f"w0 must have shape (N, 3) (N spins, rad/s, body frame), got shape {w.shape}")
    if w.shape[0] == 0:
        raise ValueError("w0 holds no spins (shape (0, 3))")
    return w


def _bounded_step_plan(t_end, dt, w, save_every, *, exact_path, per_state=3, device="cpu", attitude=False):
    """:func:`_step_plan` after the cost bound (:func:`tumble.engine.cost.refuse`) of the spins ``w`` keeping
    ``per_state`` values per stored state (a trajectory with ``save_every``, else the final state); the closed form is
    evaluated at each stored state, and ``attitude`` is carried by the steps or the closed form."""
    steps = t_end / dt
    states = steps / save_every + 2 if save_every else 2
    cost.refuse(cost.run_cost(len(w), 0 if exact_path else steps, per_state * states, times=states, attitude=attitude),
                f"w0 ({len(w):,} spins) over t_end / dt = {steps:.3g} steps", device)
    return _step_plan(t_end, dt)


def _checked_run(w, t_end, dt, method, torque, save_every, device, *, per_state=3, attitude=False):
    # size: integrate's and propagate's arguments that the run's checks need, each checked once here
    """What :func:`integrate` and :func:`propagate` check of a free body's run, each once, before anything runs: the
    device (resolved by the caller, :func:`tumble.engine.device.resolve_device`), the torque (:func:`tumble.engine.ensemble.checked_torque`),
    the method it allows (``registry.choose_method``: ``"exact"`` is torque-free), the cost bound
    (:func:`_bounded_step_plan`) and the torque profile's step rule at the step that runs. Returns ``(device,
    torque, chosen method, reason, n_steps, step)``, which the engine's run trusts
    (:func:`tumble.engine.ensemble.run_planned`)."""
    torque = checked_torque(torque)
    chosen, reason = registry.choose_method(method, torque_free=torque.free)
    n_steps, step = _bounded_step_plan(t_end, dt, w, save_every, exact_path=chosen == "exact", per_state=per_state,
                                       device=device, attitude=attitude)
    check_torque_step(torque, step)
    if device == "cuda":
        check_on_device(chosen, torque_fn=torque.fn)
    return device, torque, chosen, reason, n_steps, step


def _step_plan(t_end, dt):
    """Number of steps and the step that lands exactly on ``t_end``."""
    if t_end == 0.0:
        return 0, dt
    ratio = t_end / dt
    n_steps = round(ratio)
    if n_steps == 0 or abs(ratio - n_steps) > _STEP_COUNT_SLACK * ratio:
        n_steps = math.ceil(ratio)
    return n_steps, t_end / n_steps


def checked_save_every(save_every):
    """``save_every`` as given (None or a whole number of steps >= 1); ValueError otherwise."""
    if save_every is not None:
        if isinstance(save_every, bool) or not isinstance(save_every, (int, np.integer)) or save_every < 1:
            raise ValueError(f"save_every must be None or an integer >= 1 (steps), got {save_every!r}")
    return save_every


def _horizon_and_step(t_end, dt):
    t_end = _scalar(t_end, "t_end")
    if t_end < 0:
        raise ValueError(f"t_end must be >= 0 s, got {t_end}")
    dt = _scalar(dt, "dt")
    if dt <= 0:
        raise ValueError(f"dt must be > 0 s, got {dt}")
    return t_end, dt


def _has_torque(torque):
    """Whether ``torque`` (as :func:`integrate` and :func:`propagate` take it) asks for one: not None nor zeros."""
    return torque is not None and (callable(torque) or hasattr(torque, "items") or np.any(np.asarray(torque) != 0))


def _no_torque_or_attitude(system, torque, attitude):
    """A model or a System carries its torques in its own equations: refuse a ``torque`` or ``attitude`` for it."""
    name = system.name if hasattr(system, "rate") else f"the {system.kind} model"
    if attitude:
        raise ValueError(f"attitude=True integrates a free body's orientation; {name!r} has its state's own "
                         f"components (give the attitude as part of its state)")
    if _has_torque(torque):
        raise ValueError(f"torque acts on a free body; {name!r} has its torques in its own equations (write them "
                         f"into its rate)")


def _free_body_by_tableau(body, w0, t_end, dt, method, torque, save_every, attitude, device):
    # size: integrate's and propagate's arguments, each checked or passed on once
    """A ``Body`` stepped by a tableau added at run time (:func:`added_tableau`): ``(SystemRun, single)``."""
    if attitude or _has_torque(torque):
        raise ValueError(f"method {method!r}, a tableau added at run time, steps a free body torque-free and without "
                         f"its attitude (the per-sample loop of tumble.models.FreeBody); a torque or attitude=True "
                         f"needs one of {', '.join(m for m in METHOD_NAMES if m != 'exact')}")
    return _system_run(FreeBody(one_body(body)), w0, t_end, dt, method, None, save_every, None, device)


def _adaptive_run(body, w0, t_end, dt, torque, save_every, attitude, parameters, device, tolerance):
    # size: integrate's and propagate's arguments, each checked or passed on once
    """An error-controlled run (:func:`tumble.engine.adaptive_runs.run_adaptive`) of a system, or of a ``Body``: as
    :class:`tumble.models.FreeBody` torque-free, else with its torque and attitude as one System
    (:func:`tumble.engine.torqued_body.torqued_body`). ``(AdaptiveRun, single, torque)``: ``torque`` the checked
    torque of a ``Body`` (None: a system). ``tolerance``: ``(rtol, atol, times, max_steps)``."""
    rtol, atol, times, max_steps = tolerance
    no_save_every(save_every)
    checked = None
    if is_system(body):
        _no_torque_or_attitude(body, torque, attitude)
        system, name = body, "y0"
    else:
        no_body_parameters(parameters)
        checked = checked_torque(torque)
        system, parameters = body_system(one_body(body), checked, attitude, device)
        name = "w0"
        if attitude:  # the body frame is the space frame at t = 0
            w = _initial_spins(w0)
            w0 = np.hstack([w, np.tile([1.0, 0.0, 0.0, 0.0], (len(w), 1))])
    run, single = run_adaptive(system, w0, t_end, times=times, rtol=rtol, atol=atol, first_step=dt,
                               max_steps=max_steps, parameters=parameters, device=device, y0_name=name)
    return run, single, checked


def _system_run(system, y0, t_end, dt, method, torque, save_every, parameters, device, attitude=False):
    # size: integrate's and propagate's arguments, passed on once for both
    _no_torque_or_attitude(system, torque, attitude)
    t_end, dt = _horizon_and_step(t_end, dt)
    n_steps, step = _step_plan(t_end, dt)
    return run_system(system, y0, t_end, n_steps, step, method, save_every=checked_save_every(save_every),
                      parameters=parameters, device=device)


def propagate(body, w0, t_end, dt=None, method="rk4", *, torque=None, save_every=None, parameters=None, device="cpu",
              rtol=None, atol=None, max_steps=None):
    # size: the contract's arguments (DESIGN.md): the free body's, a system's parameters, the device, a tolerance
    """Integrate Euler's equations and return the spins as an array: the lean path of :func:`integrate`.

    The same validation, step plan and kernels as :func:`integrate` (the results are the same bits), without
    building a Dataset: for a user's own loops, where the per-call cost matters (measured in
    ``benchmarks/engine.py``). One exception: the closed form's final state alone (``method="exact"``, no
    ``save_every``) comes from the fused one-time kernel (:func:`tumble.physics.exact.omega_at`), which agrees
    with :func:`integrate` to a few ulps of ``|w|``, not bit for bit.

    Parameters
    ----------
    body : Body, array_like (3,), model or System
        Principal moments of inertia, kg m² (the free body); or a built-in model (:mod:`tumble.models`) or a user's
        :class:`tumble.System`, whose states ``w0`` then are (as :func:`integrate`).
    w0 : array_like, shape (N, 3) or (3,)
        Initial body-frame angular velocities, rad/s; a system's states, shape (N, n) or (n,).
    t_end, dt : float
        Horizon (>= 0) and step (> 0), s; the step is shortened to ``t_end / ceil(t_end / dt)`` when
        ``t_end / dt`` is not a whole number, so that the run ends exactly at ``t_end``. With ``method="dop853"``
        ``dt`` is the first step (None: chosen).
    method : str
        A fixed-step method, ``"exact"`` (:data:`tumble.registry.METHODS`) or ``"auto"`` (the closed form when
        torque-free, else ``rk4``); or a tableau added at run time (as :func:`integrate`); or ``"dop853"``, error
        controlled (as :func:`integrate`).
    torque : None, array_like (3,), mapping or callable
        As :func:`integrate` (``None`` or zero: torque-free).
    save_every : int, optional
        None: only the final state. ``k``: the initial state, every k-th step and the final one.
    parameters : mapping, optional
        A model's or System's parameters, by name, in place of its own (as :func:`integrate`).
    device : str
        ``"cpu"`` or ``"cuda"`` (:func:`tumble.engine.device.resolve_device`; the closed form too, one thread per
        sample: :func:`tumble.physics.exact.omega_on_device`; not yet a torque function).
    rtol, atol, max_steps
        ``method="dop853"`` only: as :func:`integrate`.

    Returns
    -------
    ndarray
        Shape ``(N, 3)`` (rad/s, final state) or ``(N, T, 3)`` with ``save_every``; a ``(3,)`` spin gives
        ``(3,)`` or ``(T, 3)``; a system's ``(N, n)`` or ``(N, T, n)``. The states are stepped as they come: a sample that became non-finite is NaN
        or inf (check with ``numpy.isfinite``). With ``method="dop853"`` a sample that stopped before ``t_end``
        (step limit, step underflow, a rate that returned NaN) holds the finite state it stopped with, and a
        ``RuntimeWarning`` says how many stopped and why (:func:`integrate`'s ``status`` says which).

    Raises
    ------
    ValueError
        Invalid moments, spins, horizon, step, method, torque or save interval, or ``"exact"`` with a torque; a
        device that is unknown, missing, or cannot run this yet (``device 'cuda': ...``).

    See Also
    --------
    tumble.integrate : The same run as a Dataset, with stored times and the attitude.
    tumble.run_ensemble : The same steps with observers on the fly.

    Examples
    --------
    >>> import numpy as np, tumble
    >>> body = tumble.Body(1.0, 2.0, 3.0)
    >>> w = tumble.propagate(body, [[0.01, 1.0, 0.0]], 2.0, 0.01)
    >>> w.shape
    (1, 3)
    >>> bool(np.allclose(w, tumble.exact.omega(body, [[0.01, 1.0, 0.0]], 2.0), atol=1e-8))
    True
    """
    device = resolve_device(device)  # once, here at the door: the runs below trust it
    if method in registry.ERROR_CONTROLLED:
        run, single, _ = _adaptive_run(body, w0, t_end, dt, torque, save_every, False, parameters, device,
                                       (rtol, atol, None, max_steps))
        warn_stops(run.status, len(run.final), run.name, stacklevel=1)  # their states are finite: say it
        return run.final[0] if single else run.final
    fixed_steps_only(method, dt, rtol, atol, None, max_steps)
    if is_system(body) or (added_tableau(method) and parameters is None):
        result, single = (_system_run(body, w0, t_end, dt, method, torque, save_every, parameters, device)
                          if is_system(body) else
                          _free_body_by_tableau(body, w0, t_end, dt, method, torque, save_every, False, device))
        out = result.trajectory if save_every else result.final
        return out[0] if single else out
    no_body_parameters(parameters)
    moments = one_body(body)
    single = np.ndim(w0) == 1
    w = _initial_spins(w0)
    t_end, dt = _horizon_and_step(t_end, dt)
    save_every = checked_save_every(save_every)
    device, (kind, params, fn, _), chosen, _, n_steps, step = _checked_run(w, t_end, dt, method, torque, save_every,
                                                                            device)
    if chosen == "exact" and not save_every:
        out = exact.omega_at(moments, w, t_end) if device == "cpu" else exact.omega_on_device(
            moments, w, np.array([t_end]))[:, 0]
    elif chosen == "exact":  # the stepping path's store times: 0, k, 2k, ..., and the end
        steps = np.arange(0, n_steps + 1, save_every)
        times = np.append(steps, n_steps) if steps[-1] != n_steps else steps
        times = times * step
        times[-1] = t_end
        out = exact.omega(moments, w, times) if device == "cpu" else exact.omega_on_device(moments, w, times)
    else:
        state = np.array(w.T, order="C")
        observed = stepper(device)(METHODS[chosen], state, moments, 0.0, step, n_steps, save_every=save_every or 0,
                                   torque_kind=kind, torque_params=params, torque_fn=fn)
        out = observed.saved.transpose(2, 0, 1) if save_every else state.T
    return out[0] if single else out


def integrate(body, w0, t_end, dt=None, method="rk4", torque=(0, 0, 0), save_every=None, attitude=False, *,
              parameters=None, device="cpu", rtol=None, atol=None, times=None, max_steps=None):
    # size: the contract's eight arguments (DESIGN.md), a system's parameters and the device keyword every engine
    # call takes
    r"""Integrate Euler's equations for an ensemble of initial spins.

    ``I1 w1' = (I2 - I3) w2 w3 + N1`` and cyclic, in the principal-axis (body) frame, with a fixed step, or
    evaluated in closed form (``method="exact"``, torque-free only).

    A built-in model (:mod:`tumble.models`: ``HeavyTop``, ``GravityGradient``, ...) or a user's
    :class:`tumble.System` in place of the body integrates that system's equations instead, on the same fixed steps
    (rk4, rk8; the Lie–Poisson splittings for the models that have them): its states ``w0`` have shape (N, n), and
    the Dataset holds ``state(sample, time, component)`` with the component names of the system (``spec.state``).

    ``method="dop853"`` takes a tolerance instead of a step, for any of them (a free body with a torque or its
    attitude on the CPU, as one System: :mod:`tumble.engine.torqued_body`): Dormand and Prince's eighth-order pair
    with Hairer's step-size control, each sample its own steps, the states at ``times`` read off its dense output of
    order 7 (:mod:`tumble.kernels.loops.adaptive_loop`).

    Parameters
    ----------
    body : Body, array_like (3,), model or System
        Principal moments of inertia, kg m² (the free body); or the system to integrate.
    w0 : array_like, shape (N, 3)
        Initial body-frame angular velocities, rad/s (a single spin of shape (3,) is taken as N = 1); a system's
        initial states, shape (N, n) (or (n,)).
    t_end : float
        Horizon, s (>= 0).
    dt : float
        Step, s (> 0). When ``t_end / dt`` is not an integer the step is shortened to
        ``t_end / ceil(t_end / dt)`` so the run ends exactly at ``t_end``; the step used is in
        ``attrs["dt"]``. With ``method="dop853"``: the first step (None: chosen).
    method : str
        One of ``"rk4"``, ``"rk8"``, ``"symplectic_euler"``, ``"splitting2"``, ``"splitting4"``,
        ``"implicit_midpoint"``, ``"exact"``; or a Butcher tableau added to :data:`tumble.kernels.TABLEAUX` at run
        time (torque-free, without the attitude: the per-sample loop, as :class:`tumble.models.FreeBody`); or
        ``"dop853"``, error-controlled.
    torque : array_like, shape (3,), or callable
        Body-frame torque, N m: three constants, or a function ``f(t, w1, w2, w3) -> (N1, N2, N3)``
        (numba-jitted, or jittable in nopython mode). Zero torque is compiled out of the kernel.
    save_every : int, optional
        None stores only the final state; ``k`` stores the initial state, every k-th step and the final one.
    attitude : bool
        Also integrate the orientation: ``quaternion(sample, time, component)``, the unit quaternion (scalar
        first) of the body-to-space rotation, ``v_space = q v_body q*``, with the space frame equal to the body
        frame at ``t = 0``. Every method carries it in its own way (:mod:`tumble.kernels.steps.attitude`); ``"exact"``
        gives it in closed form (:func:`tumble.physics.exact.attitude`); ``"dop853"`` steps it with the spin, to the
        tolerance, and scales the quaternions it returns to unit length. Without it no attitude code runs.
    parameters : mapping, optional
        A model's or a System's parameters, by name, in place of its own (a free body has none).
    device : str
        ``"cpu"`` or ``"cuda"`` (as :func:`propagate`; recorded in ``attrs["device"]``; ``"dop853"`` runs on the
        CPU).
    rtol, atol : float or array_like (n,), optional
        ``method="dop853"``: the tolerance of each step's error estimate, ``|err_j| <= atol_j + rtol_j |y_j|`` in
        Hairer's norm; scalars or one per state component (None: 1e-10 and 1e-12; ``rtol >= 1e-14``).
    times : array_like, optional
        ``method="dop853"``: the output times, s, increasing within ``[0, t_end]`` (None: ``t_end``).
    max_steps : int, optional
        ``method="dop853"``: the steps (accepted and rejected) a sample may take (None: 1 000 000); one that needs
        more stops with status "step limit", one whose step underflows with "step underflow" ("non-finite" where
        the rate returns NaN or infinity however short the step).

    Returns
    -------
    xarray.Dataset
        ``omega(sample, time, axis)``, rad/s, with coordinates ``sample``, ``time`` (s) and ``axis`` (1, 2, 3)
        and attributes recording the method, step, step count and torque; with ``attitude=True`` also
        ``quaternion(sample, time, component)`` (component 0 the scalar part). For a system:
        ``state(sample, time, component)``, ``component`` the names of its state, ``status(sample)``, and the
        system's name and parameters in the attributes. With ``method="dop853"`` also ``steps(sample)`` and
        ``rejected_steps(sample)``, ``rtol`` and ``atol`` in the attributes, and ``status`` with the step control's
        stops (:data:`tumble.registry.ADAPTIVE_STATUSES`).

    Raises
    ------
    ValueError
        Invalid moments, spins, horizon, step, method, torque or save interval, or ``"exact"`` with a torque.

    See Also
    --------
    tumble.propagate : The same steps, the final states as an array.
    tumble.run_ensemble : The same steps with observers on the fly.
    tumble.exact.omega : The closed form ``method="exact"`` evaluates.
    tumble.sampling.perturbed_spins : An ensemble of perturbed initial spins.

    Notes
    -----
    Euler's equations in the principal-axis frame, with a body-frame torque :math:`\mathbf N` [1]_:

    .. math::

        I_1 \dot\omega_1 = (I_2 - I_3)\,\omega_2 \omega_3 + N_1, \quad
        I_2 \dot\omega_2 = (I_3 - I_1)\,\omega_3 \omega_1 + N_2, \quad
        I_3 \dot\omega_3 = (I_1 - I_2)\,\omega_1 \omega_2 + N_3.

    Torque-free they keep the kinetic energy :math:`T = \tfrac12 \sum_i I_i \omega_i^2` and
    :math:`|L|^2 = \sum_i I_i^2 \omega_i^2`. The Lie–Poisson splittings (``"symplectic_euler"``, ``"splitting2"``,
    ``"splitting4"``) compose the exact flows of the parts of the energy [2]_. ``"dop853"`` is
    Dormand and Prince's eighth-order pair with its seventh-order dense output, as in Hairer's DOP853 [3]_.

    References
    ----------
    .. [1] L. D. Landau and E. M. Lifshitz, *Mechanics*, 3rd ed. (Pergamon, 1976), §36.
    .. [2] R. I. McLachlan, "Explicit Lie-Poisson integration and the Euler equations", Phys. Rev. Lett. 71,
       3043 (1993).
    .. [3] E. Hairer, S. P. Nørsett and G. Wanner, *Solving Ordinary Differential Equations I*, 2nd ed.
       (Springer, 1993), ch. II.

    Examples
    --------
    Two spins of ``I = (1, 2, 3)`` stepped by rk4 for 2 s, stored every 50 steps, against the closed form:

    >>> import tumble
    >>> body, w0 = tumble.Body(1.0, 2.0, 3.0), [[0.01, 1.0, 0.0], [0.0, 0.0, 1.0]]
    >>> ds = tumble.integrate(body, w0, t_end=2.0, dt=0.01, save_every=50)
    >>> dict(ds["omega"].sizes), ds.attrs["method"]
    ({'sample': 2, 'time': 5, 'axis': 3}, 'rk4')
    >>> exact = tumble.integrate(body, w0, t_end=2.0, dt=0.01, method="exact", save_every=50)
    >>> bool(abs(ds["omega"] - exact["omega"]).max() < 1e-8)
    True
    """
    device = resolve_device(device)  # once, here at the door: the runs below trust it
    if method in registry.ERROR_CONTROLLED:
        run, _, checked = _adaptive_run(body, w0, t_end, dt, torque, save_every, attitude, parameters, device,
                                        (rtol, atol, times, max_steps))
        return _adaptive_dataset(run, None if is_system(body) else (one_body(body), checked), device)
    fixed_steps_only(method, dt, rtol, atol, times, max_steps)
    if is_system(body):
        return _system_dataset(*_system_run(body, w0, t_end, dt, method, torque, save_every, parameters, device,
                                            attitude), t_end, device)
    no_body_parameters(parameters)
    moments = one_body(body)
    if added_tableau(method):
        run, _ = _free_body_by_tableau(moments, w0, t_end, dt, method, torque, save_every, attitude, device)
        t_end = float(t_end)  # checked by the run
        computed = int(run.steps_taken.sum())
        info = {"path": "per-sample loop", "torque": "none", "sample_steps_computed": computed,
                "sample_steps_skipped": len(run.final) * run.n_steps - computed, "device": device}
        return _free_body_dataset(run.trajectory if save_every else run.final[:, None],
                                  run.times if save_every else np.array([t_end]), run.status, None, method, run.dt,
                                  run.n_steps, t_end, moments, info)
    w = _initial_spins(w0)
    t_end, dt = _horizon_and_step(t_end, dt)
    if method not in METHOD_NAMES:
        added = [name for name in TABLEAUX if name not in METHOD_NAMES]
        raise ValueError(f"method must be one of {', '.join(METHOD_NAMES + tuple(added))}; got {method!r}")
    save_every = checked_save_every(save_every)
    device, torque, _, reason, n_steps, step = _checked_run(w, t_end, dt, method, torque, save_every, device,
                                                            per_state=7 if attitude else 3, attitude=bool(attitude))
    # Every argument is checked above (the engine's run trusts them: tumble.engine.ensemble.run_planned). A plain
    # integration returns what the method computes: no early stop, no drift flagging. The final state
    # alone is the driver's final-state path, as tumble.propagate's (the same bits, and no trajectory to store: 0.1 ms
    # less for 2000 spins and 200 rk4 steps); with the attitude it is read off a trajectory of two states (start, end).
    trajectory = bool(save_every or attitude)
    result = run_planned(moments, w, t_end, step, method=method, reason=reason, torque=torque, final=not trajectory,
                         save_every=(save_every or max(n_steps, 1)) if trajectory else None, drift_limit=0.0,
                         progress=False, attitude=bool(attitude), device=device)
    omega = (result.trajectory if save_every else result.trajectory[:, -1:, :]) if trajectory else result.final[:, None]
    times = result.times if save_every else np.array([t_end])
    quaternion = (result.quaternion if save_every else result.quaternion[:, -1:, :]) if attitude else None
    return _free_body_dataset(omega, times, result.status, quaternion, method, step,
                              n_steps if method != "exact" else 0, t_end, moments, result.info)


def _free_body_dataset(omega, times, status, quaternion, method, step, n_steps, t_end, moments, info):
    # size: the Dataset's contents, each once
    """:func:`integrate`'s Dataset of a free body: ``omega(sample, time, axis)``, ``status``, with ``quaternion`` (not
    None) the attitude; ``info`` the run's (its path, torque, sample-steps and device)."""
    n_bad = int(np.count_nonzero(status != STATUS_OK))
    if n_bad:
        warnings.warn(f"{n_bad} of {len(omega)} samples became non-finite (step too large for the spin rate?)",
                      RuntimeWarning, stacklevel=3)
    variables = {
        "omega": (("sample", "time", "axis"), omega, {"units": "rad/s", "long_name": "body-frame angular velocity"}),
        "status": ("sample", status, {"long_name": "sample status", "flag_values": _FLAG_VALUES.copy(),
                                      "flag_meanings": _FLAG_MEANINGS}),
        "sample": ("sample", np.arange(len(omega)), {"long_name": "ensemble member"}),
        "time": ("time", times, {"units": "s", "long_name": "time"}),
        "axis": ("axis", np.array([1, 2, 3]), {"long_name": "principal axis (1-based)"}),
    }
    if quaternion is not None:
        variables.update(_quaternion_variables(quaternion))
    attrs = {
        "method": method,
        "order": _order(method),
        "path": info["path"],
        "dt": step,
        "n_steps": n_steps,
        "t_end": t_end,
        "moments": moments,
        "torque": info["torque"],
        "n_nonfinite": n_bad,
        "sample_steps_computed": info["sample_steps_computed"],
        "sample_steps_skipped": info["sample_steps_skipped"],
        "attitude": int(quaternion is not None),  # 0: no attitude code ran
        "device": info["device"],
    }
    return indexed_dataset(variables, attrs)


def _quaternion_variables(quaternion):
    """The Dataset's ``quaternion(sample, time, component)`` and its ``component`` coordinate."""
    return {"quaternion": (("sample", "time", "component"), quaternion,
                           {"units": "1", "long_name": "body-to-space rotation, unit quaternion, scalar first"}),
            "component": ("component", np.arange(4), {"long_name": "quaternion component (0: scalar part)"})}


def _system_dataset(result, single, t_end, device):
    """:func:`integrate`'s Dataset of a model's or a System's run: ``state(sample, time, component)``."""
    del single  # a Dataset always has the sample dimension
    state = result.trajectory if result.trajectory is not None else result.final[:, None]
    times = result.times if result.times is not None else np.array([t_end])
    n_bad = int(np.count_nonzero(result.status != STATUS_OK))
    if n_bad:
        warnings.warn(f"{n_bad} of {len(state)} samples of {result.name!r} became non-finite (their state is the last "
                      f"finite one; status says which)", RuntimeWarning, stacklevel=3)
    variables = {
        "state": (("sample", "time", "component"), state,
                  {"units": result.units[0] if len(set(result.units)) == 1 else "see component_units",
                   "long_name": f"state of {result.name}"}),
        "status": ("sample", result.status, {"long_name": "sample status", "flag_values": _FLAG_VALUES.copy(),
                                             "flag_meanings": _FLAG_MEANINGS}),
        "sample": ("sample", np.arange(len(state)), {"long_name": "ensemble member"}),
        "time": ("time", times, {"units": "s", "long_name": "time"}),
        "component": ("component", np.array(result.components), {"long_name": "state component"}),
        "component_units": ("component", np.array(result.units), {"long_name": "units of each state component"}),
    }
    attrs = {
        "system": result.name,
        "method": result.method,
        "order": _order(result.method),
        "dt": result.dt,
        "n_steps": result.n_steps,
        "t_end": t_end,
        "n_nonfinite": n_bad,
        "device": device,
        **{f"parameter_{key}": value for key, value in result.parameters.items()},
    }
    return indexed_dataset(variables, attrs)


def _adaptive_dataset(run, body, device):
    """:func:`integrate`'s Dataset of an error-controlled run: a free body's ``omega(sample, time, axis)`` (``body``
    its moments and checked torque), with its ``quaternion`` where the run carried the attitude, or a system's
    ``state(sample, time, component)``; with each sample's steps and rejected steps."""
    stopped = run.status != STATUS_OK
    warn_stops(run.status, len(run.final), run.name, stacklevel=3)
    if body is not None:
        moments, torque = body
        attitude = run.states.shape[-1] == len(ATTITUDE)
        omega, quaternion = unit_quaternions(run.states) if attitude else (run.states, None)
        variables = {
            "omega": (("sample", "time", "axis"), omega, {"units": "rad/s",
                                                          "long_name": "body-frame angular velocity"}),
            "axis": ("axis", np.array([1, 2, 3]), {"long_name": "principal axis (1-based)"}),
        }
        if attitude:
            variables.update(_quaternion_variables(quaternion))
        attrs = {"moments": moments, "torque": torque.text, "attitude": int(attitude)}
    else:
        variables = {
            "state": (("sample", "time", "component"), run.states,
                      {"units": run.units[0] if len(set(run.units)) == 1 else "see component_units",
                       "long_name": f"state of {run.name}"}),
            "component": ("component", np.array(run.components), {"long_name": "state component"}),
            "component_units": ("component", np.array(run.units), {"long_name": "units of each state component"}),
        }
        attrs = {"system": run.name, **{f"parameter_{key}": value for key, value in run.parameters.items()}}
    variables.update({
        **run_variables(run),
        "sample": ("sample", np.arange(len(run.final)), {"long_name": "ensemble member"}),
        "time": ("time", run.times, {"units": "s", "long_name": "time"}),
    })
    attrs.update({**run_attrs(run), "n_stopped": int(stopped.sum()), "path": f"error-controlled, {run.path}",
                  "device": device})
    return indexed_dataset(variables, attrs)


_FLAG_VALUES = np.arange(len(STATUS_NAMES), dtype=np.int8)
_FLAG_MEANINGS = " ".join(name.replace(" ", "_") for name in STATUS_NAMES)


def _order(method):
    """The nominal order of ``method``: a kernel method's, a tableau's added at run time, or -1 (the closed form)."""
    found = METHODS.get(method) or TABLEAUX.get(method)
    return found.order if found is not None else -1


def indexed_dataset(variables, attrs, coords=()):
    """``xarray.Dataset`` of ``variables`` (name -> ``(dims, ndarray, attrs)``), those named after their one dimension
    being its indexed coordinates and those named in ``coords`` coordinates without an index (a scene's scalar
    parameters): what ``xr.Dataset(data_vars, coords, attrs)`` builds, in a tenth of its time.

    The public constructor aligns and merges its arguments and infers each index (0.4 ms for :func:`integrate`'s
    five variables, more than a 2000-spin rk4 run of 200 steps takes); here they are known to be aligned, so the
    variables and their pandas indexes are made directly and handed to ``Dataset._construct_direct``, xarray's own
    constructor of a Dataset from its parts (present since 2017; ``tests/test_latency.py`` checks the result is
    ``identical`` to the public constructor's). Should a future xarray drop it, the public constructor is used.
    The variables take xarray's ``fastpath`` (their data are numpy arrays already) and the indexes a ``pandas.Index``:
    xarray's checks for duck arrays would import ``dask.array`` in a new process (0.8 s, more than a warm
    :func:`integrate` takes otherwise; ``tests/test_first_call.py`` holds that the call does not import dask).
    """
    import xarray as xr  # here, not at the top: the scenes of a study import this module and run without xarray

    made = {name: xr.Variable(dims, np.asarray(values), dict(var_attrs), fastpath=True)
            for name, (dims, values, var_attrs) in variables.items()}
    indexed = [name for name, var in made.items() if var.dims == (name,)]
    coord_names = set(indexed) | set(coords)
    build = getattr(xr.Dataset, "_construct_direct", None)
    if build is None:
        return xr.Dataset({n: v for n, v in made.items() if n not in coord_names},
                          coords={n: v for n, v in made.items() if n in coord_names}, attrs=attrs)
    sizes = {dim: size for var in made.values() for dim, size in zip(var.dims, var.shape)}
    indexes = {name: _index(name, made[name]) for name in indexed}
    made.update({name: index.create_variables({name: made[name]})[name] for name, index in indexes.items()})
    return build(made, coord_names, sizes, dict(attrs), indexes)


def _index(name, variable):
    """The pandas index of the coordinate ``variable``. The last few small ones of each name are reused while their
    values are the same (an index is immutable: xarray shares one between a Dataset and its copies, selections and
    results): building one costs 30-60 us, comparing a few thousand values 2 us."""
    import pandas as pd
    import xarray as xr

    values = variable.values
    for key, index in _INDEXES.get(name, ()):
        if key.shape == values.shape and key.dtype == values.dtype and np.array_equal(key, values):
            return index
    index = xr.indexes.PandasIndex(pd.Index(values), name, coord_dtype=values.dtype)
    if values.size <= _REUSED_INDEX_SIZE:
        _INDEXES[name] = [(values.copy(), index)] + _INDEXES.get(name, [])[:3]
    return index


_INDEXES = {}  # coordinate name -> [(values, PandasIndex)], newest first
_REUSED_INDEX_SIZE = 1 << 16  # larger coordinates are indexed anew: their run costs far more, and memory is kept free
