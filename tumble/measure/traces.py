"""Traces: one sample's trajectory over a scene's horizon, the invariants' drift by method, a spin's attitude.

Curves kept beside the scenes for figures, each an integration of a few spins of its own: :func:`sample_trace`
(a scene's traced sample, the ``trace`` curve of :data:`tumble.measure.planning.CURVES`), :func:`invariant_drift`
(how each fixed-step method keeps ``|L|²`` and the kinetic energy) and :func:`attitude_trace` (the orientation of
one perturbed spin in space, for the attitude figures).
"""

from __future__ import annotations

import json
import math

import numpy as np

from .. import registry
from ..engine.ensemble import torque_spec
from ..engine.integration import integrate
from ..engine.sampling import perturbed_spins
from ..physics import exact, theory
from ..physics.bodies import one_body
from ..registry import STATUS_OK, STEPPING
from .planning import STEPS_PER_RADIAN, check_method, step_plan, validate_scene

# xarray is imported by the functions that make a dataset: a study's scenes run without it (``tumble run`` builds
# their dataset in its figure process, :mod:`tumble.pipeline.figure_process`).

__all__ = ["ATTITUDE_POINTS", "DRIFT_POINTS", "TRACE_POINTS", "attitude_trace", "invariant_drift", "sample_trace"]


#: Points of the optional curves: the traced sample's trajectory (flip_components figure).
TRACE_POINTS = 1500


