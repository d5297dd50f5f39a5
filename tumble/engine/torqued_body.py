"""A free body with a torque, or with its attitude, as a :class:`tumble.System`: what ``method="dop853"`` steps.

The fixed-step methods carry a torque and the attitude in the free body's fused kernels
(:mod:`tumble.kernels.steps.steppers`, :mod:`tumble.kernels.steps.attitude`). An error-controlled run steps systems
(:func:`tumble.engine.adaptive_runs.run_adaptive`), so :func:`torqued_body` writes the same equations as one:

* the state ``(w1, w2, w3)``, rad/s, and with the attitude also ``(q0, q1, q2, q3)``, the body-to-space unit
  quaternion (scalar first, ``q' = ½ q ⊗ (0, w)``, the identity at ``t = 0``);
* the rate the kernels' own: ``euler_rate`` (Euler's equations plus the torque over ``I``) and ``attitude_rate``;
* the parameters ``I1, I2, I3`` (kg m²), the torque profile's ``N1, N2, N3`` (N m) and ``tau`` (s), and ``profile``
  (its code, ``registry.TORQUE_PROFILES``): data, so every body and profile shares one compiled rate, which the
  System path vectorises across samples and caches on disk. A user's torque function ``f(t, w1, w2, w3)`` is called
  by a rate made for it (compiled with it, in each process).

The error control sees the quaternion as four more components: its norm drifts by about the tolerance over a run
(a Runge–Kutta step keeps ``|q|`` only to its order), and the quaternions returned are scaled to unit length
(:func:`unit_quaternions`), as the fixed-step Runge–Kutta methods scale theirs after every step.
"""

from __future__ import annotations

import numpy as np

from ..kernels import attitude_rate, euler_rate
from ..physics.models import FreeBody
from ..physics.system import System

__all__ = ["ATTITUDE", "SPIN", "body_system", "torqued_body", "unit_quaternions"]

#: The state's components: the spin, and the spin with the attitude.
SPIN = ("w1", "w2", "w3")
ATTITUDE = (*SPIN, "q0", "q1", "q2", "q3")

# The rates below spell out the kernels' body constants (I1, I2, I3, a1, a2, a3) from p where they call euler_rate:
# a rate with the scalar form (tumble.kernels.steps.system_steps) reads y and p by constant indices and passes no array
# on, so no helper can take p whole.


def profile_rate(t, y, p, dydt):
    """``w'`` with a named torque profile: ``p = (I1, I2, I3, N1, N2, N3, tau, profile)``."""
    dydt[0], dydt[1], dydt[2] = euler_rate(t, y[0], y[1], y[2], (p[0], p[1], p[2], (p[1] - p[2]) / p[0],
                                                                (p[2] - p[0]) / p[1], (p[0] - p[1]) / p[2]),
                                           int(p[7]), (p[3], p[4], p[5], p[6]), None)


def profile_attitude_rate(t, y, p, dydt):
    """``(w', q')`` with a named torque profile: ``p`` as :func:`profile_rate`'s."""
    dydt[0], dydt[1], dydt[2] = euler_rate(t, y[0], y[1], y[2], (p[0], p[1], p[2], (p[1] - p[2]) / p[0],
                                                                (p[2] - p[0]) / p[1], (p[0] - p[1]) / p[2]),
                                           int(p[7]), (p[3], p[4], p[5], p[6]), None)
    dydt[3], dydt[4], dydt[5], dydt[6] = attitude_rate(y[3], y[4], y[5], y[6], y[0], y[1], y[2])


def _function_rates(fn):
    """``(rate, rate with the attitude)`` calling the user's torque function ``fn`` (compiled, with
    :data:`tumble.kernels.TORQUE_SIGNATURE`): ``p = (I1, I2, I3)``."""

    def function_rate(t, y, p, dydt):
        dydt[0], dydt[1], dydt[2] = euler_rate(t, y[0], y[1], y[2], (p[0], p[1], p[2], (p[1] - p[2]) / p[0],
                                                                    (p[2] - p[0]) / p[1], (p[0] - p[1]) / p[2]),
                                               0, (0.0, 0.0, 0.0, 0.0), fn)

    def function_attitude_rate(t, y, p, dydt):
        dydt[0], dydt[1], dydt[2] = euler_rate(t, y[0], y[1], y[2], (p[0], p[1], p[2], (p[1] - p[2]) / p[0],
                                                                    (p[2] - p[0]) / p[1], (p[0] - p[1]) / p[2]),
                                               0, (0.0, 0.0, 0.0, 0.0), fn)
        dydt[3], dydt[4], dydt[5], dydt[6] = attitude_rate(y[3], y[4], y[5], y[6], y[0], y[1], y[2])

    return function_rate, function_attitude_rate


#: A user's torque function -> its rates (made once per process and function: their compiled loops are kept with
#: the System, so the second run of the same function compiles nothing).
_FUNCTION_SYSTEMS = {}


def torqued_body(moments, torque, attitude):
    """``(system, parameters)``: the free body of principal ``moments`` (3,), kg m², with ``torque`` (as
    :func:`tumble.engine.ensemble.checked_torque` returns it) and, if ``attitude``, its attitude, as a
    :class:`~tumble.physics.system.System` (one per torque function and per profile, kept: what it compiles is kept
    with it) and the values of its parameters for this body and torque."""
    i1, i2, i3 = (float(m) for m in moments)
    if torque.fn is not None:
        key = (torque.fn, bool(attitude))
        if key not in _FUNCTION_SYSTEMS:
            rates = _function_rates(torque.fn)
            _FUNCTION_SYSTEMS[key] = _system(rates[1] if attitude else rates[0], attitude, ("I1", "I2", "I3"))
        return _FUNCTION_SYSTEMS[key], {"I1": i1, "I2": i2, "I3": i3}
    n1, n2, n3, tau = (float(x) for x in torque.params) if torque.params is not None else (0.0, 0.0, 0.0, 0.0)
    values = {"I1": i1, "I2": i2, "I3": i3, "N1": n1, "N2": n2, "N3": n3, "tau": tau, "profile": float(torque.kind)}
    return _PROFILE_SYSTEMS[bool(attitude)], values


def body_system(moments, torque, attitude, device):
    """``(system, parameters)`` an error-controlled run steps for the free body of ``moments``: torque-free and
    without its attitude the built-in :class:`~tumble.physics.models.FreeBody` (on either device; parameters None),
    else :func:`torqued_body` (the CPU only: a ``ValueError`` for another ``device``)."""
    if torque.params is None and torque.fn is None and not attitude:
        return FreeBody(moments), None
    if device != "cpu":
        raise ValueError(f"device {device!r}: method 'dop853' steps a free body with a torque or its attitude on the "
                         f"CPU only (device='cpu'); torque-free and without it, it runs on the device")
    return torqued_body(moments, torque, attitude)


def _system(rate, attitude, parameters):
    return System(rate, state=ATTITUDE if attitude else SPIN, parameters=dict.fromkeys(parameters, 1.0),
                  name="free body" + (" with its attitude" if attitude else "") + " under a torque")


_PROFILE_SYSTEMS = {flag: _system(profile_attitude_rate if flag else profile_rate, flag,
                                  ("I1", "I2", "I3", "N1", "N2", "N3", "tau", "profile"))
                    for flag in (False, True)}


def unit_quaternions(states):
    """The spins ``(..., 3)`` and the quaternions scaled to unit length ``(..., 4)`` of states ``(..., 7)``."""
    q = states[..., 3:]
    return states[..., :3], q / np.sqrt(np.sum(q * q, axis=-1, keepdims=True))
