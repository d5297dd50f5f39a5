"""``tumble.integrate``: validate, run a fixed-step kernel or the closed form, return an xarray Dataset."""

import math
import warnings

import numba
import numpy as np
import xarray as xr

from . import exact
from .bodies import finite_array, one_body, spin_vectors
from .kernels.methods import METHODS, run
from .kernels.steppers import TORQUE_CONSTANT, TORQUE_USER

__all__ = ["integrate", "METHOD_NAMES"]

METHOD_NAMES = (*METHODS, "exact")

# t_end / dt within this relative distance of an integer counts as that integer (no extra short step).
_STEP_COUNT_SLACK = 1e-9


def _scalar(value, name):
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


def _step_plan(t_end, dt):
    """Number of steps and the step that lands exactly on ``t_end``."""
    if t_end == 0.0:
        return 0, dt
    ratio = t_end / dt
    n_steps = round(ratio)
    if n_steps == 0 or abs(ratio - n_steps) > _STEP_COUNT_SLACK * ratio:
        n_steps = math.ceil(ratio)
    return n_steps, t_end / n_steps


def _torque(torque):
    """``(kind, params, fn, description)``; params and fn ``None`` when torque-free."""
    if callable(torque):
        fn = torque if isinstance(torque, numba.core.registry.CPUDispatcher) else numba.njit(torque)
        return TORQUE_USER, None, fn, f"function {getattr(torque, '__name__', repr(torque))}(t, w1, w2, w3)"
    try:
        params = np.array(torque, dtype=float)
    except (TypeError, ValueError) as err:
        raise ValueError(f"torque must be 3 numbers (N m, body frame) or a function, got {torque!r}") from err
    if params.shape != (3,):
        raise ValueError(f"torque must have shape (3,) (N m, body frame), got shape {params.shape}")
    if not np.all(np.isfinite(params)):
        raise ValueError(f"torque must be finite, got {params.tolist()}")
    if not params.any():
        return TORQUE_CONSTANT, None, None, "none"
    return TORQUE_CONSTANT, params, None, f"constant {params.tolist()} N m"


def integrate(body, w0, t_end, dt, method="rk4", torque=(0, 0, 0), save_every=None, attitude=False):
    """Integrate Euler's equations for an ensemble of initial spins.

    ``I1 w1' = (I2 - I3) w2 w3 + N1`` and cyclic, in the principal-axis (body) frame, with a fixed step, or
    evaluated in closed form (``method="exact"``, torque-free only).

    Parameters
    ----------
    body : Body or array_like, shape (3,)
        Principal moments of inertia, kg m².
    w0 : array_like, shape (N, 3)
        Initial body-frame angular velocities, rad/s (a single spin of shape (3,) is taken as N = 1).
    t_end : float
        Horizon, s (>= 0).
    dt : float
        Step, s (> 0). When ``t_end / dt`` is not an integer the step is shortened to
        ``t_end / ceil(t_end / dt)`` so the run ends exactly at ``t_end``; the step used is in
        ``attrs["dt"]``.
    method : str
        One of ``"rk4"``, ``"rk8"``, ``"symplectic_euler"``, ``"splitting2"``, ``"splitting4"``,
        ``"implicit_midpoint"``, ``"exact"``.
    torque : array_like, shape (3,), or callable
        Body-frame torque, N m: three constants, or a function ``f(t, w1, w2, w3) -> (N1, N2, N3)``
        (numba-jitted, or jittable in nopython mode). Zero torque is compiled out of the kernel.
    save_every : int, optional
        None stores only the final state; ``k`` stores the initial state, every k-th step and the final one.
    attitude : bool
        Orientation is not integrated yet; ``True`` raises NotImplementedError.

    Returns
    -------
    xarray.Dataset
        ``omega(sample, time, axis)``, rad/s, with coordinates ``sample``, ``time`` (s) and ``axis`` (1, 2, 3)
        and attributes recording the method, step, step count and torque.

    Raises
    ------
    ValueError
        Invalid moments, spins, horizon, step, method, torque or save interval, or ``"exact"`` with a torque.
    """
    moments = one_body(body)
    w = _initial_spins(w0)
    t_end = _scalar(t_end, "t_end")
    if t_end < 0:
        raise ValueError(f"t_end must be >= 0 s, got {t_end}")
    dt = _scalar(dt, "dt")
    if dt <= 0:
        raise ValueError(f"dt must be > 0 s, got {dt}")
    if method not in METHOD_NAMES:
        raise ValueError(f"method must be one of {', '.join(METHOD_NAMES)}; got {method!r}")
    if save_every is not None:
        if isinstance(save_every, bool) or not isinstance(save_every, (int, np.integer)) or save_every < 1:
            raise ValueError(f"save_every must be None or an integer >= 1 (steps), got {save_every!r}")
    if attitude:
        raise NotImplementedError("attitude=True (orientation quaternions) is not implemented yet")
    kind, params, fn, torque_text = _torque(torque)
    n_steps, step = _step_plan(t_end, dt)
    save = int(save_every or 0)
    if save:
        saved_steps = list(range(0, n_steps + 1, save))
        if saved_steps[-1] != n_steps:
            saved_steps.append(n_steps)
        times = np.array(saved_steps, dtype=float) * step
    else:
        times = np.array([t_end])

    if method == "exact":
        if params is not None or fn is not None:
            raise ValueError("method 'exact' is the torque-free closed form; it cannot take a torque "
                             f"({torque_text}); use a stepping method")
        omega = exact.omega(moments, w, times)
        order, path = None, "closed form (Jacobi elliptic functions)"
    else:
        integrator = METHODS[method]
        state = np.array(w.T, order="C")  # a copy: the kernel overwrites it, never the caller's w0
        saved = run(integrator, state, moments, 0.0, step, n_steps, save_every=save, torque_kind=kind,
                    torque_params=params, torque_fn=fn)
        omega = saved.transpose(2, 0, 1) if save else state.T[:, None, :]
        order, path = integrator.order, "fixed-step kernel"

    n_bad = int(np.count_nonzero(~np.all(np.isfinite(omega), axis=(1, 2))))
    if n_bad:
        warnings.warn(f"{n_bad} of {len(w)} samples became non-finite (step too large for the spin rate?)",
                      RuntimeWarning, stacklevel=2)
    ds = xr.Dataset(
        {"omega": (("sample", "time", "axis"), omega,
                   {"units": "rad/s", "long_name": "body-frame angular velocity"})},
        coords={
            "sample": ("sample", np.arange(len(w)), {"long_name": "ensemble member"}),
            "time": ("time", times, {"units": "s", "long_name": "time"}),
            "axis": ("axis", np.array([1, 2, 3]), {"long_name": "principal axis (1-based)"}),
        },
        attrs={
            "method": method,
            "order": -1 if order is None else order,
            "path": path,
            "dt": step if n_steps else dt,
            "n_steps": n_steps if method != "exact" else 0,
            "t_end": t_end,
            "moments": moments,
            "torque": torque_text,
            "n_nonfinite": n_bad,
        },
    )
    return ds