def sample_trace(moments, w0, plan, method, torque, device="cpu"):
    """``(times, omega (T, 3))`` of one sample over the scene's horizon, about :data:`TRACE_POINTS` points."""
    if method == "exact":
        # exact.omega's time grid path, without its side-by-side check: the scene's samples have loaded its kernels
        times = np.linspace(0.0, plan.t_end, TRACE_POINTS)
        return times, exact.omega_apart(moments, w0, times)[0]
    every = max(1, -(-plan.n_steps // TRACE_POINTS))
    ds = integrate(moments, w0, plan.t_end, plan.dt, method=method, torque=torque, save_every=every, device=device)
    return ds.time.values, ds.omega.values[0]


def _var(value, units, long_name, dims=(), **attrs):
    import xarray as xr

    return xr.Variable(dims, value, {"units": units, "long_name": long_name, **attrs})


#: Stored times of an invariant-drift record (:func:`invariant_drift`).
DRIFT_POINTS = 200


def invariant_drift(body, axis, spin=1.0, amplitude=1e-3, methods=tuple(STEPPING), *, samples=16, seed=0,
                    horizon=None, dt=None):
    # size: a public call: the scene's options and the methods to compare
    """How each fixed-step method keeps the invariants ``|L|²`` and kinetic energy over a scene's horizon.

    Every method integrates the same ``samples`` spins (torque-free) with its own step (from its order,
    :data:`STEPS_PER_RADIAN`, unless ``dt`` is given) to the same :data:`DRIFT_POINTS` + 1 times.

    Returns
    -------
    xarray.Dataset
        ``drift_l2(drift_method, drift_time)`` and ``drift_energy(drift_method, drift_time)``: the largest
        relative error ``|X(t)/X(0) − 1|`` over the samples; ``drift_dt(drift_method)``.
    """
    import xarray as xr

    moments, axis, spin, amplitude, samples, _ = validate_scene(body, axis, spin, amplitude, samples, "auto", 0,
                                                                 "cone")
    methods = [check_method(m) for m in methods]
    if not methods or any(m in ("auto", "exact") for m in methods):
        raise ValueError(f"methods must be fixed-step methods ({', '.join(STEPPING)}), got {methods!r}")
    kind, value = theory.linear(moments, axis, spin)
    w0 = perturbed_spins(moments, axis, spin, amplitude, samples, seed=seed)
    t_end = horizon or step_plan(moments, axis - 1, kind, value, spin, amplitude, "exact", None,
                             2 if kind == "exponential" else 0, lambda: w0).t_end
    l2_0 = np.sum((moments * w0) ** 2, axis=1)[:, None]
    e_0 = np.sum(moments * w0**2, axis=1)[:, None]
    l2, energy, steps = [], [], []
    for m in methods:
        step = dt or min(1.0 / value if value > 0 else 1.0 / abs(spin), 1.0 / abs(spin)) / STEPS_PER_RADIAN[
            registry.method(m).order]
        every = max(1, math.ceil(t_end / step / DRIFT_POINTS))
        ds = integrate(moments, w0, t_end, t_end / (every * DRIFT_POINTS), method=m, save_every=every)
        w = ds.omega.values
        with np.errstate(invalid="ignore", over="ignore"):
            l2.append(np.abs(np.sum((moments * w) ** 2, axis=2) / l2_0 - 1).max(axis=0))
            energy.append(np.abs(np.sum(moments * w**2, axis=2) / e_0 - 1).max(axis=0))
        steps.append(ds.attrs["dt"])
    dims = ("drift_method", "drift_time")
    return xr.Dataset(
        {"drift_l2": _var(np.array(l2), "1", "largest relative |L|^2 error over the samples", dims),
         "drift_energy": _var(np.array(energy), "1", "largest relative kinetic-energy error over the samples",
                              dims),
         "drift_dt": _var(np.array(steps), "s", "time step of each method", ("drift_method",))},
        coords={"drift_method": _var(np.array(methods), "1", "integration method", ("drift_method",)),
                "drift_time": _var(np.linspace(0.0, t_end, DRIFT_POINTS + 1), "s", "time", ("drift_time",))},
        attrs={"drift_samples": samples})


#: Stored times of the attitude trace (the flip animation, strip, polhode and herpolhode figures).
ATTITUDE_POINTS = 1200
#: Steps per turn of the fastest component when a fixed-step method traces the attitude.
_ATTITUDE_STEPS_PER_TURN = 400


def _attitude_horizon(moments, w0, axis):
    """Three flips about the intermediate axis, else three body-frame periods (three turns for a steady spin)."""
    spacing = float(exact.flip_spacing(moments, w0))
    if axis - 1 == int(np.argsort(moments, kind="stable")[1]) and np.isfinite(spacing):
        return float(exact.first_flip_time(moments, w0)) + 2.5 * spacing
    period = float(exact.period(moments, w0))
    return 3.0 * (period if np.isfinite(period) else 2.0 * math.pi / float(np.linalg.norm(w0)))


def attitude_trace(body, axis=2, spin=1.0, amplitude=1e-3, method="auto", *, horizon=None, seed=0, torque=None,
                   shape="", shape_parameters=None, points=ATTITUDE_POINTS):
    # size: a public call: the scene's options and the shape to draw
    """The orientation of one perturbed spin in space, as the attitude figures read it.

    The spin is sample 0 of :func:`tumble.engine.sampling.perturbed_spins` (the same seed gives the same spin as a
    scene's first sample). Torque-free with ``method="auto"`` the closed form runs
    (:func:`tumble.physics.exact.attitude`); otherwise ``method`` (``rk4`` when ``"auto"``) steps the angular
    velocity and the attitude together (:mod:`tumble.kernels.steps.attitude`), about 400 steps per turn.

    Parameters
    ----------
    body : Body or array_like, shape (3,)
    axis, spin, amplitude
        The unperturbed spin (1-based axis, rad/s) and the tilt, rad.
    method : str
        ``"auto"``, ``"exact"`` or a fixed-step method.
    horizon : float, optional
        Time span, s; default three flips about the intermediate axis (the first flip time plus 2.5 flip
        spacings), else three periods of the body-frame motion.
    torque : optional
        As :func:`tumble.integrate`.
    shape, shape_parameters : str, mapping
        The :mod:`tumble.physics.shapes` function the body came from and its arguments, for drawing it.
    points : int
        Stored times (about; the fixed-step path stores every k-th step).

    Returns
    -------
    xarray.Dataset
        ``attitude_quaternion(attitude_time, quaternion_component)`` (body-to-space, scalar first; the
        space frame is the body frame at t = 0), ``attitude_omega(attitude_time, component)`` (rad/s) and
        ``attitude_moments(component)`` (kg m²); ``component`` is the principal axis (1, 2, 3), as in
        ``trace_omega``.

    See Also
    --------
    tumble.exact.attitude : The closed-form attitude it reads.
    tumble.integrate : ``attitude=True``: the attitude of a whole ensemble.

    Examples
    --------
    >>> import tumble
    >>> trace = tumble.attitude_trace((1.0, 2.0, 3.0), axis=2, points=50)
    >>> sorted(trace.data_vars)
    ['attitude_moments', 'attitude_omega', 'attitude_quaternion']
    """
    import xarray as xr

    moments = one_body(body)
    w0 = perturbed_spins(moments, axis, spin, amplitude, 1, seed=seed)
    _, params, fn, _ = torque_spec(torque)
    torque_free = params is None and fn is None
    chosen, _ = registry.choose_method(method, torque_free=torque_free)
    t_end = float(horizon) if horizon is not None else _attitude_horizon(moments, w0[0], axis)
    if chosen == "exact":
        ds = integrate(moments, w0, t_end, t_end / (points - 1), method="exact", save_every=1, attitude=True)
    else:
        dt = 2.0 * math.pi / (_ATTITUDE_STEPS_PER_TURN * float(np.abs(w0).max()))
        n_steps = max(1, math.ceil(t_end / dt))
        ds = integrate(moments, w0, t_end, t_end / n_steps, method=chosen, torque=torque,
                       save_every=max(1, n_steps // (points - 1)), attitude=True)
    if ds.status.values[0] != STATUS_OK:
        raise FloatingPointError(f"the attitude trace with {chosen} became non-finite; use a smaller step")
    attrs = {"units": "1", "long_name": "body-to-space rotation of the traced spin, unit quaternion, scalar first",
             "method": chosen, "spin_axis": int(axis), "body_shape": shape or "",
             "body_shape_json": json.dumps(dict(shape_parameters or {}), sort_keys=True)}
    return xr.Dataset(
        {"attitude_quaternion": (("attitude_time", "quaternion_component"), ds.quaternion.values[0], attrs),
         "attitude_omega": (("attitude_time", "component"), ds.omega.values[0],
                            {"units": "rad/s", "long_name": "body-frame angular velocity of the traced spin"}),
         "attitude_moments": ("component", moments, {"units": "kg m2", "long_name": "principal moments of inertia"})},
        coords={"attitude_time": ("attitude_time", ds.time.values, {"units": "s", "long_name": "time"}),
                "quaternion_component": ("quaternion_component", np.arange(4),
                                         {"long_name": "quaternion component (0: scalar part)"}),
                "component": ("component", np.array([1, 2, 3]), {"long_name": "principal axis (1-based)"})})
